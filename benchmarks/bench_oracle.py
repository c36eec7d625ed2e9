"""The oracle (our body fitted to the true joints, :func:`mocap.eval.mismatch.fit_oracle`): seconds
and errors of its two solvers on the same ground truth (issue 38: 230 s for 196 frames).

    PYTHONPATH=$PWD OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_oracle.py \
        [--methods trust_region,tracked] [--clip dataset-1_walk-back_active_001] [--frames 196] \
        [--dev] [--out /tmp/oracle.jsonl]

Ground truth: ``--frames`` frames of a real motion-capture clip (``--clip``, from
``../shared/data/real-motion``, its joints mapped onto our names as retargeting maps them: a
skeleton our model did not generate), and with ``--dev`` every sequence of the real-motion
benchmark's dev split (``data/real_motion/dev``, 60 frames each: the ground truth a run is
scored on). Printed per ground truth and method: wall and CPU seconds, raw, offset-removed and
limb errors (mm), frames lost. One thread (BLAS) is what a tracking run gives it.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

import mocap
from mocap.eval.mismatch import fit_oracle

REPO = Path(__file__).resolve().parents[1]
CLIPS = Path(os.environ.get("MOCAP_SHARED_DATA") or REPO.parent / "shared" / "data") / "real-motion"


def clip_truth(body, name: str, frames: int):
    from mocap.clips.bvh import read_bvh
    from mocap.clips.retarget import clip_targets

    path = next(CLIPS.rglob(f"{name}.bvh"))
    clip = read_bvh(path)
    _, _, ours, targets = clip_targets(clip, body)
    if len(targets) < frames:
        raise SystemExit(f"{path}: {len(targets)} frames, fewer than --frames {frames}")
    return f"{name}[:{frames}]", ours, targets[:frames], None, None


def dev_truths(body):
    from mocap.data.sequence_io import load_sequence

    for folder in sorted((REPO / "data" / "real_motion" / "dev").iterdir()):
        if (folder / "sequence.json").is_file():
            gt = load_sequence(folder).gt
            yield folder.name, list(gt.joint_names), gt.joints, gt.joint_valid, gt.skeleton or None


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--methods", default="trust_region,tracked")
    p.add_argument("--clip", default="dataset-1_walk-back_active_001")
    p.add_argument("--frames", type=int, default=196)
    p.add_argument("--no-clip", action="store_true", help="only the dev split")
    p.add_argument("--dev", action="store_true", help="also every dev-split sequence")
    p.add_argument("--label", default=str(REPO))
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    body = mocap.load_body("paper22")
    truths = [] if args.no_clip else [clip_truth(body, args.clip, args.frames)]
    if args.dev:
        truths += list(dev_truths(body))
    print(f"{'ground truth':<34} {'method':<13} {'wall s':>7} {'cpu s':>7} {'raw':>6} {'offs-rm':>7} "
          f"{'limbs':>6} lost")
    for name, names, joints, valid, skeleton in truths:
        for method in args.methods.split(","):
            t, c = time.perf_counter(), time.process_time()
            with threadpool_limits(1):
                fit = fit_oracle(body, names, joints, valid, skeleton, method=method)
            wall, cpu = time.perf_counter() - t, time.process_time() - c
            m = fit.metrics
            print(f"{name:<34} {method:<13} {wall:7.2f} {cpu:7.2f} {m['raw_mm']:6.2f} "
                  f"{m['offset_removed_mm']:7.2f} {m['limbs_mm']:6.2f} {m['frames_lost']:4d}", flush=True)
            if args.out:
                with args.out.open("a") as f:
                    f.write(json.dumps({"label": args.label, "truth": name, "frames": len(joints),
                                        "method": method, "wall_s": wall, "cpu_s": cpu,
                                        "load": os.getloadavg()[0],
                                        **{k: v for k, v in m.items() if k != "offsets_mm"}}) + "\n")


if __name__ == "__main__":
    main()

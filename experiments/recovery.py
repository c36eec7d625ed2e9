"""Recovery from an injected tracking failure (issue 5): a frame skip, then a large pose
perturbation of the tracker's state, on a synthetic sequence with ground truth.

    python experiments/recovery.py --tracker local --data walk_mpi08 --seed 0 [--frames 80]

For each failure it reports the error before (mean of the 5 frames before it) and the number
of frames until the error is back under twice that level (or "not recovered"). Writes
recovery.json next to its output.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from mocap.eval.metrics import joint_errors
from mocap.trackers.run import frame_of, noisy_initial_pose

REPO = Path(__file__).resolve().parents[1]


def frames_to_recover(errors: list[float], start: int, before: float) -> int | None:
    for k, e in enumerate(errors[start:]):
        if e < 2 * before:
            return k
    return None


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tracker", default="local")
    p.add_argument("--data", default="walk_mpi08")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--frames", type=int, default=80)
    p.add_argument("--skip-at", type=int, default=25, help="frames skip_at..skip_at+skip-1 are dropped")
    p.add_argument("--skip", type=int, default=5)
    p.add_argument("--perturb-at", type=int, default=50)
    p.add_argument("--perturb-deg", type=float, default=30.0)
    p.add_argument("--out", type=Path, default=REPO / "outputs" / "recovery")
    args = p.parse_args(argv)
    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        cfg = compose("track", overrides=[f"tracker={args.tracker}", f"data={args.data}",
                                          f"seed={args.seed}", f"data.frames={args.frames}"])
    body = instantiate(cfg.body)
    seq = instantiate(cfg.data, _partial_=True)(body=body)
    tracker = instantiate(cfg.tracker, _partial_=True)(body=body, rig=seq.rig,
                                                        rng=np.random.default_rng([args.seed, 1]))
    rng = np.random.default_rng(args.seed)
    tracker.initialize(noisy_initial_pose(body, seq.gt.chi[0], rng, 3.0, 0.02), seq.gt.alpha)
    shaped = body.shaped(seq.gt.alpha)
    errors: dict[int, float] = {}
    skipped = set(range(args.skip_at, args.skip_at + args.skip))
    for f in range(1, seq.num_frames):
        if f in skipped:
            continue
        if f == args.perturb_at:      # a large perturbation of the tracker's last estimate
            bad = tracker.history[-1].copy()
            idx = rng.choice(np.arange(6, body.num_dofs), size=6, replace=False)
            bad[idx] += np.deg2rad(args.perturb_deg) * rng.choice([-1, 1], size=6)
            bad[:3] += [0.1, -0.1, 0.0]
            tracker.history = [np.clip(bad, body.limits[:, 0], body.limits[:, 1])]
        est = tracker.step(frame_of(seq, f))
        err = joint_errors(shaped.joints(est.chi), seq.gt.joints[f:f + 1], body.joint_names)
        errors[f] = float(err.mean())
        print(f"frame {f:3d}: {errors[f]:7.1f} mm", file=sys.stderr)
    frames = sorted(errors)
    series = [errors[f] for f in frames]
    report = {"tracker": args.tracker, "data": args.data, "seed": args.seed, "errors_mm": errors}
    for name, at in (("frame_skip", args.skip_at + args.skip), ("perturbation", args.perturb_at)):
        i = frames.index(at)
        before = float(np.mean([errors[f] for f in frames[max(0, i - 5):i]]))
        report[name] = {"at_frame": at, "error_before_mm": before, "error_at_mm": errors[at],
                        "frames_to_recover": frames_to_recover(series, i, before)}
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"recovery_{args.tracker}_{args.data}_s{args.seed}.json"
    path.write_text(json.dumps(report, indent=2))
    for name in ("frame_skip", "perturbation"):
        r = report[name]
        rec = r["frames_to_recover"]
        print(f"{args.tracker} {name} at frame {r['at_frame']}: before {r['error_before_mm']:.1f} mm, "
              f"at {r['error_at_mm']:.1f} mm, "
              + (f"recovered after {rec} frames" if rec is not None else "not recovered"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

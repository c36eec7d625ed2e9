"""The silhouette-only hybrid's start hypotheses scored over the first frames (``start_frames``,
:mod:`mocap.trackers.start_frames`), without tracking on: per sequence folder and seed, the cached
self-initialisation (the random state ``mocap track ... seed=S`` gives it), its hypotheses each tracked
by the local step alone over frames 0..N, and per hypothesis the summed mean per-view E_S over the first
n+1 frames for each n of ``--frames`` (the tracks do not depend on N, so one run scores every N) beside
its joint error (mm, mean over the joints) at frame 0 and over those frames: does the lowest energy over
frames pick the better start, and which hypothesis would each setting keep (``--margin``).

    python -m experiments.sil_start_frames data/real_motion/dev/* --seeds 0 1 2 --frames 5 10 \\
        --init-cache outputs/init_cache --out outputs/sil6/start_frames.jsonl
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from experiments.sil_hybrid_diagnosis import joint_errors
from experiments.tools.jsonl import report
from mocap.body import load_body
from mocap.data.sources import folder_sequence
from mocap.eval.by_name import NameScorer
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of
from mocap.trackers.start_frames import chosen_hypothesis


def run(seq_path: Path, seed: int, frames: list[int], margin: float, init_cache: str | None,
        turns: tuple = (), restarts: int = 0) -> dict:
    body = load_body("paper22")
    seq = folder_sequence(body=body, path=str(seq_path), name=f"real_{seq_path.name}", seed=seed)
    n = max(frames)
    tracker = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng([seed, 1]),
                           start_frames={"frames": n, "turns": tuple(turns),
                                                                  "restarts": restarts})
    est0, _ = tracker.initializer(init_cache)(frame_of(seq, 0))
    tracker.begin(frame_of(seq, 0), est0)
    names, found, shapes = tracker.start_tracks([frame_of(seq, f) for f in range(n + 1)])
    scorer = NameScorer(body, seq.gt.person(0))
    err = np.stack([joint_errors(scorer, np.repeat(shapes[h][None], n + 1, 0), found.poses[h])[1].mean(axis=1)
                    for h in range(len(names))])                                     # (H, n+1) mm
    out = {"data": seq.name, "seed": seed, "hypotheses": names,
           "frame0_mm": [round(float(e), 1) for e in err[:, 0]], "by_frames": {}}
    for k in frames:
        total = found.energy[:, :k + 1].sum(axis=1)
        best = chosen_hypothesis(total, margin)
        out["by_frames"][k] = {"energy": [round(float(e), 4) for e in total],
                               "mm": [round(float(e), 1) for e in err[:, :k + 1].mean(axis=1)],
                               "chosen": names[best], "lowest": names[int(np.argmin(total))]}
    return out


def summary(r: dict) -> str:
    parts = []
    for k, b in r["by_frames"].items():
        e0 = b["energy"][0]
        alts = ", ".join(f"{h} {100 * (e / e0 - 1):+.0f}% {m:.0f}mm" for h, e, m
                         in zip(r["hypotheses"][1:], b["energy"][1:], b["mm"][1:], strict=True))
        parts.append(f"N={k}: start {b['mm'][0]:.0f}mm, {alts} -> {b['chosen']}")
    return f"{r['data']} seed {r['seed']} frame0 {r['frame0_mm']}: " + "; ".join(parts)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="+", type=Path)
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--frames", type=int, nargs="+", default=[5, 10])
    p.add_argument("--margin", type=float, default=0.05)
    p.add_argument("--restarts", type=int, default=0, help="more self-initialisations (other random states)")
    p.add_argument("--turns", type=float, nargs="*", default=[], help="more hypotheses: turned by (deg)")
    p.add_argument("--init-cache", default="outputs/init_cache")
    p.add_argument("--out", type=Path, help="append each run's JSON here (one line each)")
    a = p.parse_args(argv)
    for s in a.sequences:
        for seed in a.seeds:
            r = run(s, seed, a.frames, a.margin, a.init_cache, tuple(a.turns), a.restarts)
            report(r, summary(r), a.out)


if __name__ == "__main__":
    main()

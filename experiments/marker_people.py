"""Question: with several people in view, does the multi-person marker tracker keep
identities apart and track each person as well as it tracks them alone?

Several people: identity switches and per-person error of the multi-person marker tracker
(mocap/trackers/markers/people.py) against tracking each person alone.

    python experiments/marker_people.py --seeds 0 1 2 --frames 50 --out marker_people.json

Scene (:func:`mocap.data.crowd.crossing_scene`): three people with different shapes, two
walking towards each other on lines ``--gap`` m apart and crossing half way, one gesturing
to the side; the 25 BODY_25B keypoints of each, grouped per person as a detector does
(1 px noise), seen by the HumanEva-like 4 views. ``together``: one PeopleTracker on
everyone's detections; ``alone``: each person tracked on their own detections only (the
single-person reference). Error: mean keypoint-landmark distance to the person's truth (mm,
frames 1..F-1); an identity switch: a frame where a track is nearer another person's truth
than the one it started on.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mocap.body import load_body
from mocap.body.skeletons import LAYOUTS
from mocap.cameras import rig_from_config
from mocap.data.crowd import crossing_scene, crowd_detections
from mocap.data.sequence import Sequence
from mocap.trackers.markers.people import PeopleTracker
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]


def run(body, seq, truth, seed):
    rngs = iter(np.random.default_rng(seed).spawn(20))
    people = PeopleTracker(lambda: make_tracker("marker_apf", body=body, rig=seq.rig, rng=next(rngs)))
    tracks = people.start(frame_of(seq, 0))
    for f in range(1, seq.num_frames):
        people.step(frame_of(seq, f))
    out = {}
    for t in tracks:
        lms = t.tracker.landmarks
        idx = [LABELS.index(n) for n in lms.names]
        frames = sorted(f for f in t.estimates if f > 0)
        X = lms.positions(t.tracker.shaped, np.stack([t.estimates[f].chi for f in frames])).astype(np.float64)
        d = np.stack([np.linalg.norm(X - truth[n, frames][:, idx], axis=-1).mean(axis=1)
                      for n in range(len(truth))])                     # (N, frames)
        start = int(np.argmin(d[:, 0]))
        who = np.argmin(d, axis=0)
        out[t.id] = {"person": start, "switches": int((who != start).sum()),
                     "error_mm": 1e3 * float(d[start].mean())}
    return out


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--frames", type=int, default=50)
    p.add_argument("--gap", type=float, default=0.35)
    p.add_argument("--out", default="marker_people.json")
    args = p.parse_args()
    body = load_body("paper22")
    rig = rig_from_config("humaneva")
    rows = []
    for seed in args.seeds:
        chis, alphas = crossing_scene(body, args.frames, people=3, gap=args.gap, seed=seed)
        det, truth = crowd_detections(body, rig, chis, alphas, LABELS, noise_px=1.0, seed=seed)
        together = run(body, Sequence(name="crowd", rig=rig, fps=25, detections=det), truth, seed)
        for tid, r in together.items():
            n = r["person"]
            alone_det, _ = crowd_detections(body, rig, chis[n:n + 1], alphas[n:n + 1], LABELS, noise_px=1.0,
                                            seed=seed)
            alone = run(body, Sequence(name="alone", rig=rig, fps=25, detections=alone_det), truth[n:n + 1],
                        seed)
            rows.append({"seed": seed, "track": tid, "person": n, "switches": r["switches"],
                         "error_mm": r["error_mm"], "alone_error_mm": alone[0]["error_mm"],
                         "ratio": r["error_mm"] / alone[0]["error_mm"]})
            print(rows[-1], flush=True)
    Path(args.out).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))
    print("| seed | person | switches | together mm | alone mm | ratio |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['seed']} | {r['person']} | {r['switches']} | {r['error_mm']:.1f} "
              f"| {r['alone_error_mm']:.1f} | {r['ratio']:.2f} |")


if __name__ == "__main__":
    main()

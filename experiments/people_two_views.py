"""Question: is a person seen by only two cameras of a larger rig (standing outside the other
cameras' fields of view) tracked by ``marker_people``, and how well?

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD .venv/bin/python experiments/people_two_views.py \
        [--frames 20] [--set people.min_views=3 likelihood_min_views=3]

Scene (:func:`two_view_scene`): a 4-camera rig on a 4.5 m ring, two wide cameras and two
narrower ones aimed to one side. Person A is seen by all 4 views; person B walks on the other
side, inside the wide cameras' images only (2 views: the other two images hold none of its
keypoints). 1 px detector noise, BODY_25B
keypoints. Prints per true person: the frames tracked, the track's mean keypoint error (mm)
against the truth, and the tracks made.
"""

from __future__ import annotations

import argparse

import numpy as np

from mocap import presets
from mocap.body import load_body_model
from mocap.body.skeletons import LAYOUTS
from mocap.cameras import Rig, project
from mocap.cameras.rigs import ring_rig
from mocap.data.crowd import crowd_detections, straight_walk
from mocap.data.sequence import Sequence
from mocap.threads import thread_budget
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]


def two_view_rig() -> Rig:
    """4 cameras on a 4.5 m ring, 90 deg apart: cam_00 and cam_01 wide (70 deg vertical field
    of view, looking at (0, 0, 0.9)), cam_02 and cam_03 narrower (30 deg, looking at
    (-1, -1, 0.9))."""
    common = {"num_cameras": 4, "radius": 4.5, "height": 2.0, "width": 640, "image_height": 480}
    wide = ring_rig(fov_deg=70.0, look_at=(0.0, 0.0, 0.9), **common)
    narrow = ring_rig(fov_deg=30.0, look_at=(-1.0, -1.0, 0.9), **common)
    return Rig((wide[0], wide[1], narrow[2], narrow[3]))


def two_view_scene(body, frames: int = 20, seed: int = 0):
    """(sequence, truth (2, F, L, 3) world m, the views seeing any keypoint of each person):
    A walks near (-1, -1), seen by all 4 cameras; B walks near (1.4, 1.1), inside the two wide
    cameras' images only."""
    rig = two_view_rig()
    chis = np.stack([straight_walk(body, frames, (-1.4, -1.0), (-0.6, -1.0), 0.0, seed),
                     straight_walk(body, frames, (1.2, 1.2), (1.6, 0.9), -0.6, seed + 1)])
    alphas = np.random.default_rng(seed).normal(0, 0.5, (2, body.num_shape))
    det, truth = crowd_detections(body, rig, chis, alphas, LABELS, noise_px=1.0, seed=seed)
    sizes = np.asarray(rig.sizes, np.float64)
    seen = []
    for n in range(2):
        views = set()
        for c in range(len(rig)):
            px, depth = project(rig[c], truth[n].reshape(-1, 3), return_depth=True)
            if np.any((depth > 0.1) & np.all((px >= 0) & (px < sizes[c]), axis=1)):
                views.add(c)
        seen.append(sorted(views))
    return Sequence(name="two_views", rig=rig, fps=25, detections=det), truth, seen


def track(body, seq, truth, seed: int, keys: dict) -> dict:
    people = make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(seed), **keys)
    people.check_sequence(seq)
    people.start(frame_of(seq, 0))
    for f in range(1, seq.num_frames):
        people.step(frame_of(seq, f))
    out = {"tracks": len(people.tracks), "people": {}}
    for t in people.tracks:
        lms = t.tracker.landmarks
        idx = [LABELS.index(n) for n in lms.names]
        errs = {n: [] for n in range(len(truth))}
        for f, est in sorted(t.estimates.items()):
            X = lms.positions(t.tracker.shaped, est.chi[None])[0].astype(np.float64)
            d = [np.linalg.norm(X - truth[n, f][idx], axis=1).mean() for n in range(len(truth))]
            errs[int(np.argmin(d))].append(min(d))
        who = max(errs, key=lambda n: len(errs[n]))
        e = np.array(errs[who][1:] or errs[who])          # frame 0 is the start-up's estimate
        out["people"][who] = {"track": t.id, "frames": len(t.estimates),
                              "mean_mm": round(1000 * float(e.mean()), 1),
                              "max_mm": round(1000 * float(e.max()), 1)}
    return out


def main() -> None:
    from experiments.people_ghosts import overrides

    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", nargs="*", default=[], help="tracker overrides, e.g. people.min_views=3")
    args = p.parse_args()
    body = load_body_model(presets.read("body", "paper22")["dofs"], name="paper22")
    seq, truth, seen = two_view_scene(body, args.frames, args.seed)
    print(f"views with any keypoint of A: {seen[0]}, of B: {seen[1]}")
    with thread_budget(1):
        r = track(body, seq, truth, args.seed, overrides(args.set))
    print(f"tracks made: {r['tracks']}")
    for n, name in enumerate("AB"):
        got = r["people"].get(n)
        print(f"person {name}: " + ("not tracked" if got is None else
              f"track {got['track']}, {got['frames']}/{args.frames} frames, mean keypoint error "
              f"{got['mean_mm']} mm (max {got['max_mm']})"))


if __name__ == "__main__":
    main()

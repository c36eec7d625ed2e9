"""Question: with a detector's false people in the views (whole skeletons seen by one or two
cameras), does ``marker_people`` make ghost tracks, and does suppressing them cost the real
people anything (entrants picked up late, identities lost)?

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD .venv/bin/python experiments/people_ghosts.py \
        --seeds 0 1 2 --false-people 6 \
        [--set people.min_views=2 people.support=0 people.max_under_viewed=1000]

Scene: the synthetic crowd (``data=crowd``, :func:`mocap.data.crowd.crowd_sequence`: five
people, at most four at once, 5 views) with ``--false-people`` false skeletons
(:func:`mocap.data.crowd.false_skeletons`: plausible walking people, each seen in one or two
views only, over a quarter to all of the frames). Tracker: the ``marker_people`` preset with
``--set`` overrides (``people.min_views=2 people.support=0 people.max_under_viewed=1000`` is
the tracker before ghost suppression). Per seed: tracks made, tracks assigned to no true person (the Hungarian
assignment of :func:`mocap.eval.people_metrics.people_scores`: extra tracks), ghost tracks
(a track whose mean joint error to every true person present is above 0.5 m in all its
frames, the issue's measure), per true person the frames from
appearance to tracked, identity switches and MPJPE (:func:`mocap.eval.people_metrics.people_scores`).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from mocap import presets
from mocap.body import load_body_model
from mocap.data.crowd import crowd_sequence
from mocap.data.people_truth import people_truth
from mocap.eval.people_metrics import people_scores
from mocap.threads import thread_budget
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of


def overrides(pairs: list[str]) -> dict:
    """``a.b=v`` strings -> a nested dict (values parsed as JSON where they parse)."""
    out: dict = {}
    for pair in pairs:
        key, value = pair.split("=", 1)
        try:
            v = json.loads(value)
        except json.JSONDecodeError:
            v = value
        *path, last = key.split(".")
        d = out
        for k in path:
            d = d.setdefault(k, {})
        d[last] = v
    return out


def run(body, seq, seed: int, keys: dict) -> dict:
    people = make_tracker("marker_people", body=body, rig=seq.rig, rng=np.random.default_rng(seed), **keys)
    people.check_sequence(seq)
    people.start(frame_of(seq, 0))
    for f in range(1, seq.num_frames):
        people.step(frame_of(seq, f))
    tracks = people.estimates_by_person()
    ids = sorted(tracks)
    truth = people_truth(seq)
    T = seq.num_frames
    est = np.full((T, len(ids), len(body.joint_names), 3), np.nan)
    for i, tid in enumerate(ids):
        frames = sorted(tracks[tid])
        shaped = body.shaped(tracks[tid][frames[0]].alpha)
        est[frames, i] = shaped.pose(np.stack([tracks[tid][f].chi for f in frames])).joints
    gt = np.asarray(truth.joints, np.float64)
    scores = people_scores(est, gt, gate_mm=500.0)
    err = np.linalg.norm(est[:, None] - gt[:, :, None], axis=-1).mean(-1)        # (T, G, E)
    nearest = np.nanmin(np.where(np.isfinite(err), err, np.inf), axis=(0, 1))     # (E,)
    ghosts = [int(ids[e]) for e in range(len(ids)) if nearest[e] > 0.5]
    story = seq.meta["crowd"]
    return {"seed": seed, "tracks": len(ids), "ghosts": ghosts,
            "latency": {g: scores["people"][int(g)]["latency_frames"] for g in story["entering"]},
            "switches": scores["switches"],
            "mpjpe_mm": [round(p["mpjpe_mm"], 1) for p in scores["people"]],
            "unassigned": len(scores["unassigned_tracks"])}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--frames", type=int, default=80)
    p.add_argument("--false-people", type=int, default=6)
    p.add_argument("--false-views", type=int, default=2)
    p.add_argument("--set", nargs="*", default=[], help="tracker overrides, e.g. people.min_views=2")
    args = p.parse_args()
    body = load_body_model(presets.read("body", "paper22")["dofs"], name="paper22")
    keys = overrides(args.set)
    print("| seed | tracks | tracks of no true person | ghost tracks (never within 0.5 m) "
          "| entrants: frames to tracked | switches | MPJPE per person (mm) |")
    print("|---|---|---|---|---|---|---|")
    with thread_budget(1):
        for seed in args.seeds:
            seq = crowd_sequence(body=body, frames=args.frames, seed=seed, false_people=args.false_people,
                                 false_views=args.false_views)
            r = run(body, seq, seed, keys)
            print(f"| {seed} | {r['tracks']} | {r['unassigned']} | {len(r['ghosts'])} {r['ghosts']} | "
                  f"{', '.join(str(v) for v in r['latency'].values())} | {r['switches']} | "
                  f"{', '.join(str(v) for v in r['mpjpe_mm'])} |", flush=True)


if __name__ == "__main__":
    main()

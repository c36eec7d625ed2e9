"""Question: with a detector that has a real one's semantics (systematic keypoint offsets,
left/right swaps, limbs of another person, confidences that do not match the error), does
``marker_apf`` beat robust per-frame triangulation of the same detections, and by how much?

    python experiments/detector_semantics.py --split test --views 4 8 --seeds 0 1 2 \
        --variants default --out detector_semantics_test.json

Sequences: the real-motion benchmark (``data/real_motion/<split>/*``) and, with ``--mismatch``,
the model-mismatch ones (``data/mismatch/*``), each with detections simulated from its
ground-truth joints (``data.detections.semantics=realistic``, :mod:`mocap.data.detector_semantics`,
seeded by the seed and the sequence), in the first 4 (views 0, 2, 4, 6) or all 8 views.
Per (sequence, views, seed): robust per-frame triangulation of the detections
(:mod:`experiments.tools.triangulation`; a keypoint no two views agree on keeps its last value) and
``marker_apf`` variants (:data:`VARIANTS`, the preset plus settings), self-initialised on frame 0
as ``mocap track ... init.mode=tracker`` does, both scored by the same MPJPE on the same 15
joints over the same frames (:class:`mocap.eval.by_name.NameScorer`). Writes one JSON row per
run and prints a table of the mean over seeds with the gap (triangulation - marker_apf) in mm.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from experiments.tools.triangulation import robust_triangulation, score_triangulation
from mocap.body import load_body
from mocap.data.sources import folder_sequence
from mocap.eval.by_name import NameScorer
from mocap.trackers.init_cache import initial_estimate
from mocap.trackers.markers.offsets import remove_profile
from mocap.trackers.markers.settings import MarkerSettings
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, track_sequence

DATA = Path(__file__).resolve().parents[1] / "data"
#: marker_apf settings per variant (overrides of the marker_apf preset)
OLD = {"offsets": {"frames": 0}, "refine": {"outlier_views": 0.0},
       "init": {"outlier_sigma": 4.0, "bound_sigma": 3.0}, "use_confidence": False, "keypoint_profile": None}


def _with(**changes) -> dict:
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in OLD.items()}
    for k, v in changes.items():
        out[k] = {**out.get(k, {}), **v} if isinstance(v, dict) else v
    return out


VARIANTS: dict[str, dict] = {
    "default": {},                                        # today's defaults
    "old": OLD,                                           # the defaults before issue 26
    "os8": _with(init={"outlier_sigma": 8.0}),
    "os8_b6": _with(init={"outlier_sigma": 8.0, "bound_sigma": 6.0}),
    "os8_off10": _with(init={"outlier_sigma": 8.0}, offsets={"frames": 10}),
    "os8_off20": _with(init={"outlier_sigma": 8.0}, offsets={"frames": 20}),
    "os8_views": _with(init={"outlier_sigma": 8.0}, refine={"outlier_views": 3.0}),
    "os8_conf": _with(init={"outlier_sigma": 8.0}, use_confidence=True),
    "os8_all": _with(init={"outlier_sigma": 8.0}, offsets={"frames": 10}, refine={"outlier_views": 3.0},
                     use_confidence=True),
    # with the detector profile (keypoint_profile: auto -> realistic_sim on these detections)
    "p_os8_b6": _with(init={"outlier_sigma": 8.0, "bound_sigma": 6.0}, keypoint_profile="auto"),
    "p_os8_b6_off10": _with(init={"outlier_sigma": 8.0, "bound_sigma": 6.0}, keypoint_profile="auto",
                            offsets={"frames": 10}),
    "p_os8_b6_views": _with(init={"outlier_sigma": 8.0, "bound_sigma": 6.0}, keypoint_profile="auto",
                            refine={"outlier_views": 3.0}),
    "p_os8_b6_conf": _with(init={"outlier_sigma": 8.0, "bound_sigma": 6.0}, keypoint_profile="auto",
                           use_confidence=True),
}


def sequences(split: str, mismatch: bool) -> list[Path]:
    out = sorted((DATA / "real_motion" / split).iterdir()) if split else []
    if mismatch:
        out += [p for p in sorted((DATA / "mismatch").iterdir()) if p.is_dir()]
    return [p for p in out if (p / "gt.npz").exists()]


def calibrate(body, paths: list[Path], seeds: list[int], semantics: str) -> dict:
    """A detector profile (keypoint type -> mean (out, forward, up) mm) from sequences with
    ground truth: robust triangulation of the detections (8 views) against the ground-truth
    joints, in the keypoint frames of the ground truth, median over frames, left and right
    mirrored together, mean over sequences and seeds."""
    from mocap.data.detector_semantics import _kind, gt_keypoint_names, keypoint_frames

    per_type: dict[str, list] = {}
    for path in paths:
        for seed in seeds:
            seq = folder_sequence(body=body, path=str(path), images=False, seed=seed,
                                  detections={"semantics": semantics})
            names = gt_keypoint_names(seq.gt)
            gate = MarkerSettings().likelihood(seq.rig.sizes).gate_px
            X, inl = robust_triangulation(seq.rig, seq.detections, names, seq.num_frames, gate, hold=False)
            frames = keypoint_frames(seq.gt.joints, names)
            local = np.einsum("fjab,fja->fjb", frames, X - seq.gt.joints)
            med = np.nanmedian(local, axis=0)                          # (J, 3) metres
            for j, n in enumerate(names):
                kind, sign = _kind(n)
                per_type.setdefault(kind, []).append(med[j] * [sign or 1.0, 1.0, 1.0])
    return {k: tuple(round(1e3 * float(x), 1) for x in np.mean(v, axis=0)) for k, v in per_type.items()}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--split", default="test", choices=["dev", "test", ""])
    p.add_argument("--mismatch", action="store_true", help="add data/mismatch's sequences")
    p.add_argument("--only", nargs="*", default=None, help="sequence folder names to keep")
    p.add_argument("--views", nargs="+", type=int, default=[4, 8], choices=[4, 8])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--variants", nargs="+", default=["default"], choices=list(VARIANTS))
    p.add_argument("--semantics", default="realistic", help="realistic, offsets_only, or none: the "
                   "folder's own (Canton-style) detections")
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--out", default="detector_semantics.json")
    p.add_argument("--calibrate", action="store_true", help="print a detector profile calibrated on "
                   "the split's sequences (and --mismatch) and stop")
    args = p.parse_args()
    body = load_body("paper22")
    if args.calibrate:
        print(calibrate(body, sequences(args.split, args.mismatch), args.seeds, args.semantics))
        return
    rows = []
    for path in sequences(args.split, args.mismatch):
        if args.only and path.name not in args.only:
            continue
        for nv in args.views:
            for seed in args.seeds:
                seq = folder_sequence(body=body, path=str(path), images=False, seed=seed,
                                      views=None if nv == 8 else [0, 2, 4, 6],
                                      detections={"semantics": None if args.semantics == "none"
                                                  else args.semantics})
                F = min(args.frames, seq.num_frames)
                scorer = NameScorer(body, seq.gt)
                key = {"sequence": path.name, "views": nv, "seed": seed, "frames": F}
                gate = MarkerSettings().likelihood(seq.rig.sizes).gate_px
                names = list(seq.detections.labels)
                t = time.perf_counter()
                X, inl = robust_triangulation(seq.rig, seq.detections, names, F, gate)
                sec = (time.perf_counter() - t) / F
                tri = score_triangulation(scorer, names, X)
                rows.append({**key, "method": "triangulation", "mpjpe_mm": tri["mpjpe_mm"],
                             "per_joint_mm": tri["per_joint_mm"], "coverage": float((inl > 0).mean()),
                             "sec_per_frame": sec})
                print(json.dumps({k: v for k, v in rows[-1].items() if k != "per_joint_mm"}), flush=True)
                profile = (seq.meta.get("detections") or {}).get("keypoint_profile")
                if profile:     # the same detector profile the tracker uses, removed frame by frame
                    Y = np.stack([remove_profile(profile, names, x) for x in X])
                    tri = score_triangulation(scorer, names, Y)
                    rows.append({**key, "method": "triangulation+profile", "mpjpe_mm": tri["mpjpe_mm"],
                                 "per_joint_mm": tri["per_joint_mm"]})
                    print(json.dumps({k: v for k, v in rows[-1].items() if k != "per_joint_mm"}), flush=True)
                for variant in args.variants:
                    t = time.perf_counter()
                    # as mocap.api.track(seq, "marker_apf", seed=seed, init="tracker", ...)
                    trk = make_tracker("marker_apf", body=body, rig=seq.rig,
                                       rng=np.random.default_rng([seed, 1]), **VARIANTS[variant])
                    trk.check_sequence(seq)                 # as mocap track: reads the detector profile
                    chi0, alpha0, _ = initial_estimate(trk, frame_of(seq, 0))
                    res = track_sequence(trk, seq, chi0, alpha0, F)
                    sec = (time.perf_counter() - t) / F
                    chis = np.stack([e.chi for e in res.estimates])
                    alphas = np.stack([e.alpha for e in res.estimates])
                    pts = scorer.points_by_shape(alphas, chis)
                    m = scorer.score(pts)
                    rows.append({**key, "method": f"marker_apf:{variant}", "mpjpe_mm": m["mpjpe_mm"],
                                 "per_joint_mm": m["per_joint_mm"], "pcp": m.get("pcp"),
                                 "sec_per_frame": sec,
                                 "track_fps": (F - 1) / max(sum(res.seconds), 1e-9)})
                    print(json.dumps({k: v for k, v in rows[-1].items() if k != "per_joint_mm"}), flush=True)
    Path(args.out).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))
    print_table(rows)


def print_table(rows: list[dict]) -> None:
    methods = list(dict.fromkeys(r["method"] for r in rows))
    print("| sequence | views | " + " | ".join(methods) + " | gap (tri - " + methods[-1] + ") |")
    print("|---|---|" + "---|" * (len(methods) + 1))
    for s in dict.fromkeys(r["sequence"] for r in rows):
        for nv in sorted({r["views"] for r in rows}):
            cell = {}
            for m in methods:
                v = [r["mpjpe_mm"] for r in rows
                     if r["sequence"] == s and r["views"] == nv and r["method"] == m]
                cell[m] = (np.mean(v), np.std(v)) if v else (np.nan, np.nan)
            gap = [a["mpjpe_mm"] - b["mpjpe_mm"] for a in rows for b in rows
                   if a["sequence"] == b["sequence"] == s and a["views"] == b["views"] == nv
                   and a["seed"] == b["seed"] and a["method"] == "triangulation"
                   and b["method"] == methods[-1]]
            print(f"| {s} | {nv} | " + " | ".join(f"{mu:.1f} ± {sd:.1f}" for mu, sd in cell.values())
                  + f" | {np.mean(gap):+.1f} (min {np.min(gap):+.1f}) |")


if __name__ == "__main__":
    main()

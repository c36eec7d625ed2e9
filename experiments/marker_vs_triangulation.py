"""Question: does the marker tracker (with refinement, confidences, learned offsets) beat
robust per-frame triangulation of the same keypoint detections, and by how much?

marker_apf against robust per-frame triangulation of the same keypoint detections.

    python experiments/marker_vs_triangulation.py --motions walk box gestures --seeds 0 1 2 \
        --variants base refine --out marker_vs_triangulation.json

Synthetic scenes (paper22 body, a shape drawn per seed, the HumanEva-like 4-view rig): the
25 BODY_25B keypoints of the landmark catalogue as a detector sees them: each found with
probability ``--detection`` at its projection plus Gaussian noise whose std grows as the
detector's confidence drops (confidence ~ U(0.4, 1), std = noise x (1.4 - c) / 0.7, mean
``--noise`` px), ``--false-positives`` wrong detections per view and frame (Poisson, random
label, uniform in the person's box grown by 30 %, confidence U(0.1, 0.6)), and optionally a
constant body-frame offset per keypoint (``--offset-mm``: std per axis; the detector's
"hip" is not our hip joint). Errors are measured against the true keypoint landmarks
without offsets, in mm, mean over keypoints and frames 1..F-1:

* ``triangulation``: :func:`mocap.trackers.markers.startup.triangulate_candidates` per frame
  (every pair of candidates a hypothesis, most inliers within the gate wins, re-triangulated
  from its inliers); landmarks it cannot triangulate are left out (its coverage is printed);
* ``marker_apf`` variants: the tracker (the ``marker_apf`` preset, :mod:`mocap.trackers.presets`)
  started by its own start-up on frame 0; ``refine``: with 3 Gauss-Newton steps
  (mocap/trackers/markers/refine.py);
  ``refine_noconf``: the same without confidence weights; ``refine_offsets``: plus keypoint
  offsets learned over 10 frames; ``conf`` / ``refine_conf`` / ``refine_conf_offsets``: the
  same with the confidence-weighted likelihood (``use_confidence``). The tracker's error is
  that of its landmarks without the learned offsets (the offsets model where the detector
  marks a landmark; the truth is the landmark itself), so triangulation, which sees only the
  detector's points, keeps the offsets in its error. With ``--mismatch`` the detector marks
  the true joints themselves, so the error of the tracker's keypoints (landmarks + learned
  offsets) is reported too (``error_keypoints_mm``, column ``...+kp``).
Writes one JSON row per (motion, seed, method) and prints the table.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocap.body import load_body
from mocap.body.catalogue import make_landmark_set
from mocap.body.skeletons import LAYOUTS, SKELETONS
from mocap.cameras import Rig, project, rig_from_config
from mocap.data.generate import make_synthetic
from mocap.data.sequence import Detections, Sequence
from mocap.data.sequence_io import load_sequence
from mocap.energy.markers import arrange_detections
from mocap.trackers.markers.startup import triangulate_candidates
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, track_sequence

LABELS = [n for n in LAYOUTS["BODY_25B"] if n is not None]
#: what the HumanEva-style ground truth's joints are in our landmark catalogue: its thorax is
#: the base of the neck (between the clavicles), its pelvis the midpoint of the hips
HUMANEVA_LANDMARKS = {"thorax": "neck_base", "pelvis": "mid_hip"}
HUMANEVA = ("pelvis", "thorax", "head", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow",
            "r_wrist", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")
VARIANTS = {
    "base": {"refine": {"iterations": 0}},
    "refine": {"refine": {"iterations": 3}},
    "refine_noconf": {"refine": {"iterations": 3, "use_confidence": False}},
    "refine_offsets": {"refine": {"iterations": 3}, "offsets": {"frames": 10}},
    "conf": {"refine": {"iterations": 0}, "use_confidence": True},
    "refine_conf": {"refine": {"iterations": 3}, "use_confidence": True},
    "refine_conf_offsets": {"refine": {"iterations": 3}, "offsets": {"frames": 10}, "use_confidence": True},
}


def detector(body, rig, seq, args, rng):
    """(Detections, true keypoints (F, L, 3)) of the module docstring."""
    lms = make_landmark_set(body, LABELS)
    shaped = body.shaped(seq.gt.alpha)
    G = shaped.pose(seq.gt.chi).transforms.astype(np.float64)           # (F, J, 4, 4)
    rest = lms.rest_points(shaped).astype(np.float64)
    truth = lms.from_transforms(G, rest)
    offsets = np.random.default_rng(1000).normal(0, args.offset_mm / 1e3, rest.shape)
    seen = lms.from_transforms(G, rest + offsets)
    return detect_points(rig, seen, lms.names, args, rng), truth


def detect_points(rig, seen, names, args, rng) -> Detections:
    """Detections of points seen: (F, L, 3) labelled ``names`` (module docstring's model)."""
    rest = seen[0]
    rows = []
    w, h = np.asarray(rig.sizes[0], np.float64)
    for f in range(len(seen)):
        px = project(rig, seen[f])                                       # (C, L, 2)
        for c in range(len(rig)):
            hit = rng.random(len(rest)) < args.detection
            conf = rng.uniform(0.4, 1.0, len(rest))
            xy = px[c] + rng.normal(0, 1, px[c].shape) * (args.noise * (1.4 - conf) / 0.7)[:, None]
            lab = np.arange(len(rest))
            n_fp = rng.poisson(args.false_positives)
            lo, hi = px[c].min(axis=0), px[c].max(axis=0)
            pad = 0.3 * (hi - lo)
            fp = rng.uniform(lo - pad, hi + pad, (n_fp, 2))
            xy = np.concatenate([xy[hit], fp])
            lab = np.concatenate([lab[hit], rng.integers(0, len(rest), n_fp)])
            conf = np.concatenate([conf[hit], rng.uniform(0.1, 0.6, n_fp)])
            inside = (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0) & (xy[:, 1] < h)
            for i in np.flatnonzero(inside):
                rows.append((f, c, lab[i], xy[i, 0], xy[i, 1], conf[i]))
    a = np.array(rows)
    return Detections(tuple(names), a[:, 0].astype(np.int64), a[:, 1].astype(np.int64),
                      a[:, 2].astype(np.int64), a[:, 3:5], a[:, 5])


def triangulation_error(trk, seq, truth) -> tuple[float, float]:
    errs, have = [], []
    for f in range(1, seq.num_frames):
        obs = arrange_detections(seq.detections.select(f), trk.landmarks.names, trk.rig)
        X, _ = triangulate_candidates(trk.pinhole, obs, trk.likelihood.gate_px)
        ok = np.isfinite(X[:, 0])
        errs.append(np.linalg.norm(X[ok] - truth[f][ok], axis=1))
        have.append(ok.mean())
    return 1e3 * float(np.concatenate(errs).mean()), float(np.mean(have))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--motions", nargs="+", default=["walk", "box", "gestures"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--variants", nargs="+", default=["base", "refine"], choices=list(VARIANTS))
    p.add_argument("--frames", type=int, default=50)
    p.add_argument("--detection", type=float, default=0.9)
    p.add_argument("--noise", type=float, default=2.0)
    p.add_argument("--false-positives", type=float, default=1.5)
    p.add_argument("--offset-mm", type=float, default=0.0)
    p.add_argument("--out", default="marker_vs_triangulation.json")
    p.add_argument("--mismatch", default=None, help="folder of model-mismatch sequences (<motion>/ sequence "
                   "folders with ground-truth joints): detect their 15 HumanEva joints instead")
    p.add_argument("--views", type=int, default=4, help="with --mismatch: the first N views")
    p.add_argument("--same-names", action="store_true", help="with --mismatch: label the truth's "
                   "thorax/pelvis as our thorax/pelvis joints (before: spine level, above the hips) "
                   "instead of the neck base / mid-hip landmarks they are")
    args = p.parse_args()
    body = load_body("paper22")
    rig = rig_from_config("humaneva")
    rows = []
    for motion in args.motions:
        for seed in args.seeds:
            if args.mismatch:
                seq = load_sequence(Path(args.mismatch) / motion, images=False)
                rig = Rig(tuple(seq.rig)[:args.views])
                # ground-truth names (HumanEva short names 'lsho', ... or ours) -> landmark names
                to_ours = {**SKELETONS["humaneva15"], **{n: n for n in HUMANEVA}}
                gt_names = [to_ours.get(str(n)) for n in seq.gt.joint_names]
                names = [n for n in HUMANEVA if n in gt_names]
                if len(names) < len(HUMANEVA):
                    raise SystemExit(f"{motion}: ground truth lacks {sorted(set(HUMANEVA) - set(names))}")
                truth = seq.gt.joints[:args.frames, [gt_names.index(n) for n in names]]
                if not args.same_names:
                    names = [HUMANEVA_LANDMARKS.get(n, n) for n in names]
                det = detect_points(rig, truth, names, args, np.random.default_rng([seed, 7]))
                seq = Sequence(name=motion, rig=rig, fps=seq.fps, detections=det)
            else:
                seq = make_synthetic(body, rig, motion=motion, frames=args.frames, fps=25, seed=seed,
                                     masks=False)
                det, truth = detector(body, rig, seq, args, np.random.default_rng([seed, 7]))
                names = LABELS
                seq = replace(seq, detections=det)
            for variant in args.variants:
                # the marker_apf preset (mocap.trackers.presets) with the variant's settings merged in
                trk = make_tracker("marker_apf", body=body, rig=rig, rng=np.random.default_rng(seed),
                                   **VARIANTS[variant])
                t = time.perf_counter()
                chi0, alpha = trk.initial_estimate(frame_of(seq, 0))
                res = track_sequence(trk, seq, chi0, alpha)
                sec = (time.perf_counter() - t) / seq.num_frames
                lms = trk.landmarks
                idx = [names.index(n) for n in lms.names]
                chis = np.stack([e.chi for e in res.estimates[1:]])
                shaped = body.shaped(alpha)
                # the tracker's landmarks (our joints), without the learned keypoint offsets: the
                # truth is the landmark, the offsets only model where the detector marks it
                rest = lms.rest_points(shaped).astype(np.float64)
                est = lms.from_transforms(shaped.pose(chis).transforms.astype(np.float64), rest)
                err = 1e3 * float(np.linalg.norm(est - truth[1:, idx], axis=-1).mean())
                row = {"motion": motion, "seed": seed, "method": f"marker_apf:{variant}", "error_mm": err,
                       "sec_per_frame": sec, "start_up": trk.start_up.get("chosen")}
                if args.mismatch and trk.offsets is not None:
                    # here the detector marks the truth itself: the tracker's estimate of it is
                    # the keypoint (landmark + learned offset), reported beside the landmark error
                    kp = lms.from_transforms(shaped.pose(chis).transforms.astype(np.float64),
                                             rest + trk.offsets)
                    kp_err = np.linalg.norm(kp - truth[1:, idx], axis=-1)
                    row["error_keypoints_mm"] = 1e3 * float(kp_err.mean())
                rows.append(row)
                print(rows[-1], flush=True)
            tri, cover = triangulation_error(trk, seq, truth[:, idx])
            rows.append({"motion": motion, "seed": seed, "method": "triangulation", "error_mm": tri,
                         "coverage": cover})
            print(rows[-1], flush=True)
    Path(args.out).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))
    for r in [r for r in rows if "error_keypoints_mm" in r]:
        rows.append({**r, "method": r["method"] + "+kp", "error_mm": r["error_keypoints_mm"]})
    methods = sorted({r["method"] for r in rows})
    print("| motion | " + " | ".join(methods) + " |")
    print("|---|" + "---|" * len(methods))
    for motion in args.motions:
        cells = []
        for m in methods:
            v = [r["error_mm"] for r in rows if r["motion"] == motion and r["method"] == m]
            cells.append(f"{np.mean(v):.1f} ± {np.std(v):.1f}")
        print(f"| {motion} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()

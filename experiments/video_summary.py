"""Question: which tracker fits a real recording best when every run is judged with the same
keypoint-to-joint offsets (fitted once, on the keypoint tracker)?

Table of ``mocap video-check`` runs on one recording, with one set of keypoint-to-joint offsets for all.

    python experiments/video_summary.py outputs/video_check/demo_0_40_2 [reference tracker]

Each subfolder is a run of ``mocap video-check`` (metrics.json + motion.npz) on the
same frames. The constant keypoint-to-landmark offsets are fitted ONCE, on the reference run
(default ``marker_apf``: the tracker that sees the keypoints), and applied to every run, so a
tracker's own bias is not absorbed; each run's self-fitted figure is listed as well. Writes
summary.json and summary.md into the folder.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np

from mocap.body.catalogue import make_landmark_set
from mocap.eval.keypoint_metrics import triangulate_detections
from mocap.eval.video_metrics import fit_offsets, lost_frames, offset_reprojection
from mocap.export.motion import load_motion
from mocap.run_folder import run_body, run_sequence


def main(folder: str, reference: str = "marker_apf") -> dict:
    root = Path(folder)
    runs = {p.name: p for p in sorted(root.iterdir())
            if (p / "motion.npz").is_file() and (p / "metrics.json").is_file()}
    if reference not in runs:
        raise FileNotFoundError(f"no {reference} run in {root} (runs: {sorted(runs)})")
    cfg = json.loads((runs[reference] / "metrics.json").read_text())["config"]
    body = run_body(cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = run_sequence(cfg, body, drop=("masks", "segmentation"))
    det = seq.detections
    lms = make_landmark_set(body, "auto", det.labels)
    px_scale = 1.0 / float(seq.meta.get("scale", 1.0))
    check = cfg["check"]

    def landmarks(run: Path) -> np.ndarray:
        motion = load_motion(run / "motion.npz")        # the shape of the last frame for all
        return lms.positions(body.shaped(motion.alpha[-1]), motion.chi).astype(np.float64)

    ref_X = landmarks(runs[reference])
    offsets = fit_offsets(seq.rig, ref_X, lms.names, det, check["min_confidence"])
    F = len(ref_X)
    rows = {}
    for name, run in runs.items():
        m = json.loads((run / "metrics.json").read_text())
        X = landmarks(run)
        shared = offset_reprojection(seq.rig, X, lms.names, det, check["min_confidence"], px_scale, offsets)
        # lost: median error with the shared offsets above lost_px (full-resolution px)
        lost = lost_frames(shared["fitted_per_frame_px"], None, check["lost_px"])
        rows[name] = {
            "frames": len(X), "raw_px": shared["median_px"], "shared_offsets_px": shared["fitted_median_px"],
            "shared_offsets_px_per_view": shared["fitted_median_px_per_view"],
            "self_offsets_px": m["reprojection"]["fitted_median_px"],
            "silhouette_iou": m.get("silhouette_iou"), "lost_frames_shared": lost,
            "lost_frames_run": m.get("lost_frames"),
            "sec_per_frame": m.get("sec_per_frame"), "init_seconds": m.get("init_seconds"),
            "apf_calls_per_frame": m.get("apf_calls_per_frame"),
        }
    T = triangulate_detections(seq.rig, det, lms.names, F, check["min_confidence"])
    tri = offset_reprojection(seq.rig, T, lms.names, det, check["min_confidence"], px_scale,
                              np.zeros_like(offsets))
    rows["triangulation (per frame)"] = {"frames": F, "raw_px": tri["median_px"], "shared_offsets_px": None,
                                         "self_offsets_px": None, "silhouette_iou": None,
                                         "lost_frames_shared": [], "sec_per_frame": None}
    base = rows[reference]["shared_offsets_px"]
    lines = ["| run | raw px | px, offsets fitted on " + reference + " | px, own offsets | silhouette IoU "
             "| lost frames | APF calls/frame | s/frame |", "|---|---|---|---|---|---|---|---|"]
    fmt = lambda v, f="{:.1f}": "-" if v is None else f.format(v)  # noqa: E731
    for name, r in rows.items():
        shown = r.get("shared_offsets_px") and name != reference
        ratio = f" ({r['shared_offsets_px'] / base:.2f}x)" if shown else ""
        lines.append(f"| {name} | {fmt(r['raw_px'])} | {fmt(r['shared_offsets_px'])}{ratio} | "
                     f"{fmt(r['self_offsets_px'])} | {fmt(r['silhouette_iou'], '{:.3f}')} | "
                     f"{r['lost_frames_shared'] or 'none'} | {fmt(r.get('apf_calls_per_frame'), '{:.2f}')} | "
                     f"{fmt(r.get('sec_per_frame'))} |")
    offsets_mm = {n: round(float(1e3 * np.linalg.norm(o))) for n, o in zip(lms.names, offsets, strict=True)}
    md = "\n".join(lines) + f"\n\nOffsets (mm, fitted on {reference}): {offsets_mm}\n"
    (root / "summary.md").write_text(md)
    (root / "summary.json").write_text(json.dumps({"reference": reference, "offsets_mm": offsets_mm,
                                                   "offsets_m": {n: o.tolist() for n, o in
                                                                 zip(lms.names, offsets, strict=True)},
                                                   "runs": rows}, indent=2))
    print(md)
    return rows


if __name__ == "__main__":
    main(*sys.argv[1:])

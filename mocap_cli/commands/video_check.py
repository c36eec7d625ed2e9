"""``mocap video-check``: track a real recording given as videos (init.mode=tracker: no ground
truth) and check the result independently: reprojection of the body's landmarks against the
confident keypoints (raw and with constant keypoint-to-joint offsets, fitted once and
reported), silhouette IoU of the tracked body against the masks, lost frames; the same
reprojection figures for per-frame triangulation of the keypoints. The run itself is
:func:`mocap.run_folder.run_tracking` (motion.npz, metrics.json, recording.rrd with video, masks and
the projected body per view); the check's figures are added to metrics.json.

    mocap video-check tracker=hybrid data.masks=outputs/segment/demo_0_40_2 data.stop=40
    mocap video-check --multirun tracker=hybrid,local,apf_prior,apf,marker_apf \\
        data.masks=outputs/segment/demo_0_40_2 data.stop=40
"""

from __future__ import annotations

from omegaconf import DictConfig

from mocap_cli.hydra_edge import run_command, track_run


def check_metrics(check: dict, metrics: dict, result, body, seq) -> dict:
    """The check's figures for a finished run (``check``: min_confidence, lost_px, lost_iou)."""
    # imported here: --help and argument errors import no numeric stack
    import numpy as np

    from mocap.body.catalogue import make_landmark_set
    from mocap.eval.keypoint_metrics import triangulate_detections
    from mocap.eval.video_metrics import lost_frames, offset_reprojection, silhouette_iou

    if seq.detections is None:
        raise ValueError("the check needs keypoint detections (data.keypoints)")
    chis = np.stack([e.chi for e in result.estimates])
    F = len(chis)
    shaped = body.shaped(result.estimates[-1].alpha)
    det = seq.detections
    lms = make_landmark_set(body, "auto", det.labels)
    X = lms.positions(shaped, chis).astype(np.float64)
    px_scale = 1.0 / float(seq.meta.get("scale", 1.0))          # report full-resolution pixels
    rep = offset_reprojection(seq.rig, X, lms.names, det, check["min_confidence"], px_scale)
    T = triangulate_detections(seq.rig, det, lms.names, F, check["min_confidence"])
    tri = offset_reprojection(seq.rig, T, lms.names, det, check["min_confidence"], px_scale)
    iou = None
    if seq.masks is not None:
        verts = np.stack([shaped.pose(c).vertices[0] for c in chis]).astype(np.float64)
        iou = silhouette_iou(verts, body.faces, seq.rig, seq.masks[:F])
    init = metrics.get("init", {})
    return {
        "source_frames": seq.meta.get("source_frames", [])[:F],
        "reprojection": rep,
        "triangulation_reprojection": {k: v for k, v in tri.items() if k != "offsets_mm"},
        "silhouette_iou": None if iou is None else float(iou.mean()),
        "silhouette_iou_per_view": None if iou is None else dict(zip(seq.rig.names, iou.mean(0).tolist(),
                                                                     strict=True)),
        "lost_frames": lost_frames(rep["fitted_per_frame_px"], iou, check["lost_px"], check["lost_iou"]),
        "init_seconds": float(init.get("seconds", 0.0)), "init_cached": bool(init.get("cached", False)),
        **({"init_hypotheses": init["hypotheses"]} if "hypotheses" in init else {}),
        "segmentation": seq.meta.get("segmentation"),
    }


def task(cfg: DictConfig) -> None:
    check = {k: float(v) for k, v in cfg.check.items()}

    def needs_keypoints(seq):
        if seq.detections is None:
            raise ValueError("the check needs keypoint detections (data.keypoints)")

    metrics = track_run(cfg, check_sequence=needs_keypoints,
                        extra=lambda m, result, body, seq: check_metrics(check, m, result, body, seq))
    if metrics is None:
        return
    rep, tri = metrics["reprojection"], metrics["triangulation_reprojection"]
    iou = "n/a" if metrics["silhouette_iou"] is None else f"{metrics['silhouette_iou']:.3f}"
    print(f"{metrics['tracker']}: reprojection {rep['median_px']:.1f} px raw, "
          f"{rep['fitted_median_px']:.1f} px with offsets (triangulation {tri['median_px']:.1f}); "
          f"silhouette IoU {iou}; "
          f"lost frames {metrics['lost_frames']}; "
          f"{metrics['sec_per_frame']:.1f} s/frame")


def main(argv: list[str] | None = None) -> int:
    """Run ``mocap video-check`` with Hydra overrides ``argv``."""
    return run_command(task, "video_check", "mocap video-check", argv)

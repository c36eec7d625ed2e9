"""Track a real recording given as videos (init.mode=tracker: no ground truth) and check the
result independently: reprojection of the body's landmarks against the confident keypoints
(raw and with constant keypoint-to-joint offsets, fitted once and reported), silhouette IoU
of the tracked body against the masks, lost frames; the same reprojection figures for
per-frame triangulation of the keypoints. Writes metrics.json, estimates.npz (chi per frame,
alpha) and recording.rrd (video, masks and the projected body per view) into the run folder.

    python experiments/video_check.py tracker=hybrid data.masks=outputs/segment/demo_0_40_2 data.stop=40
    python experiments/video_check.py --multirun tracker=hybrid,local,apf_prior,apf,marker_apf \
        data.masks=outputs/segment/demo_0_40_2 data.stop=40
"""

from __future__ import annotations

import json
from pathlib import Path

import hydra
import numpy as np
from _harness import parallel_jobs
from hydra.core.hydra_config import HydraConfig
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from mocap.body.catalogue import make_landmark_set
from mocap.eval.keypoint_metrics import triangulate_detections
from mocap.eval.run_metadata import run_metadata
from mocap.eval.run_metrics import run_metrics
from mocap.eval.video_metrics import lost_frames, offset_reprojection, silhouette_iou
from mocap.recording.factory import make_sink
from mocap.recording.sink import RunInfo
from mocap.threads import resolve_threads
from mocap.trackers.init_cache import initial_estimate
from mocap.trackers.run import frame_of, track_sequence

REPO = Path(__file__).resolve().parents[1]


@hydra.main(version_base="1.3", config_path="../mocap_cli/conf", config_name="video_check")
def main(cfg: DictConfig) -> None:
    out_dir = Path(HydraConfig.get().runtime.output_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    body = instantiate(cfg.body)
    seq = instantiate(cfg.data, _partial_=True)(body=body)
    if seq.detections is None:
        raise ValueError("the check needs keypoint detections (data.keypoints)")
    tracker = instantiate(cfg.tracker, _partial_=True)(body=body, rig=seq.rig,
                                                        rng=np.random.default_rng([cfg.seed, 1]),
                                                        keep_particles=False)
    # the silhouette trackers of a comparison share one self-initialisation (same body, frame,
    # rig, settings and seed): init.cache stores it (mocap/trackers/init_cache.py). Only those
    # are cached: the key holds init_settings, which a keypoint tracker's start-up lacks
    cache = cfg.init.cache if hasattr(tracker, "init_settings") else None
    init, alpha, init_info = initial_estimate(tracker, frame_of(seq, 0), cache)
    init_seconds = float(init_info["seconds"])
    F = seq.num_frames if cfg.frames is None else min(int(cfg.frames), seq.num_frames)
    config_yaml = OmegaConf.to_yaml(cfg, resolve=True)
    sink = make_sink(out_dir, **OmegaConf.to_container(cfg.recording))
    sink.start(RunInfo(config_yaml, run_metadata(config_yaml, REPO, int(cfg.seed), tracker=tracker.name,
                                                 data=seq.name)), body, seq)
    shaped = body.shaped(alpha)

    def record(f, est, seconds):
        out = shaped.pose(est.chi)
        sink.frame(frame_of(seq, f), est, out.joints[0], out.vertices[0], None, None, seconds)
        print(f"{tracker.name}: frame {f + 1}/{F} {seconds:.1f} s", flush=True)

    try:
        result = track_sequence(tracker, seq, init, alpha, F, on_frame=record,
                                threads=resolve_threads(cfg.get("threads", "auto"), parallel_jobs()))
    except BaseException:
        sink.finish(None, failed=True)
        raise
    chis = np.stack([e.chi for e in result.estimates])
    shaped = body.shaped(result.estimates[-1].alpha)
    det = seq.detections
    lms = make_landmark_set(body, "auto", det.labels)
    X = lms.positions(shaped, chis).astype(np.float64)
    px_scale = 1.0 / float(seq.meta.get("scale", 1.0))          # report full-resolution pixels
    check = cfg.check
    rep = offset_reprojection(seq.rig, X, lms.names, det, check.min_confidence, px_scale)
    T = triangulate_detections(seq.rig, det, lms.names, F, check.min_confidence)
    tri = offset_reprojection(seq.rig, T, lms.names, det, check.min_confidence, px_scale)
    iou = None
    if seq.masks is not None:
        verts = np.stack([shaped.pose(c).vertices[0] for c in chis]).astype(np.float64)
        iou = silhouette_iou(verts, body.faces, seq.rig, seq.masks[:F])
    lost = lost_frames(rep["fitted_per_frame_px"], iou, check.lost_px, check.lost_iou)
    metrics = {
        "tracker": tracker.name, "seed": int(cfg.seed), "data": seq.name, "frames": F,
        "source_frames": seq.meta.get("source_frames", [])[:F],
        "reprojection": rep,
        "triangulation_reprojection": {k: v for k, v in tri.items() if k != "offsets_mm"},
        "silhouette_iou": None if iou is None else float(iou.mean()),
        "silhouette_iou_per_view": None if iou is None else dict(zip(seq.rig.names, iou.mean(0).tolist(),
                                                                     strict=True)),
        "lost_frames": lost,
        "init_seconds": init_seconds, "init_cached": bool(init_info.get("cached", False)),
        **({"init_hypotheses": init_info["hypotheses"]} if "hypotheses" in init_info else {}),
        **{k: v for k, v in run_metrics(body, seq, result.estimates, result.seconds).items()
           if k in ("sec_per_frame", "energy_evals_per_frame", "apf_calls_per_frame")},
        "segmentation": seq.meta.get("segmentation"),
        "config": OmegaConf.to_container(cfg, resolve=True),
    }
    sink.finish(metrics)
    np.savez_compressed(out_dir / "estimates.npz", chi=chis, alpha=result.estimates[-1].alpha)
    (out_dir / "metrics.json").write_text(json.dumps(metrics, indent=2))
    print(f"{tracker.name}: reprojection {rep['median_px']:.1f} px raw, {rep['fitted_median_px']:.1f} px "
          f"with offsets (triangulation {tri['median_px']:.1f}); silhouette IoU "
          f"{metrics['silhouette_iou']}; lost frames {lost}; {metrics['sec_per_frame']:.1f} s/frame "
          f"-> {out_dir}")


if __name__ == "__main__":
    main()

"""The metrics of one tracking run (what metrics.json holds besides its config)."""

from __future__ import annotations

import numpy as np

from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.estimates import FrameEstimate, per_shape
from mocap.eval.metrics import mmta_mmtp
from mocap.eval.mismatch import LOST_MM, fit_oracle, mismatch_metrics


def _valid(gt, F: int):
    return None if gt.joint_valid is None else gt.joint_valid[:F]


_ORACLES: dict = {}
_SURFACE_ORACLES: dict = {}


def _oracle_key(body: BodyModel, seq: Sequence, F: int) -> tuple:
    return (body.name, body.num_dofs, seq.name, F, float(np.nansum(seq.gt.joints[:F])))


def oracle_fit(body: BodyModel, seq: Sequence, frames: int | None = None):
    """The oracle (:func:`mocap.eval.mismatch.fit_oracle`) on the first ``frames`` frames of
    ``seq``'s ground truth (all: None), fitted once per body and sequence in a process."""
    gt = seq.gt
    F = gt.num_frames if frames is None else frames
    key = _oracle_key(body, seq, F)
    if key not in _ORACLES:
        _ORACLES[key] = fit_oracle(body, gt.joint_names, gt.joints[:F], _valid(gt, F), gt.skeleton or None)
    return _ORACLES[key]


def oracle_metrics(body: BodyModel, seq: Sequence, frames: int | None = None) -> dict:
    """The oracle's metrics (:func:`oracle_fit`)."""
    return oracle_fit(body, seq, frames).metrics


def surface_oracle_metrics(body: BodyModel, seq: Sequence, frames: int) -> dict | None:
    """The surface oracle (:func:`mocap.eval.surface_oracle.fit_surface_oracle`) on the first
    ``frames`` frames of the true surface, from the joint oracle's fit (ground truth by name
    with both hips) or from the ground truth's own shape and poses (data our body generated);
    None where neither is there. Fitted once per body and sequence in a process."""
    from mocap.eval.surface_oracle import fit_surface_oracle

    gt = seq.gt
    key = _oracle_key(body, seq, frames)
    if key not in _SURFACE_ORACLES:
        if gt.chi is not None and gt.alpha is not None and gt.chi.shape[1] == body.num_dofs:
            alpha0, chi0 = gt.alpha, gt.chi[:frames]
        elif gt.chi is None and {"l_hip", "r_hip"} <= set(NameScorer(body, gt).mapping.values()):
            fit = oracle_fit(body, seq, frames)
            alpha0, chi0 = fit.alpha, fit.chi
        else:
            return None
        _SURFACE_ORACLES[key] = fit_surface_oracle(body, gt.surface[:frames], gt.surface_faces, alpha0,
                                                   chi0).metrics
    return _SURFACE_ORACLES[key]


def surface_run_metrics(body: BodyModel, seq: Sequence, chis: np.ndarray, alpha: np.ndarray) -> dict:
    """The surface part of :func:`accuracy_metrics` (a ground truth with ``surface``):
    :func:`mocap.eval.surface.surface_metrics` of the tracked mesh (``surface_to_mesh_mm``,
    ``..._p90_mm``, ``mesh_to_surface_mm``, ``..._p90_mm``, ``surface_per_frame``); with masks,
    the silhouette overlap (``silhouette_iou``, ``..._per_view``, ``..._per_frame``); the
    surface oracle's (``surface_oracle_mm``, ``surface_oracle_p90_mm``,
    ``surface_oracle_mesh_to_surface_mm``, ``surface_oracle``: all its metrics and frames); and
    ``surface_eval_sec`` (wall and process CPU seconds spent on the metrics and on the oracle; the
    oracle's once per sequence in a process, 0 when it was cached)."""
    import time

    from mocap.eval.surface import iou_metrics, silhouette_iou, surface_metrics

    F = len(chis)
    t0, c0 = time.perf_counter(), time.process_time()
    verts = per_shape(body, alpha, chis, lambda shaped, c: shaped.vertices(c)).astype(np.float64)
    out = surface_metrics(seq.gt.surface[:F], verts, body.faces, seq.gt.surface_faces)
    if seq.masks is not None:
        out.update(iou_metrics(silhouette_iou(seq.rig, body.faces, verts, seq.masks[:F]), seq.rig.names))
    t1, c1 = time.perf_counter(), time.process_time()
    oracle = surface_oracle_metrics(body, seq, F)
    if oracle is not None:
        out["surface_oracle_mm"] = oracle["surface_to_mesh_mm"]
        out["surface_oracle_p90_mm"] = oracle["surface_to_mesh_p90_mm"]
        out["surface_oracle_mesh_to_surface_mm"] = oracle["mesh_to_surface_mm"]
        out["surface_oracle"] = oracle
    t2, c2 = time.perf_counter(), time.process_time()
    out["surface_eval_sec"] = {"metrics": round(t1 - t0, 3), "oracle": round(t2 - t1, 3),
                               "metrics_cpu": round(c1 - c0, 3), "oracle_cpu": round(c2 - c1, 3)}
    return out


def run_metrics(body: BodyModel, seq: Sequence, estimates: list[FrameEstimate], seconds: list[float]) -> dict:
    """Accuracy against ground truth (when the sequence has it), speed and effort.

    estimates: one per frame, frame 0 being the initialisation; seconds: step time per frame.
    Keys: mpjpe_mm, mpjpe_std_mm, per_joint_mm, per_frame_mm, mpjpe_root_aligned_mm, pcp,
    pcp_per_limb (with ground truth, joints matched by name: :mod:`mocap.eval.by_name`),
    frames_lost (after frame 0, raw error above 150 mm); for ground truth by name only (data our
    model did not generate) ``mismatch`` (raw / offset-removed / limb errors) and ``oracle`` (the
    same for our body fitted to the true joints: :mod:`mocap.eval.mismatch`); mmta,
    mmtp_mm (when ground-truth markers match the default landmark set); with a true surface
    the surface metrics of :func:`surface_run_metrics`; without ground truth but
    with detections, the keypoint metrics of :func:`mocap.eval.keypoint_metrics.keypoint_run_metrics`
    (reprojection error per view, bone-length stability, jitter); sec_per_frame,
    energy_evals_per_frame, and apf_calls_per_frame when a tracker reports ``apf_called``.
    """
    F = len(estimates)
    tracked = seconds[1:]
    out: dict = {"frames": F}
    out.update(data_settings(seq))
    if seq.gt is not None:
        out.update(accuracy_metrics(body, seq, np.stack([e.chi for e in estimates]),
                                    np.stack([e.alpha for e in estimates])))
    keypoint_recording = "layout" in seq.meta     # read from keypoint files: scored on them too
    if seq.detections is not None and len(seq.detections) and (seq.gt is None or keypoint_recording):
        from mocap.eval.keypoint_metrics import keypoint_run_metrics

        out.update(keypoint_run_metrics(body, seq, estimates))
    out["sec_per_frame"] = float(np.mean(tracked)) if tracked else 0.0
    evals = [e.diagnostics.energy_evaluations for e in estimates[1:]]
    out["energy_evals_per_frame"] = float(np.mean(evals)) if evals else 0.0
    calls = [e.diagnostics.apf_called for e in estimates[1:] if e.diagnostics.apf_called is not None]
    if calls:
        out["apf_calls_per_frame"] = float(np.mean(calls))
    return out


def data_settings(seq: Sequence) -> dict:
    """What the data was read as, resolved (not the config's ``auto``): for keypoint recordings
    ``keypoints`` {layout, layout_setting, person}; ``ground_truth``: the ground-truth file
    and its people, when it came from a file."""
    out: dict = {}
    if "layout" in seq.meta:
        out["keypoints"] = {k: seq.meta[k] for k in ("layout", "layout_setting", "person") if k in seq.meta}
    if seq.gt is not None and "gt" in seq.meta:
        out["ground_truth"] = {"file": seq.meta["gt"], "people": list(seq.gt.person_names) or 1,
                               "skeleton": seq.gt.skeleton or "mocap"}
    return out


def accuracy_metrics(body: BodyModel, seq: Sequence, chis: np.ndarray, alpha: np.ndarray) -> dict:
    """The ground-truth part of :func:`run_metrics` for poses chis (F, D) of shape alpha (K,),
    or one shape per frame (F, K) (frame 0: the initialisation): what a run is re-scored with
    when the evaluation changes (``mocap rescore``). Ground truth of several people: the
    per-person scores of :func:`mocap.eval.people.score_people` (the run's one track assigned
    to the person it follows best)."""
    F = len(chis)
    out: dict = {}
    if seq.gt.person_names:
        return people_accuracy(body, seq.gt, [(alpha, chis)])
    scorer = NameScorer(body, seq.gt)
    points = scorer.points_by_shape(alpha, chis)
    scores = scorer.score(points)     # joints matched by name
    out.update({k: v for k, v in scores.items() if k not in ("scored", "unscored")})
    out["frames_lost"] = int(np.sum(np.asarray(scores["per_frame_mm"][1:]) > LOST_MM))
    if seq.gt.chi is None and {"l_hip", "r_hip"} <= set(scorer.mapping.values()):
        # data our model did not generate: errors fair under mismatch, and the floor
        out["mismatch"] = mismatch_metrics(points, seq.gt.joint_names,
                                           seq.gt.joints[:F], _valid(seq.gt, F), seq.gt.skeleton or None)
        out["oracle"] = oracle_metrics(body, seq, F)
    if seq.gt.surface is not None:
        out.update(surface_run_metrics(body, seq, chis, alpha))
    if scores["unscored"]:
        out["unscored_joints"] = scores["unscored"]
    landmarks = LandmarkSet(body)
    if seq.gt.markers is not None and tuple(seq.gt.marker_names) == landmarks.names:
        est_markers = per_shape(body, alpha, chis, landmarks.positions)
        out.update(mmta_mmtp(est_markers[1:], seq.gt.markers[1:F]) if F > 1 else {})
    return out


def people_accuracy(body: BodyModel, gt, tracks) -> dict:
    """Per-person accuracy of tracks [(alpha (K,) or (F, K), chis (F, D) with NaN rows where the
    track does not exist)] against a ground truth of several people (:mod:`mocap.eval.people`);
    ``frames_lost``: tracked frames of the assigned people above the lost threshold."""
    from mocap.eval.people import score_people

    scorer = NameScorer(body, gt.person(0))     # names checked against the body
    points = []
    for alpha, chis in tracks:
        chis = np.asarray(chis, np.float64)
        have = np.isfinite(chis).all(axis=1)
        pts = scorer.points_by_shape(alpha, np.where(have[:, None], chis, 0.0))
        points.append({n: np.where(have[:, None], v, np.nan) for n, v in pts.items()})
    out = score_people(points, gt, scorer.mapping, **scorer.kwargs)
    per_frame = [np.asarray(e["per_frame_mm"], float) for e in out["people"].values() if "per_frame_mm" in e]
    out["frames_lost"] = int(sum(np.sum(np.nan_to_num(pf[1:], nan=0.0) > LOST_MM) for pf in per_frame))
    return out

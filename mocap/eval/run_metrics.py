"""The metrics of one tracking run (what metrics.json holds besides its config)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel
from mocap.body.skeleton import joint_offsets_of
from mocap.data.sequence import Sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.estimates import FrameEstimate, per_shape
from mocap.eval.metrics import mmta_mmtp
from mocap.eval.mismatch import LOST_MM, fit_oracle, mismatch_metrics
from mocap.safe_files import write_text_atomic


def _valid(gt, F: int):
    return None if gt.joint_valid is None else gt.joint_valid[:F]


#: the oracle's solver in a run's metrics (:func:`mocap.eval.mismatch.fit_oracle`'s ``method``)
ORACLE_METHOD = "tracked"
#: the version of the oracle's results: a cached fit is reused only by the same version (raise it
#: when the fit or its metrics change)
ORACLE_VERSION = 1


@dataclass(frozen=True)
class OracleSettings:
    """The ``oracle`` block of a run's config: the oracle is our body fitted to the true joints
    (data our model did not generate; the floor every tracker is compared to).

    enabled: fit it (False: a run's metrics.json has no ``oracle`` and the ablation table's oracle
    columns stay empty; the tracking and every other metric are unchanged). cache: a folder
    keeping each fit by the content hash of the ground truth it was fitted to (with the body and
    :data:`ORACLE_VERSION`), so the runs of a sweep over one sequence fit it once (None: only
    within a process)."""

    enabled: bool = True
    cache: str | None = None

    def __post_init__(self):
        if not isinstance(self.enabled, bool):
            raise ValueError(f"setting oracle.enabled = {self.enabled!r}: true or false")
        if self.cache is not None and not isinstance(self.cache, str | Path):
            raise ValueError(f"setting oracle.cache = {self.cache!r}: a folder or null")


def oracle_settings(config: Mapping | OracleSettings | None) -> OracleSettings:
    """OracleSettings from a config's ``oracle`` block (None: the defaults); an unknown key or a
    bad value raises ValueError naming it."""
    if isinstance(config, OracleSettings):
        return config
    config = dict(config or {})
    unknown = sorted(set(config) - {f.name for f in fields(OracleSettings)})
    if unknown:
        raise ValueError(f"setting oracle.{unknown[0]} is not a setting (oracle has: enabled, cache)")
    return OracleSettings(**config)


_ORACLES: dict = {}          # key -> the joint oracle's metrics
_FITS: dict = {}             # key -> the joint oracle's fit (the surface oracle starts from it)
_SURFACE_ORACLES: dict = {}  # key -> the surface oracle's metrics


def oracle_key(body: BodyModel, gt, F: int) -> str:
    """The content hash naming an oracle fit: the body (name, DOFs, model), the ground truth's
    names, skeleton, first F frames of joints and validity, the solver and :data:`ORACLE_VERSION`."""
    from mocap.export.motion import model_hash

    h = hashlib.sha256()
    h.update(json.dumps([body.name, list(body.dof_names), model_hash(body), list(gt.joint_names),
                         gt.skeleton or "", F, ORACLE_METHOD, ORACLE_VERSION]).encode())
    h.update(np.ascontiguousarray(gt.joints[:F], np.float64).tobytes())
    valid = _valid(gt, F)
    h.update(b"-" if valid is None else np.ascontiguousarray(valid, bool).tobytes())
    return h.hexdigest()[:32]


def oracle_fit(body: BodyModel, seq: Sequence, frames: int | None = None):
    """The oracle (:func:`mocap.eval.mismatch.fit_oracle`, :data:`ORACLE_METHOD`) on the first
    ``frames`` frames of ``seq``'s ground truth (all: None), fitted once per body and ground
    truth in a process."""
    gt = seq.gt
    F = gt.num_frames if frames is None else frames
    key = oracle_key(body, gt, F)
    if key not in _FITS:
        _FITS[key] = fit_oracle(body, gt.joint_names, gt.joints[:F], _valid(gt, F), gt.skeleton or None,
                                method=ORACLE_METHOD)
        _ORACLES.setdefault(key, _FITS[key].metrics)
    return _FITS[key]


def _cached(path: Path | None, key: str, compute, memo: dict, **info) -> dict:
    """``memo[key]``, else the metrics stored in ``path`` (by an earlier run), else ``compute()``,
    written there (to a temporary name, renamed: runs in parallel never read half a file)."""
    if key in memo:
        return memo[key]
    if path is not None and path.is_file():
        try:
            memo[key] = json.loads(path.read_text())["metrics"]
            return memo[key]
        except (OSError, ValueError, KeyError):
            pass                                         # unreadable: fitted again, rewritten
    metrics = compute()
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, json.dumps({"key": key, **info, "metrics": metrics}))
    memo[key] = metrics
    return metrics


def oracle_metrics(body: BodyModel, seq: Sequence, frames: int | None = None,
                   settings: OracleSettings | None = None) -> dict:
    """The oracle's metrics (:func:`oracle_fit`) on the first ``frames`` frames of ``seq``'s
    ground truth (all: None), computed once per body and ground truth in a process, and once per
    cache folder when ``settings.cache`` names one (the file ``oracle-<key>.json``,
    :func:`oracle_key`)."""
    settings = settings or OracleSettings()
    F = seq.gt.num_frames if frames is None else frames
    key = oracle_key(body, seq.gt, F)
    path = None if settings.cache is None else Path(settings.cache) / f"oracle-{key}.json"
    return _cached(path, key, lambda: oracle_fit(body, seq, F).metrics, _ORACLES, data=seq.name, frames=F)


def surface_oracle_metrics(body: BodyModel, seq: Sequence, frames: int,
                           settings: OracleSettings | None = None) -> dict | None:
    """The surface oracle (:func:`mocap.eval.surface_oracle.fit_surface_oracle`) on the first
    ``frames`` frames of the true surface, from the joint oracle's fit (ground truth by name
    with both hips) or from the ground truth's own shape and poses (data our body generated);
    None where neither is there. Fitted once per body and ground truth in a process, and once per
    cache folder (``surface-oracle-<key>.json``) when ``settings.cache`` names one."""
    from mocap.eval.surface_oracle import fit_surface_oracle

    settings = settings or OracleSettings()
    gt = seq.gt
    own = gt.chi is not None and gt.alpha is not None and gt.chi.shape[1] == body.num_dofs
    by_name = gt.chi is None and {"l_hip", "r_hip"} <= set(NameScorer(body, gt).mapping.values())
    if not own and not by_name:
        return None
    h = hashlib.sha256(oracle_key(body, gt, frames).encode())
    h.update(np.ascontiguousarray(gt.surface[:frames], np.float64).tobytes())
    h.update(b"-" if gt.surface_faces is None else np.ascontiguousarray(gt.surface_faces, np.int64).tobytes())
    key = h.hexdigest()[:32]

    def compute():
        if own:
            alpha0, chi0 = gt.alpha, gt.chi[:frames]
        else:
            fit = oracle_fit(body, seq, frames)
            alpha0, chi0 = fit.alpha, fit.chi
        return fit_surface_oracle(body, gt.surface[:frames], gt.surface_faces, alpha0, chi0).metrics

    path = None if settings.cache is None else Path(settings.cache) / f"surface-oracle-{key}.json"
    return _cached(path, key, compute, _SURFACE_ORACLES, data=seq.name, frames=frames)


def surface_run_metrics(body: BodyModel, seq: Sequence, chis: np.ndarray, alpha: np.ndarray,
                        oracle: OracleSettings | None = None,
                        joint_offsets: np.ndarray | None = None) -> dict:
    """The surface part of :func:`accuracy_metrics` (a ground truth with ``surface``):
    :func:`mocap.eval.surface.surface_metrics` of the tracked mesh (``surface_to_mesh_mm``,
    ``..._p90_mm``, ``mesh_to_surface_mm``, ``..._p90_mm``, ``surface_per_frame``); with masks,
    the silhouette overlap (``silhouette_iou``, ``..._per_view``, ``..._per_frame``); where
    ``oracle.enabled``, the surface oracle's (``surface_oracle_mm``, ``surface_oracle_p90_mm``,
    ``surface_oracle_mesh_to_surface_mm``, ``surface_oracle``: all its metrics and frames); and
    ``surface_eval_sec`` (wall and process CPU seconds spent on the metrics and on the oracle; the
    oracle's once per ground truth in a process or cache folder, 0 when it was cached)."""
    import time

    from mocap.eval.surface import iou_metrics, silhouette_iou, surface_metrics

    oracle = oracle or OracleSettings()
    F = len(chis)
    t0, c0 = time.perf_counter(), time.process_time()
    verts = per_shape(body, alpha, chis, lambda shaped, c: shaped.vertices(c),
                      joint_offsets).astype(np.float64)
    out = surface_metrics(seq.gt.surface[:F], verts, body.faces, seq.gt.surface_faces)
    if seq.masks is not None:
        out.update(iou_metrics(silhouette_iou(seq.rig, body.faces, verts, seq.masks[:F]), seq.rig.names))
    t1, c1 = time.perf_counter(), time.process_time()
    fit = surface_oracle_metrics(body, seq, F, oracle) if oracle.enabled else None
    if fit is not None:
        out["surface_oracle_mm"] = fit["surface_to_mesh_mm"]
        out["surface_oracle_p90_mm"] = fit["surface_to_mesh_p90_mm"]
        out["surface_oracle_mesh_to_surface_mm"] = fit["mesh_to_surface_mm"]
        out["surface_oracle"] = fit
    t2, c2 = time.perf_counter(), time.process_time()
    out["surface_eval_sec"] = {"metrics": round(t1 - t0, 3), "oracle": round(t2 - t1, 3),
                               "metrics_cpu": round(c1 - c0, 3), "oracle_cpu": round(c2 - c1, 3)}
    return out


def frames_without_detections(detections, frames: int) -> list[int]:
    """The frames (of the first ``frames``) in which no view has a detection (ascending)."""
    seen = np.zeros(frames, bool)
    f = np.asarray(detections.frame, np.int64)
    seen[f[(f >= 0) & (f < frames)]] = True
    return [int(i) for i in np.flatnonzero(~seen)]


def run_metrics(body: BodyModel, seq: Sequence, estimates: list[FrameEstimate], seconds: list[float],
                oracle: OracleSettings | Mapping | None = None) -> dict:
    """Accuracy against ground truth (when the sequence has it), speed and effort.

    estimates: one per frame, frame 0 being the initialisation; seconds: step time per frame.
    Keys: mpjpe_mm, mpjpe_std_mm, per_joint_mm, per_frame_mm, mpjpe_root_aligned_mm, pcp,
    pcp_per_limb (with ground truth, joints matched by name: :mod:`mocap.eval.by_name`),
    frames_lost (after frame 0, raw error above 150 mm); for ground truth by name only (data our
    model did not generate) ``mismatch`` (raw / offset-removed / limb errors) and ``oracle`` (the
    same for our body fitted to the true joints: :mod:`mocap.eval.mismatch`); mmta,
    mmtp_mm (when ground-truth markers match the default landmark set); with a true surface the
    surface metrics of :func:`surface_run_metrics`; with detections,
    frames_without_detections (frames tracked with no detection in any view: blind); without
    ground truth but with detections, the keypoint metrics of
    :func:`mocap.eval.keypoint_metrics.keypoint_run_metrics` (reprojection error per view,
    bone-length stability, jitter); sec_per_frame,
    energy_evals_per_frame, and apf_calls_per_frame when a tracker reports ``apf_called``.
    ``oracle``: whether and where the oracle is fitted (:class:`OracleSettings`, a run config's
    ``oracle`` block).
    """
    F = len(estimates)
    tracked = seconds[1:]
    out: dict = {"frames": F}
    out.update(data_settings(seq))
    if seq.gt is not None:
        out.update(accuracy_metrics(body, seq, np.stack([e.chi for e in estimates]),
                                    np.stack([e.alpha for e in estimates]), oracle,
                                    joint_offsets_of(estimates, body.num_joints)))
    if seq.detections is not None:      # tracked blind: frames whose views hold no detection at all
        out["frames_without_detections"] = frames_without_detections(seq.detections, F)
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
    choices = [e.diagnostics.start_choice for e in estimates if e.diagnostics.start_choice]
    if choices:                         # the hybrid's start chosen over frames (start_frames)
        out["start_choice"] = dict(choices[0])
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


def accuracy_metrics(body: BodyModel, seq: Sequence, chis: np.ndarray, alpha: np.ndarray,
                     oracle: OracleSettings | Mapping | None = None,
                     joint_offsets: np.ndarray | None = None) -> dict:
    """The ground-truth part of :func:`run_metrics` for poses chis (F, D) of shape alpha (K,),
    or one shape per frame (F, K) (frame 0: the initialisation), and rest-joint corrections
    ``joint_offsets`` (None, (J, 3) or (F, J, 3)): what a run is re-scored with
    when the evaluation changes (``mocap rescore``). Ground truth of several people: the
    per-person scores of :func:`mocap.eval.people.score_people` (the run's one track assigned
    to the person it follows best). ``oracle``: as in :func:`run_metrics`."""
    oracle = oracle_settings(oracle)
    F = len(chis)
    out: dict = {}
    if seq.gt.person_names:
        return people_accuracy(body, seq.gt, [(alpha, chis)])
    scorer = NameScorer(body, seq.gt)
    points = scorer.points_by_shape(alpha, chis, joint_offsets)
    scores = scorer.score(points)     # joints matched by name
    out.update({k: v for k, v in scores.items() if k not in ("scored", "unscored")})
    out["frames_lost"] = int(np.sum(np.asarray(scores["per_frame_mm"][1:]) > LOST_MM))
    if seq.gt.chi is None and {"l_hip", "r_hip"} <= set(scorer.mapping.values()):
        # data our model did not generate: errors fair under mismatch, and the floor
        out["mismatch"] = mismatch_metrics(points, seq.gt.joint_names,
                                           seq.gt.joints[:F], _valid(seq.gt, F), seq.gt.skeleton or None)
        if oracle.enabled:
            out["oracle"] = oracle_metrics(body, seq, F, oracle)
    if seq.gt.surface is not None:
        out.update(surface_run_metrics(body, seq, chis, alpha, oracle, joint_offsets))
    if scores["unscored"]:
        out["unscored_joints"] = scores["unscored"]
    landmarks = LandmarkSet(body)
    if seq.gt.markers is not None and tuple(seq.gt.marker_names) == landmarks.names:
        est_markers = per_shape(body, alpha, chis, landmarks.positions, joint_offsets)
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

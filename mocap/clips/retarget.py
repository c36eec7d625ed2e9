"""Retargeting a motion-capture clip onto our body: per frame the pose chi, and one shape alpha
per clip, that best place our body's points on the clip's joints.

The clip's joints are renamed to our points by the skeleton's name map (:mod:`mocap.clips.names`:
body joints or landmarks of the catalogue, e.g. ``Hips -> mid_hip``, ``UpperLeg_L -> l_hip``).
Least squares on those points (:mod:`mocap.clips.fit`, the oracle's machinery), joint limits as
bounds:

1. ``shape_frames`` frames spread over the clip: each frame's pose at the mean shape from
   ``starts`` starting points (the oracle's starts; each solved as in step 3);
2. shape and those frames' poses jointly (the oracle's second step, solved by
   Levenberg-Marquardt on the analytic pose Jacobian): the clip's alpha, fixed from then on;
3. every frame in order, each starting from the previous frame's pose (temporal warm start;
   frame 0 from step 2's), by bounded Levenberg-Marquardt on the analytic Jacobian; a frame whose
   worst point stays over ``restart_mm`` off is solved again from a Kabsch start and the best
   kept.

The residual of each point in each frame (mm) is what no pose of our body within its limits
can explain: different joint definitions (a mocap joint CENTRE against our body's joint), a
spine that bends where ours is rigid, limits. :class:`Retargeted` keeps them with summaries.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.clips.bvh import Clip, resample
from mocap.clips.fit import (
    PointFunction,
    fit_shape_lm,
    multistart_frames,
    pose_bounds,
    torso_points,
    track_poses,
)
from mocap.clips.names import NameMap, load_map, map_named


@dataclass(frozen=True)
class Retargeted:
    """A clip on our body (F frames, S fitted points, D DOFs, K shape coefficients).

    chi (F, D) poses, alpha (K,) the clip's shape; targets (F, S, 3) the clip's joints and
    fitted (F, S, 3) our points (metres, Z up); residual_mm (F, S) their distances;
    point_names (S,) our names, clip_names (S,) the clip's; frame_index (F,) the clip's
    frames used, times (F,) seconds; fps of the result; shape_frames: the frames alpha was
    fitted on (indices into the F frames); seconds: wall time of the whole retargeting,
    cpu_seconds: its process CPU time (what a busy machine does not inflate)."""

    path: Path | None
    body: str
    dof_names: tuple[str, ...]
    fps: float
    frame_index: np.ndarray
    times: np.ndarray
    chi: np.ndarray
    alpha: np.ndarray
    point_names: tuple[str, ...]
    clip_names: tuple[str, ...]
    targets: np.ndarray
    fitted: np.ndarray
    residual_mm: np.ndarray
    shape_frames: np.ndarray
    seconds: float
    name_map: str = ""
    match: str = "positions"
    cpu_seconds: float = float("nan")

    @property
    def num_frames(self) -> int:
        return len(self.chi)

    @property
    def median_mm(self) -> float:
        """Median over all frames and points."""
        return float(np.median(self.residual_mm))

    @property
    def max_mm(self) -> float:
        return float(np.max(self.residual_mm))

    @property
    def mean_mm(self) -> float:
        return float(np.mean(self.residual_mm))

    @property
    def per_joint_median_mm(self) -> dict[str, float]:
        """Our point name -> median residual over frames."""
        med = np.median(self.residual_mm, axis=0)
        return {n: float(v) for n, v in zip(self.point_names, med, strict=True)}

    @property
    def per_joint_max_mm(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.point_names, np.max(self.residual_mm, axis=0), strict=True)}

    @property
    def seconds_per_frame(self) -> float:
        return self.seconds / max(self.num_frames, 1)

    def summary(self) -> dict:
        """Plain numbers (JSON-ready)."""
        return {"path": str(self.path) if self.path else "", "frames": self.num_frames, "fps": self.fps,
                "median_mm": self.median_mm, "max_mm": self.max_mm, "mean_mm": self.mean_mm,
                "per_joint_median_mm": self.per_joint_median_mm, "per_joint_max_mm": self.per_joint_max_mm,
                "seconds": self.seconds, "ms_per_frame": 1e3 * self.seconds_per_frame,
                "cpu_seconds": self.cpu_seconds,
                "cpu_ms_per_frame": 1e3 * self.cpu_seconds / max(self.num_frames, 1),
                "body": self.body, "name_map": self.name_map, "match": self.match}


def clip_targets(clip: Clip, body: BodyModel, name_map: NameMap | str | Path | None = None
                 ) -> tuple[NameMap, list[str], list[str], np.ndarray]:
    """The clip's mapped joints: (map, clip names, our names, positions (F, S, 3)). ``name_map``:
    a :class:`NameMap`, a shipped map's name, a YAML path, or None (the map that recognised the
    clip when it was read)."""
    from mocap.body.catalogue import CATALOGUE

    if isinstance(name_map, NameMap):
        nm = name_map
    elif isinstance(name_map, Path) or (isinstance(name_map, str) and name_map.endswith((".yaml", ".yml"))):
        nm = load_map(name_map)
    elif isinstance(name_map, str):
        nm = map_named(name_map)
    elif clip.name_map:
        nm = map_named(clip.name_map)
    else:
        raise ValueError(f"{clip.path}: no name map recognises its skeleton (joints "
                         f"{', '.join(clip.names[:6])}, ...): add one to mocap/clips/maps/ or pass "
                         "name_map= (a YAML file, see docs/clips.md)")
    known = set(body.joint_names) | set(CATALOGUE)
    unknown = sorted({v for v in nm.joints.values() if v not in known})
    if unknown:
        raise ValueError(f"name map {nm.name!r} ({nm.source}): no point of body {body.name!r} is called "
                         f"{', '.join(unknown)} (body joints or landmarks of mocap.body.catalogue)")
    pairs = [(c, o) for c, o in nm.joints.items() if c in clip.names]
    if len(pairs) < 4:
        raise ValueError(f"{clip.path}: only {len(pairs)} of its joints are mapped by {nm.name!r} "
                         f"({nm.source}); retargeting needs at least 4")
    clip_names = [c for c, _ in pairs]
    ours = [o for _, o in pairs]
    dup = sorted({o for o in ours if ours.count(o) > 1})
    if dup:
        raise ValueError(f"name map {nm.name!r}: several clip joints map to {', '.join(dup)}")
    targets = np.stack([clip.joint(c) for c in clip_names], axis=1)
    return nm, clip_names, ours, targets


def retarget_points(point_names: list[str] | tuple[str, ...], targets: np.ndarray, body: BodyModel, *,
                    shape_frames: int = 10, starts: int = 4, shape_bound: float = 3.0,
                    alpha: np.ndarray | None = None, restart_mm: float = 40.0, seed: int = 0,
                    valid: np.ndarray | None = None, shape_iterations: int = 60,
                    segments: list[tuple[int, int]] | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The core: poses (F, D) and one shape (K,) placing our points ``point_names`` (S,) on
    ``targets`` (F, S, 3) metres (see the module docstring). ``alpha``: a fixed shape (steps 1-2
    skipped except for frame 0's pose); valid (F, S) bool: missing targets; shape_iterations: the
    most Levenberg-Marquardt iterations of step 2. -> chi (F, D),
    alpha (K,), fitted points (F, S, 3), shape_frames (indices). ``segments``: (parent, child)
    point indices; given, step 3 matches the first point's position and each segment's
    DIRECTION (our segment, of our length, along the clip's) instead of the positions (see
    :func:`retarget`, ``match="segments"``)."""
    targets = np.asarray(targets, np.float64)
    F, S = targets.shape[:2]
    if targets.shape != (F, len(point_names), 3) or F == 0:
        raise ValueError(f"targets {targets.shape} do not match {len(point_names)} point names (F, S, 3)")
    valid = np.isfinite(targets).all(axis=-1) if valid is None else np.asarray(valid, bool)
    fn = PointFunction(body, point_names)
    w = valid.astype(np.float64)[..., None]
    target = np.where(valid[..., None], targets, 0.0)
    lo_d, hi_d = pose_bounds(body)
    torso = torso_points(point_names)
    rng = np.random.default_rng(seed)
    sel = np.unique(np.linspace(0, F - 1, min(shape_frames, F)).round().astype(int))
    a0 = np.zeros(body.num_shape) if alpha is None else np.asarray(alpha, np.float64)
    best, _ = multistart_frames(fn, a0, target[sel], w[sel, :, 0], lo_d, hi_d, torso, starts, rng)
    if alpha is None:
        alpha, poses, _ = fit_shape_lm(fn, target[sel], w[sel, :, 0], best, lo_d, hi_d, shape_bound,
                                       iterations=shape_iterations)
    else:
        alpha, poses = a0, best
    if segments is None:
        chi, _ = track_poses(fn, alpha, target, w[..., 0], poses[0], lo_d, hi_d, restart_mm, torso)
    else:
        if not valid.all():
            raise ValueError("match='segments' needs every target in every frame")
        C, rows = segment_rows(fn, alpha, targets, segments)
        chi, _ = track_poses(fn, alpha, rows, np.ones(rows.shape[:2]), poses[0], lo_d, hi_d, restart_mm,
                             torso, combine=C, restart_target=targets)
    return chi, alpha, fn(alpha, chi), sel


def segment_rows(fn: PointFunction, alpha: np.ndarray, targets: np.ndarray,
                 segments: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """The rows of segment matching: combine (R, S) and targets (F, R, 3). Row 0: the first
    segment's parent point at its target position; row r: child - parent, whose target is our
    rest length of that segment (shape alpha) along the clip's direction."""
    S = targets.shape[1]
    root = segments[0][0]
    C = np.zeros((1 + len(segments), S))
    C[0, root] = 1.0
    rest = fn(alpha, np.zeros((1, fn.body.num_dofs)))[0]
    rows = [targets[:, root]]
    for r, (p, c) in enumerate(segments, start=1):
        C[r, c], C[r, p] = 1.0, -1.0
        d = targets[:, c] - targets[:, p]
        unit = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
        rows.append(np.linalg.norm(rest[c] - rest[p]) * unit)
    return C, np.stack(rows, axis=1)


def clip_segments(clip: Clip, clip_names: list[str]) -> list[tuple[int, int]]:
    """(parent, child) indices into clip_names: each mapped joint and its nearest mapped
    ancestor in the clip's hierarchy; the segment from the mapped root comes first."""
    index = {n: k for k, n in enumerate(clip_names)}
    segs = []
    for c in clip_names:
        j = clip.parents[clip.names.index(c)]
        while j >= 0 and clip.names[j] not in index:
            j = clip.parents[j]
        if j >= 0:
            segs.append((index[clip.names[j]], index[c]))
    roots = {p for p, _ in segs} - {c for _, c in segs}
    if len(roots) != 1:
        raise ValueError(f"{clip.path}: the mapped joints form {len(roots)} trees; "
                         "match='segments' needs one")
    root = roots.pop()
    return sorted(segs, key=lambda pc: pc[0] != root)


def retarget(clip: Clip, body: BodyModel, *, name_map: NameMap | str | Path | None = None, step: int = 1,
             fps: float | None = None, shape_frames: int = 10, starts: int = 4, shape_bound: float = 3.0,
             alpha: np.ndarray | None = None, restart_mm: float = 40.0, seed: int = 0,
             shape_iterations: int = 60, match: str = "positions") -> Retargeted:
    """Retarget ``clip`` onto ``body`` (module docstring). ``fps``: resample the clip first
    (:func:`mocap.clips.bvh.resample`); ``step``: then keep every step-th frame; ``alpha``: use
    this shape instead of fitting one.

    ``match="positions"`` (default): step 3 places our points on the clip's joints.
    ``match="segments"``: step 3 places the mapped root (the Bandai Hips: our pelvis) and turns
    each of our segments (between a mapped joint and its nearest mapped ancestor in the clip's
    hierarchy: pelvis-hip, hip-knee, ..., neck base-shoulder, shoulder-elbow, ...) along the
    clip's, keeping our lengths. Where the clip's proportions differ from any of our shapes
    (Bandai's shoulders are 0.21 m apart, ours 0.35 m), positions bend the limbs to reach
    misplaced joints; segments copy the limbs' directions. The residuals are positions in both."""
    if not (isinstance(step, int) and step >= 1):
        raise ValueError(f"step={step!r} for {clip.path}: a positive integer")
    if match not in ("positions", "segments"):
        raise ValueError(f"match={match!r} for {clip.path}: 'positions' or 'segments'")
    t0, c0 = time.perf_counter(), time.process_time()
    if fps is not None:
        clip = resample(clip, fps)
    nm, clip_names, ours, targets = clip_targets(clip, body, name_map)
    keep = np.arange(0, clip.num_frames, step)
    targets = targets[keep]
    chi, alpha, fitted, sel = retarget_points(ours, targets, body, shape_frames=shape_frames, starts=starts,
                                              shape_bound=shape_bound, alpha=alpha,
                                              restart_mm=restart_mm, seed=seed,
                                              shape_iterations=shape_iterations,
                                              segments=clip_segments(clip, clip_names) if match == "segments"
                                              else None)
    times = clip.times[keep] if clip.times is not None else clip.frame_index[keep] / clip.fps
    return Retargeted(path=clip.path, body=body.name, dof_names=tuple(body.dof_names), fps=clip.fps / step,
                      frame_index=clip.frame_index[keep], times=times, chi=chi, alpha=alpha,
                      point_names=tuple(ours), clip_names=tuple(clip_names), targets=targets, fitted=fitted,
                      residual_mm=1e3 * np.linalg.norm(fitted - targets, axis=-1), shape_frames=sel,
                      seconds=time.perf_counter() - t0, name_map=nm.name, match=match,
                      cpu_seconds=time.process_time() - c0)

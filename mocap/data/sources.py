"""Sequences from configuration (``conf/data/*.yaml``): synthetic in memory, or a folder."""

from __future__ import annotations

from collections.abc import Mapping
from collections.abc import Sequence as Sequence_
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import rig_from_config
from mocap.data.corruption import SilhouetteNoise
from mocap.data.generate import make_synthetic
from mocap.data.sequence import Detections, Sequence
from mocap.data.sequence_io import NO_GT_HINT, gt_opted_out, load_sequence


def synthetic_sequence(*, body: BodyModel, cameras: str | Mapping, motion: str, frames: int,
                       fps: float, seed: int, name: str = "synthetic", **options) -> Sequence:
    """Generate a sequence in memory (see :func:`mocap.data.generate.make_synthetic`)."""
    from mocap.checks import check_fps

    check_fps(fps, "data.fps")
    rig = rig_from_config(cameras)
    return make_synthetic(body, rig, motion=motion, frames=frames, fps=fps, seed=seed, name=name,
                          **options)


def folder_sequence(*, body: BodyModel, path: str, images: bool = True, name: str | None = None,
                    views: Sequence_[int | str] | None = None,
                    silhouette_noise: Mapping | None = None, seed: int = 0,
                    nonfinite: str = "refuse", gt: str | None = None,
                    detections: Mapping | None = None) -> Sequence:
    """A sequence folder written by ``mocap make-dataset`` (or converted data).

    path: the folder (a relative path is relative to the working directory).
    views: keep only these views (indices or camera names, in this order), e.g. [0, 2, 4, 6].
    silhouette_noise: options of :class:`mocap.data.corruption.SilhouetteNoise` applied to
    every mask, deterministically for ``seed`` (the same seed gives the same masks).
    nonfinite: NaN / Inf in the ground truth or detections: refuse (default) or drop them
    (counted in the sequence's meta and the run's metrics.json, ``dropped_nonfinite``).
    gt: a ground-truth file used instead of the folder's gt.npz (which is otherwise used
    whenever it is there): joints by name, :func:`mocap.data.sequence_io.load_ground_truth`;
    "none": no ground truth, the folder's gt.npz ignored.
    detections: None or ``{semantics: null}``: the folder's detections; ``{semantics: realistic}``
    (or ``offsets_only``, plus any field of :class:`mocap.data.detector_semantics.DetectorSemantics`):
    detections simulated from the ground-truth joints in every view with a real detector's
    semantics, seeded by ``seed`` and the folder's name (the same seed gives the same detections;
    a ``views`` subset sees the same detections as the full rig).
    """
    p = Path(path)
    if not p.is_dir():
        raise FileNotFoundError(f"data path not found: {p}")
    if not (p / "sequence.json").is_file() and any(p.glob("*.toml")) and (p / "pose").is_dir():
        raise ValueError(f"data path {p} is a Pose2Sim folder (Calib.toml, pose/), not a sequence folder: "
                         f"track it with data=pose2sim_demo data.path={p}, or make a sequence folder with "
                         f"mocap convert {p} OUT")
    if gt is not None and not gt_opted_out(gt) and not Path(gt).is_file():
        raise FileNotFoundError(f"setting gt = {str(gt)!r}: ground-truth file not found (a gt.npz: joints by "
                                f"name, docs/data_formats.md; {NO_GT_HINT})")
    seq = load_sequence(p, images=images, nonfinite=nonfinite, gt=gt)
    changes: dict = {}
    if detections and dict(detections).get("semantics") is not None:
        seq = _simulated_detections(seq, p, detections, seed)
    if name:
        changes["name"] = str(name)
    if views is not None:
        idx = [seq.rig.index(v) if isinstance(v, str) else int(v) for v in views]
        if not idx or len(set(idx)) != len(idx) or min(idx) < 0 or max(idx) >= seq.num_views:
            raise ValueError(f"{p}: views must be distinct indices in [0, {seq.num_views}) or "
                             f"names of {list(seq.rig.names)}, got {list(views)}")
        changes.update(rig=seq.rig[idx],
                       masks=None if seq.masks is None else seq.masks[:, idx],
                       images=None if seq.images is None else seq.images[:, idx],
                       detections=None if seq.detections is None else _keep_views(seq.detections, idx))
    masks = changes.get("masks", seq.masks)
    if silhouette_noise and masks is not None:
        noise = SilhouetteNoise(**dict(silhouette_noise))
        if noise.active:
            rng = np.random.default_rng([int(seed), 7])
            changes["masks"] = np.stack([np.stack([noise.apply(m, rng) for m in frame])
                                         for frame in masks])
        changes["meta"] = {**seq.meta, "silhouette_noise": dict(silhouette_noise),
                           "noise_seed": int(seed)}
    if views is not None:
        changes.setdefault("meta", dict(seq.meta))["views"] = list(changes["rig"].names)
    return replace(seq, **changes) if changes else seq


def _simulated_detections(seq: Sequence, path: Path, options: Mapping, seed: int) -> Sequence:
    import zlib

    from mocap.data.detector_semantics import gt_keypoint_names, semantics_from, simulate

    semantics = semantics_from(options)             # raises on a bad option before any work
    if seq.gt is None:
        raise ValueError(f"{path}: detections.semantics={dict(options)['semantics']!r} simulates detections "
                         "from the ground-truth joints, but the folder has no gt.npz")
    rng = np.random.default_rng([int(seed), zlib.crc32(path.resolve().name.encode()), 26])
    sim = simulate(seq.gt.joints, gt_keypoint_names(seq.gt), seq.rig, semantics, rng)
    # the detector profile (mocap.trackers.markers.offsets.PROFILES) calibrated for these
    # semantics, unless the offsets were changed
    profile = "realistic_sim" if "offsets_mm" not in dict(options) else None
    meta = {**seq.meta, "detections": {**dict(options), "seed": int(seed), "keypoint_profile": profile,
                                       "simulator": "mocap.data.detector_semantics"}}
    return replace(seq, detections=sim.detections, meta=meta)


def _keep_views(det: Detections, idx: list[int]) -> Detections:
    new = np.full(int(max(det.view.max(initial=0), max(idx))) + 1, -1)
    new[idx] = np.arange(len(idx))
    keep = new[det.view] >= 0
    return Detections(det.labels, det.frame[keep], new[det.view[keep]], det.label[keep],
                      det.xy[keep], det.confidence[keep],
                      None if det.person is None else det.person[keep])

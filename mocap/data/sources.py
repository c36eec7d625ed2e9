"""Sequences from configuration (``conf/data/*.yaml``): synthetic in memory, or a folder; their
settings and defaults: :mod:`mocap.data.source_settings`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.cameras import rig_from_config
from mocap.data.corruption import SilhouetteNoise
from mocap.data.generate import make_synthetic
from mocap.data.sequence import Detections, Sequence
from mocap.data.sequence_io import NO_GT_HINT, gt_opted_out, load_sequence
from mocap.data.source_settings import FolderSource, SyntheticSource
from mocap.settings import settings_from_mapping


def synthetic_sequence(*, body: BodyModel, **keys) -> Sequence:
    """Generate a sequence in memory; ``keys``: the settings that differ from
    :class:`~mocap.data.source_settings.SyntheticSource`'s defaults."""
    s = settings_from_mapping(SyntheticSource, keys)
    rig = rig_from_config(s.cameras)
    return make_synthetic(body, rig, **{k: v for k, v in vars(s).items() if k != "cameras"})


def folder_sequence(*, body: BodyModel, **keys) -> Sequence:
    """A sequence folder written by ``mocap make-dataset`` (or converted data); ``keys``: the
    settings that differ from :class:`~mocap.data.source_settings.FolderSource`'s defaults (a
    ``views`` subset sees the same simulated detections as the full rig)."""
    s = settings_from_mapping(FolderSource, keys)
    path, images, name, views, silhouette_noise, seed, nonfinite, gt, detections = (
        s.path, s.images, s.name, s.views, s.silhouette_noise, s.seed, s.nonfinite, s.gt, s.detections)
    if path is None:
        raise ValueError("setting data.path is missing: the sequence folder (data.path=/path/to/seq)")
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

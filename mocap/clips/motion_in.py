"""A clip in as a run's ``motion.npz`` (:mod:`mocap.export.motion`): read, retargeted onto our
body, written in the format runs write, so ``mocap export`` (BVH, TRC, glTF, C3D), replay and
rendering take it like a run's motion.

Besides the run keys, the file keeps the retargeting: ``retarget_point_names`` (S,),
``retarget_clip_names`` (S,), ``retarget_targets`` (F, S, 3) float32 (the clip's joints,
metres, Z up), ``retarget_residual_mm`` (F, S), ``source_frame_index`` (F,) and
``source`` (the clip's path). Its ``tracker`` is ``"retarget"`` and ``data`` the clip's path.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from mocap.body.model import BodyModel
from mocap.clips.retarget import Retargeted


def motion_arrays_of(r: Retargeted, body: BodyModel) -> dict:
    """The arrays of a ``motion.npz`` holding a retargeted clip."""
    from mocap.export.motion import motion_arrays

    est = [SimpleNamespace(chi=c, alpha=r.alpha, diagnostics={}) for c in r.chi]
    arrays = motion_arrays(body, est, [r.seconds_per_frame] * r.num_frames, r.fps,
                           info={"tracker": "retarget", "data": str(r.path or ""), "run_id": "", "seed": -1})
    arrays["timestamps"] = np.asarray(r.times - r.times[0], np.float64)
    arrays.update({"retarget_point_names": np.array(r.point_names, dtype=str),
                   "retarget_clip_names": np.array(r.clip_names, dtype=str),
                   "retarget_targets": r.targets.astype(np.float32),
                   "retarget_residual_mm": r.residual_mm,
                   "source_frame_index": np.asarray(r.frame_index, np.int64),
                   "source": np.array(str(r.path or ""))})
    return arrays


def import_motion(path: str | Path, out: str | Path, body: BodyModel, *, unit: str | None = None,
                  up: str | None = None, frames: slice | None = None, name_map=None, step: int = 1,
                  fps: float | None = None, overwrite: bool = False, **options) -> Path:
    """Read the BVH clip ``path`` (:func:`mocap.clips.read_bvh`: ``unit``, ``up``, ``frames``),
    retarget it onto ``body`` (:func:`mocap.clips.retarget.retarget`: ``name_map``, ``step``,
    ``fps`` and ``options``) and write ``out`` (a ``motion.npz``; a folder gets
    ``out/motion.npz``). An existing file is kept unless ``overwrite``. Returns the file."""
    from mocap.clips.bvh import read_bvh
    from mocap.clips.retarget import retarget
    from mocap.export.motion import write_motion

    out = Path(out)
    if out.is_dir() or not out.suffix:
        out = out / "motion.npz"
    if out.suffix != ".npz":
        raise ValueError(f"out={str(out)!r}: a motion.npz file (or a folder for one)")
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out} exists (pass overwrite=True / --overwrite to replace it)")
    clip = read_bvh(path, unit=unit, up=up, frames=frames)
    r = retarget(clip, body, name_map=name_map, step=step, fps=fps, **options)
    out.parent.mkdir(parents=True, exist_ok=True)
    return write_motion(out, motion_arrays_of(r, body))

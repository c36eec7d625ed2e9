"""Ground truth from a folder of named 3D joints (a Vicon/Theia export, HumanEva, Shelf...).

Accepted layouts (``folder``):
- ``*.csv`` with a header. ``frame,name,x,y,z`` (one file or several: rows of any frames), or
  ``name,x,y,z`` (one file per frame, frames in file-name order). ``joint`` may stand for
  ``name``. Empty or non-numeric coordinates mark the joint missing in that frame.
- ``*.npz`` holding ``joint_names`` (J,) and ``joints`` (F, J, 3) (all frames) or (J, 3)
  (one file per frame, in file-name order); optional ``joint_valid`` of the same frames.

Joints missing in a frame get NaN and ``valid`` False. ``scale`` converts units to metres
(0.001 for millimetres).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from mocap.data.sequence import GroundTruth
from mocap.safe_files import write_text_atomic


def _num(s: str) -> float:
    try:
        return float(s)
    except (TypeError, ValueError):
        return float("nan")


def read_named_joints(folder: str | Path,
                      scale: float = 1.0) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """-> (names (J,), joints (F, J, 3) metres, valid (F, J) bool)."""
    folder = Path(folder)
    files = sorted(folder.glob("*.csv")) or sorted(folder.glob("*.npz"))
    if not files:
        raise FileNotFoundError(f"{folder}: no .csv or .npz files of named joints")
    frames: dict[int, dict[str, np.ndarray]] = {}
    names: list[str] = []
    for k, path in enumerate(files):
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                if "joint_names" not in z or "joints" not in z:
                    raise ValueError(f"{path}: needs fields 'joint_names' and 'joints'")
                jn = [str(n) for n in z["joint_names"]]
                arr = z["joints"].astype(np.float64)
                ok = z["joint_valid"].astype(bool) if "joint_valid" in z else None
            arr = arr[None] if arr.ndim == 2 else arr
            ok = None if ok is None else (ok[None] if ok.ndim == 1 else ok)
            if arr.shape[1:] != (len(jn), 3):
                raise ValueError(f"{path}: 'joints' is {arr.shape}, expected (F, {len(jn)}, 3)")
            base = len(frames)
            for f in range(len(arr)):
                pts = arr[f].copy()
                if ok is not None:
                    pts[~ok[f]] = np.nan
                frames[base + f] = dict(zip(jn, pts, strict=True))
            names += [n for n in jn if n not in names]
            continue
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
        if not rows:
            continue
        cols = {c.strip().lower(): c for c in rows[0]}
        name_col = cols.get("name") or cols.get("joint")
        if name_col is None or not {"x", "y", "z"} <= cols.keys():
            raise ValueError(f"{path}: header needs name (or joint), x, y, z [and frame]; "
                             f"got {list(rows[0])}")
        for row in rows:
            f = int(row[cols["frame"]]) if "frame" in cols else k
            n = row[name_col].strip()
            frames.setdefault(f, {})[n] = np.array([_num(row[cols[a]]) for a in "xyz"])
            if n not in names:
                names.append(n)
    order = sorted(frames)
    if order != list(range(order[0], order[0] + len(order))):
        raise ValueError(f"{folder}: frames {order[0]}..{order[-1]} are not contiguous")
    joints = np.full((len(order), len(names), 3), np.nan)
    for i, f in enumerate(order):
        for n, p in frames[f].items():
            joints[i, names.index(n)] = p
    joints *= scale
    valid = np.isfinite(joints).all(axis=-1)
    return tuple(names), joints, valid


def sequence_info(sequence: str | Path) -> dict:
    """sequence.json of a sequence folder; a missing one is refused naming what the folder is
    (a Pose2Sim folder: ``mocap convert`` makes a sequence folder of it)."""
    sequence = Path(sequence)
    meta_path = sequence / "sequence.json"
    if not sequence.is_dir():
        raise FileNotFoundError(f"sequence folder not found: {sequence}")
    if not meta_path.is_file():
        pose2sim = any(sequence.glob("*.toml")) or (sequence / "pose").is_dir()
        raise FileNotFoundError(
            f"{sequence} has no sequence.json: "
            + (f"it is a Pose2Sim folder (calibration, pose/); make a sequence folder with `mocap convert "
               f"{sequence} OUT` and add the ground truth to OUT" if pose2sim else "not a sequence folder"))
    try:
        return json.loads(meta_path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{meta_path}: invalid JSON ({exc})") from None


def add_ground_truth(sequence: str | Path, names, joints: np.ndarray, valid: np.ndarray,
                     skeleton: str = "", overwrite: bool = False) -> Path:
    """Write joints-by-name ground truth (gt.npz) into a sequence folder and mark it in
    sequence.json. The frame count must match the sequence's."""
    from mocap.data.sequence_io import write_ground_truth

    sequence = Path(sequence)
    info = sequence_info(sequence)
    meta_path = sequence / "sequence.json"
    if int(info["frames"]) != len(joints):
        raise ValueError(f"{len(joints)} frames of joints, but sequence {sequence} has {info['frames']}")
    if (sequence / "gt.npz").exists() and not overwrite:
        raise FileExistsError(f"{sequence / 'gt.npz'} exists (pass --overwrite to replace it)")
    if skeleton:
        from mocap.body.skeletons import SKELETONS, resolve_mapping
        resolve_mapping(names, [v for v in SKELETONS.get(skeleton, {}).values() if v], skeleton)
    gt = GroundTruth(alpha=None, chi=None, joints=joints, markers=None, dof_names=(),
                     joint_names=tuple(names), marker_names=(), joint_valid=valid, skeleton=skeleton)
    write_ground_truth(gt, sequence / "gt.npz")
    info.setdefault("content", {})["gt"] = True
    write_text_atomic(meta_path, json.dumps(info, indent=2))
    return sequence / "gt.npz"

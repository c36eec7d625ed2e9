"""Degrees of freedom of the kinematic chain, defined by configuration (``mocap/presets/body``).

Each revolute DOF names its joint, its axis and its anatomical limits (chi_min, chi_max)
used by the joint-limit prior (Zhang et al. 2013, Eq. 14). Axes live in the rest body
frame (x: subject's left, y: back, z: up) and are given as

    axis: [x, y, z]                      a fixed direction
    axis: {bone: child}                  along the rest bone from the joint to ``child``
    axis: {bone: [a, b]}                 along the rest bone from joint a to joint b
    axis: {bone: child, cross: [x,y,z]}  normalised (bone direction x the given vector)

Bone-relative axes follow the body's shape (they are resolved from the rest joints of alpha).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DofSpec:
    """One revolute degree of freedom (angles in radians)."""

    name: str
    joint: str
    limits: tuple[float, float]
    axis: tuple[float, float, float] | None = None
    bone: tuple[str, str] | None = None
    cross: tuple[float, float, float] | None = None


def dofs_from_config(entries: Sequence[Mapping]) -> tuple[DofSpec, ...]:
    """Parse config entries ``{name, joint, axis, limits_deg: [min, max]}``."""
    specs = []
    for i, e in enumerate(entries):
        where = f"body DOF #{i} ({e.get('name', '?')})"
        for key in ("name", "joint", "axis", "limits_deg"):
            if key not in e:
                raise ValueError(f"{where}: missing field '{key}'")
        lo, hi = (float(x) for x in e["limits_deg"])
        if not lo < hi:
            raise ValueError(f"{where}: limits_deg must be [min, max] with min < max")
        axis, bone, cross = e["axis"], None, None
        if isinstance(axis, Mapping):
            b = axis.get("bone")
            if b is None:
                raise ValueError(f"{where}: axis mapping needs 'bone'")
            bone = (e["joint"], str(b)) if isinstance(b, str) else (str(b[0]), str(b[1]))
            cross = tuple(float(x) for x in axis["cross"]) if "cross" in axis else None
            axis = None
        else:
            axis = tuple(float(x) for x in axis)
            if len(axis) != 3 or np.linalg.norm(axis) < 1e-9:
                raise ValueError(f"{where}: axis must be a non-zero 3-vector")
        specs.append(DofSpec(name=str(e["name"]), joint=str(e["joint"]),
                             limits=(np.deg2rad(lo), np.deg2rad(hi)),
                             axis=axis, bone=bone, cross=cross))
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate DOF names in {names}")
    return tuple(specs)


def resolve_axes(dofs: Sequence[DofSpec], joint_names: Sequence[str],
                 joints_rest: np.ndarray) -> np.ndarray:
    """Unit axes of the DOFs: joints_rest (*, J, 3) -> (*, D, 3)."""
    index = {n: i for i, n in enumerate(joint_names)}
    out = np.empty(joints_rest.shape[:-2] + (len(dofs), 3), dtype=joints_rest.dtype)
    for d, s in enumerate(dofs):
        if s.bone is None:
            a = np.broadcast_to(np.asarray(s.axis, dtype=joints_rest.dtype), out[..., d, :].shape)
        else:
            a = joints_rest[..., index[s.bone[1]], :] - joints_rest[..., index[s.bone[0]], :]
            if s.cross is not None:
                a = np.cross(a, np.asarray(s.cross, dtype=joints_rest.dtype))
        out[..., d, :] = a / np.linalg.norm(a, axis=-1, keepdims=True)
    return out


def check_joints(dofs: Sequence[DofSpec], joint_names: Sequence[str]) -> None:
    """Raise if a DOF names a joint the model does not have."""
    known = set(joint_names)
    for s in dofs:
        for j in (s.joint,) + (s.bone or ()):
            if j not in known:
                raise ValueError(f"DOF '{s.name}' names unknown joint '{j}' "
                                 f"(the model has: {', '.join(joint_names)})")

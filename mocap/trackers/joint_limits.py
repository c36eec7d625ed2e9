"""A tracker's own joint limits (``tracker.joint_limits`` of the hybrid, issue 34 item 4): the body
with other limits for one tracker only, the body itself (its oracles, the other trackers, the pose
prior's library) unchanged.

The shipped limits are too tight for the motion the benchmarks hold (docs/results/surface.md, "The
two-cue hybrid's pose": 39-43 % of the training motion's elbows past them); ``widened`` names the
limits widened from the motion library's TRAINING poses (``experiments/joint_limits.py``,
:func:`mocap.body.limits_from_data.widened_limits`), shipped per body as
``assets/<body>_widened_limits.json``; any other non-empty value is a JSON file of the same form,
``{dof name: [lower, upper] degrees}`` (DOFs not named keep the body's limits)."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel

#: the value of ``joint_limits`` naming the limits shipped for the body, widened from training motion
WIDENED = "widened"
ASSETS = Path(__file__).with_name("assets")


def limits_path(body_name: str, spec: str) -> Path:
    """The JSON file of ``spec`` (``widened``: the one shipped for ``body_name``; else a path)."""
    return ASSETS / f"{body_name}_widened_limits.json" if spec == WIDENED else Path(spec)


def read_limits(body: BodyModel, spec: str) -> np.ndarray:
    """The body's limits (D, 2) rad with those of ``spec``'s file put in; a one-line ValueError naming
    the file and the entry for a missing file, an unknown or root DOF, a pair that is not
    [lower, upper] finite degrees with lower < upper, before any tracking."""
    path = limits_path(body.name, spec)
    if not path.is_file():
        raise ValueError(f"joint_limits: no limits file {path} (for {spec!r}, body {body.name!r})")
    try:
        table = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"joint_limits: {path} is not JSON ({e})") from None
    if not isinstance(table, dict):
        raise ValueError(f"joint_limits: {path} holds {type(table).__name__}, expected {{dof: [lo, hi] deg}}")
    out = np.array(body.limits, np.float64)
    for name, pair in table.items():
        if name not in body.dof_names[6:]:
            raise ValueError(f"joint_limits: {path}: {name!r} is not a joint DOF of body {body.name!r}")
        ok = (isinstance(pair, list) and len(pair) == 2
              and all(isinstance(v, (int, float)) and math.isfinite(v) for v in pair) and pair[0] < pair[1])
        if not ok:
            raise ValueError(f"joint_limits: {path}: {name} = {pair!r}, expected [lower, upper] "
                             "finite degrees, lower < upper")
        out[body.dof_index(name)] = np.deg2rad(pair)
    return out


def tracker_body(body: BodyModel, spec: str) -> BodyModel:
    """``body`` itself for ``spec`` '' (its own limits); else a shallow copy whose ``limits`` (D, 2)
    are :func:`read_limits`'s (mesh, shape model and DOFs shared; ``body`` untouched)."""
    if not spec:
        return body
    limits = read_limits(body, spec)
    own = copy.copy(body)
    own.limits = limits
    return own

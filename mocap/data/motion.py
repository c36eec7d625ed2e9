"""A procedural motion library in the body's DOF space (the HumanEva action set).

Each action is a small set of periodic joint-angle patterns (degrees, by DOF name) plus a
global trajectory; a seeded generator draws its variation (speed, amplitude, phase, style).
DOFs a body does not have are ignored, so the same action drives ``paper22`` and ``full``.
Angles are kept inside the joint limits by a smooth saturation (no kinks), so motions stay
smooth and valid. Training motions (for the pose prior) and test motions come from
disjoint random streams: ``split="train"`` and ``split="test"`` never share a generator.

    chi = generate_motion(body, "walk", frames=100, fps=25, seed=0)      # (100, D)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.body.twists import se3_log

ACTIONS = ("walk", "jog", "box", "gestures", "throw_catch")
_SPLITS = {"train": 1, "test": 2}


@dataclass(frozen=True)
class Variation:
    """Random variation of one action instance."""

    speed: float        # cycle-frequency factor
    amplitude: float    # joint-amplitude factor
    phase: float        # radians
    style: dict         # per-DOF offsets in degrees
    heading: float      # initial heading (radians about z)

    @staticmethod
    def draw(rng: np.random.Generator) -> Variation:
        return Variation(speed=float(rng.uniform(0.85, 1.15)), amplitude=float(rng.uniform(0.8, 1.2)),
                         phase=float(rng.uniform(0, 2 * np.pi)),
                         style={k: float(rng.normal(0, 4.0)) for k in _STYLE_DOFS},
                         heading=float(rng.uniform(0, 2 * np.pi)))


_STYLE_DOFS = ("l_shoulder_abd", "r_shoulder_abd", "l_elbow_flex", "r_elbow_flex", "spine_flex",
               "l_hip_abd", "r_hip_abd", "neck_flex")


def _gait(phi: np.ndarray, a: float, hip: float, knee: float, shoulder: float, elbow: float,
          elbow_mean: float, lean: float) -> dict[str, np.ndarray]:
    """Walking/jogging joint patterns over the gait phase phi (radians), degrees."""
    def knee_wave(p):  # flexion peak in swing, small peak in stance
        return 0.85 * np.clip(np.sin(p - 0.6), 0, None) ** 2 + 0.15 * np.clip(np.sin(2 * p), 0, None)

    return {
        "l_hip_flex": a * hip * np.sin(phi) + 5, "r_hip_flex": a * hip * np.sin(phi + np.pi) + 5,
        "l_knee_flex": 5 + a * knee * knee_wave(phi + np.pi / 2),
        "r_knee_flex": 5 + a * knee * knee_wave(phi + 3 * np.pi / 2),
        "l_shoulder_flex": a * shoulder * np.sin(phi + np.pi), "r_shoulder_flex": a * shoulder * np.sin(phi),
        "l_elbow_flex": elbow_mean + a * elbow * np.sin(phi + np.pi),
        "r_elbow_flex": elbow_mean + a * elbow * np.sin(phi),
        "l_shoulder_abd": np.full_like(phi, -20.0), "r_shoulder_abd": np.full_like(phi, -20.0),
        "spine_flex": np.full_like(phi, lean), "spine_rot": 6 * a * np.sin(phi),
        "l_ankle_flex": 10 * np.sin(phi + 0.3), "r_ankle_flex": 10 * np.sin(phi + np.pi + 0.3),
    }


def _walk(t, v):
    phi = 2 * np.pi * 0.9 * v.speed * t + v.phase
    return _gait(phi, v.amplitude, 22, 55, 18, 12, 20, 3), 1.2 * v.speed, 0.02


def _jog(t, v):
    phi = 2 * np.pi * 1.4 * v.speed * t + v.phase
    return _gait(phi, v.amplitude, 32, 85, 30, 15, 80, 8), 2.0 * v.speed, 0.04


def _box(t, v):
    a, w = v.amplitude, 2 * np.pi * 1.1 * v.speed
    # alternating punches: a punch is a short smooth pulse of extension
    pl = np.clip(np.sin(w * t + v.phase), 0, None) ** 4
    pr = np.clip(np.sin(w * t + v.phase + np.pi), 0, None) ** 4
    bob = np.sin(2 * w * t)
    return {
        "l_shoulder_flex": 55 + a * 35 * pl, "r_shoulder_flex": 55 + a * 35 * pr,
        "l_shoulder_abd": -15 + 10 * pl, "r_shoulder_abd": -15 + 10 * pr,
        "l_shoulder_rot": -30 + 20 * pl, "r_shoulder_rot": 30 - 20 * pr,
        "l_elbow_flex": 115 - a * 95 * pl, "r_elbow_flex": 115 - a * 95 * pr,
        "l_hip_flex": 18 + 4 * bob, "r_hip_flex": 8 + 4 * bob,
        "l_knee_flex": 25 + 6 * bob, "r_knee_flex": 25 + 6 * bob,
        "spine_rot": 15 * a * (pr - pl), "spine_flex": 10 + 2 * bob, "neck_flex": np.full_like(t, -5.0),
    }, 0.0, 0.01


def _gestures(t, v):
    a, w = v.amplitude, 2 * np.pi * 0.5 * v.speed
    wave = np.sin(3 * w * t + v.phase)
    raise_l = 0.5 - 0.5 * np.cos(w * t + v.phase)
    raise_r = 0.5 - 0.5 * np.cos(w * t + v.phase + 2.0)
    return {
        "l_shoulder_abd": -10 + a * 110 * raise_l, "r_shoulder_abd": -10 + a * 70 * raise_r,
        "l_shoulder_flex": 20 * raise_l, "r_shoulder_flex": 50 * raise_r,
        "l_elbow_flex": 30 + a * 40 * raise_l * (1 + wave) / 2, "r_elbow_flex": 60 + 30 * raise_r,
        "l_shoulder_rot": 20 * wave * raise_l, "neck_rot": 20 * np.sin(0.5 * w * t),
        "l_hip_flex": np.full_like(t, 3.0), "r_hip_flex": np.full_like(t, 3.0),
        "l_knee_flex": np.full_like(t, 5.0), "r_knee_flex": np.full_like(t, 5.0),
    }, 0.0, 0.0


def _throw_catch(t, v):
    a, w = v.amplitude, 2 * np.pi * 0.6 * v.speed
    s = np.sin(w * t + v.phase)             # +1: arm cocked overhead, -1: released forward
    c = 0.5 + 0.5 * np.cos(w * t + v.phase)
    return {
        "r_shoulder_flex": 70 + a * 70 * s, "r_shoulder_abd": 20 + 20 * s,
        "r_elbow_flex": 60 + 40 * s, "r_shoulder_rot": 30 * s,
        "l_shoulder_flex": 40 + 30 * c, "l_elbow_flex": 50 + 30 * c,
        "spine_rot": -20 * s, "spine_flex": 5 - 8 * s,
        "l_hip_flex": 12 - 8 * s, "r_hip_flex": -2 + 6 * s,
        "l_knee_flex": 15 - 8 * s, "r_knee_flex": 12 + 4 * s,
    }, 0.0, 0.0


_ACTIONS: dict[str, Callable] = {"walk": _walk, "jog": _jog, "box": _box,
                                 "gestures": _gestures, "throw_catch": _throw_catch}


def _saturate(x: np.ndarray, lo: float, hi: float, margin: float) -> np.ndarray:
    """Smoothly keep x inside (lo, hi): identity in the middle, tanh within ``margin`` of a limit."""
    a, b = lo + margin, hi - margin
    out = x.copy()
    over, under = x > b, x < a
    out[over] = b + margin * np.tanh((x[over] - b) / margin)
    out[under] = a - margin * np.tanh((a - x[under]) / margin)
    return out


def _root_twists(t: np.ndarray, speed: float, bob: float, heading0: float, radius: float) -> np.ndarray:
    """Global twists (F, 6): the body walks a circle of ``radius`` around the origin (so it
    stays in the capture volume), facing its direction of travel; or turns slowly in place."""
    F = len(t)
    T = np.tile(np.eye(4), (F, 1, 1))
    if speed > 0:
        ang = heading0 + speed * t / radius
        pos = np.stack([radius * np.cos(ang), radius * np.sin(ang)], axis=1)
        # travel direction (counter-clockwise tangent); the body faces -y at rest
        heading = ang + np.pi          # rotates -y onto the tangent (-sin, cos)
    else:
        pos = np.zeros((F, 2))
        heading = heading0 + 0.15 * np.sin(0.4 * t)
    c, s = np.cos(heading), np.sin(heading)
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 0, 3], T[:, 1, 3] = pos[:, 0], pos[:, 1]
    T[:, 2, 3] = bob * np.sin(4 * np.pi * t * max(speed, 0.5))
    return se3_log(T)


def generate_motion(body: BodyModel, action: str, frames: int, fps: float = 25.0, seed: int = 0,
                    split: str = "test", radius: float = 1.0) -> np.ndarray:
    """A smooth motion within joint limits: (frames, D) poses chi in the body's DOF order."""
    if action not in _ACTIONS:
        raise ValueError(f"unknown action '{action}' (known: {', '.join(ACTIONS)})")
    if split not in _SPLITS:
        raise ValueError(f"split must be 'train' or 'test', got {split!r}")
    if frames < 1 or fps <= 0:
        raise ValueError("frames must be >= 1 and fps > 0")
    rng = np.random.default_rng([seed, _SPLITS[split], ACTIONS.index(action)])
    v = Variation.draw(rng)
    t = np.arange(frames) / fps
    angles_deg, speed, bob = _ACTIONS[action](t, v)
    chi = np.zeros((frames, body.num_dofs))
    for name, values in angles_deg.items():
        if name in body.dof_names:
            d = body.dof_index(name)
            deg = np.broadcast_to(values, t.shape) + v.style.get(name, 0.0)
            lo, hi = body.limits[d]
            chi[:, d] = _saturate(np.deg2rad(deg), lo, hi, margin=np.deg2rad(8))
    chi[:, :6] = _root_twists(t, speed, bob, v.heading, radius)
    return chi.astype(body.dtype)


def save_motion(path: str | Path, body: BodyModel, chi: np.ndarray, fps: float) -> Path:
    """Write a joint-angle sequence: .npz with dof_names, chi (F, D) and fps."""
    path = Path(path)
    np.savez(path, dof_names=np.array(body.dof_names), chi=np.asarray(chi), fps=np.array(fps))
    return path


def load_motion(path: str | Path, body: BodyModel) -> tuple[np.ndarray, float]:
    """Read a joint-angle sequence (.npz as written by :func:`save_motion`, or .csv with a
    header of DOF names, radians, and an optional ``fps`` comment line ``# fps: 25``).

    DOFs of the body missing from the file are zero; DOFs unknown to the body are an error.
    Returns (chi (F, D), fps).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"motion file not found: {path}")
    fps = 25.0
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            for key in ("dof_names", "chi"):
                if key not in z:
                    raise ValueError(f"{path}: missing field '{key}'")
            names, values = [str(n) for n in z["dof_names"]], z["chi"]
            fps = float(z["fps"]) if "fps" in z else fps
    elif path.suffix == ".csv":
        lines = path.read_text().splitlines()
        for line in lines:
            if line.startswith("#") and "fps" in line:
                fps = float(line.split(":")[1])
        rows = [line for line in lines if line.strip() and not line.startswith("#")]
        names = [n.strip() for n in rows[0].split(",")]
        values = np.array([[float(x) for x in r.split(",")] for r in rows[1:]])
    else:
        raise ValueError(f"{path}: unsupported motion format (use .npz or .csv)")
    values = np.atleast_2d(values)
    if values.shape[1] != len(names):
        raise ValueError(f"{path}: {values.shape[1]} columns for {len(names)} DOF names")
    unknown = [n for n in names if n not in body.dof_names]
    if unknown:
        raise ValueError(f"{path}: DOFs unknown to body '{body.name}': {', '.join(unknown)}")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{path}: motion contains NaN or inf")
    chi = np.zeros((len(values), body.num_dofs), dtype=body.dtype)
    for i, n in enumerate(names):
        chi[:, body.dof_index(n)] = values[:, i]
    return chi, fps

"""Synthetic camera rigs and presets.

World frame: z up, metres. :func:`ring_rig` places cameras on a horizontal circle around the
z axis, all looking at one point, with upright images (the camera y axis, image down, points
down in the world). Presets ship with the package (``mocap/presets/cameras/*.yaml``,
:mod:`mocap.presets`); Hydra finds them as the ``cameras`` config group.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import yaml

from mocap.cameras.calibration_io import _is_opencv_yaml, _read_text, load_calibration
from mocap.cameras.camera import Camera, Rig


def _vec3(v: Sequence[float] | np.ndarray, what: str) -> np.ndarray:
    a = np.array([float(x) for x in v]) if not isinstance(v, np.ndarray) else v.astype(float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be 3 finite numbers, got {v!r}")
    return a


def look_at_rotation(
    position: Sequence[float] | np.ndarray,
    target: Sequence[float] | np.ndarray,
    up: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
) -> np.ndarray:
    """(3, 3) world-to-camera rotation ``cam_R_world`` of a camera at ``position`` (3,) world
    looking at ``target`` (3,) world, with the image upright with respect to ``up`` (3,):
    rows are the camera axes in the world, z = forward, x = forward x up (right),
    y = z x x (down)."""
    position, target, up = _vec3(position, "position"), _vec3(target, "target"), _vec3(up, "up")
    z = target - position
    if np.linalg.norm(z) == 0:
        raise ValueError("camera position and look-at target coincide")
    z = z / np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        raise ValueError(f"viewing direction {z.tolist()} is parallel to up {up.tolist()}")
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])


def intrinsics(width: int, height: int, fov_deg: float | None = None,
               focal: float | None = None) -> np.ndarray:
    """(3, 3) pinhole K with square pixels and the principal point at the image centre
    ((width - 1) / 2, (height - 1) / 2) in OpenCV's pixel-centre convention. Give either the
    vertical field of view ``fov_deg`` (over the image height) or ``focal`` in pixels."""
    if (fov_deg is None) == (focal is None):
        raise ValueError("give exactly one of fov_deg and focal")
    if fov_deg is not None:
        if not 0 < fov_deg < 180:
            raise ValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
        focal = 0.5 * height / np.tan(np.radians(fov_deg) / 2.0)
    return np.array([[focal, 0.0, (width - 1) / 2.0],
                     [0.0, focal, (height - 1) / 2.0],
                     [0.0, 0.0, 1.0]])


def look_at_camera(
    name: str,
    position: Sequence[float] | np.ndarray,
    target: Sequence[float] | np.ndarray,
    K: np.ndarray,
    width: int,
    height: int,
    dist: Sequence[float] | np.ndarray | None = None,
    up: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
) -> Camera:
    """A :class:`Camera` at ``position`` (3,) world metres looking at ``target`` (3,)."""
    R = look_at_rotation(position, target, up)
    return Camera(name=name, K=K, dist=dist, R=R, t=-R @ _vec3(position, "position"),
                  width=width, height=height)


def ring_rig(
    num_cameras: int,
    radius: float,
    height: float,
    width: int,
    image_height: int,
    fov_deg: float | None = None,
    focal: float | None = None,
    look_at: Sequence[float] = (0.0, 0.0, 1.0),
    dist: Sequence[float] | None = None,
    names: Sequence[str] | None = None,
    start_deg: float = 0.0,
) -> Rig:
    """Cameras evenly spaced on a circle around the world z axis, all looking at ``look_at``.

    num_cameras: C. radius: circle radius, metres. height: camera height (world z), metres.
    width, image_height: image size, pixels. fov_deg: vertical field of view (over
    image_height), degrees; or focal: focal length, pixels (exactly one). look_at: (3,)
    world target. dist: (<= 5,) OpenCV distortion shared by all cameras. names: C names,
    default ``cam_00``, ``cam_01``, .... start_deg: azimuth of camera 0 (0 = on the +x axis),
    the others follow counter-clockwise seen from above.
    """
    num_cameras = int(num_cameras)
    if num_cameras < 1:
        raise ValueError(f"num_cameras must be >= 1, got {num_cameras}")
    if not radius > 0:
        raise ValueError(f"radius must be positive, got {radius}")
    if names is None:
        names = [f"cam_{i:02d}" for i in range(num_cameras)]
    names = [str(n) for n in names]
    if len(names) != num_cameras:
        raise ValueError(f"{len(names)} names for {num_cameras} cameras")
    K = intrinsics(int(width), int(image_height), fov_deg=fov_deg, focal=focal)
    target = _vec3(look_at, "look_at")
    dist_arr = None if dist is None else [float(d) for d in dist]
    angles = np.radians(float(start_deg)) + 2.0 * np.pi * np.arange(num_cameras) / num_cameras
    cams = []
    for name, a in zip(names, angles, strict=True):
        position = np.array([radius * np.cos(a), radius * np.sin(a), float(height)])
        cams.append(look_at_camera(name, position, target, K, int(width), int(image_height),
                                   dist=dist_arr))
    return Rig(tuple(cams))


def _plain(value):
    """Nested mappings and lists (any Mapping / non-string Sequence) as dicts and lists."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(_plain(v) for v in value)
    if isinstance(value, Sequence) and not isinstance(value, (str, bytes)):
        return [_plain(v) for v in value]
    return value


def rig_from_config(config: Mapping | str | Path) -> Rig:
    """A rig from a Hydra config (mapping or DictConfig with ``_target_``), a preset name
    (``"humaneva"``, ``"mpi08"``, ``"ring4_small"``: :mod:`mocap.presets`), or the
    path of a config YAML or of a calibration file (.json/.yaml/.yml/.xml/.toml, see
    :func:`mocap.cameras.calibration_io.load_calibration`).

    A config may also be ``{"calibration": <path>}`` (optionally with ``image_sizes``) to
    load a calibration file.
    """
    from mocap import presets

    if isinstance(config, (str, Path)):
        path = Path(config)
        if path.suffix == "" and not path.exists():
            return rig_from_config(presets.read("cameras", str(config)))
        if path.suffix in (".yaml", ".yml"):
            text = _read_text(path)
            if not _is_opencv_yaml(text):
                data = yaml.safe_load(text)
                if isinstance(data, Mapping) and ("_target_" in data or "calibration" in data):
                    return rig_from_config(data)
        return load_calibration(path)
    config = _plain(config)        # a mapping of the command line's configs (mocap_cli) to plain values
    if "calibration" in config and "_target_" not in config:
        return load_calibration(str(config["calibration"]), image_sizes=config.get("image_sizes"))
    rig = presets.build(config, kind="cameras", where="camera config")
    if not isinstance(rig, Rig):
        raise TypeError(f"camera config produced {type(rig).__name__}, expected Rig")
    return rig

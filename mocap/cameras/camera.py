"""Pinhole cameras with OpenCV distortion, and rigs of them.

Conventions (the whole package):

* OpenCV camera frame: x right, y down, z forward (optical axis).
* World-to-camera: ``x_cam = R @ x_world + t``; the camera centre is ``-R.T @ t``.
* Pixel coordinates follow OpenCV: the centre of pixel (column i, row j) is at (i, j), so an
  image of width W spans u in [-0.5, W - 0.5].
* Distortion: OpenCV's 5-coefficient model ``(k1, k2, p1, p2, k3)`` (radial + tangential),
  see :func:`mocap.cameras.projection.distort_normalized`.
* Project world frame: z up, metres.

:class:`Camera` and :class:`Rig` are immutable; their arrays are float64 and read-only.
"""

from __future__ import annotations

import operator
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

#: Largest allowed |R^T R - I| entry and |det R - 1| for a rotation matrix.
ROTATION_ATOL = 1e-5

CAMERA_FIELDS = ("name", "K", "dist", "R", "t", "width", "height")


class InvalidCameraError(ValueError):
    """A camera parameter is invalid. ``camera``: the camera's name; ``field``: the
    :class:`Camera` field at fault (one of :data:`CAMERA_FIELDS`); ``reason``: what is wrong."""

    def __init__(self, camera: str, field: str, reason: str):
        super().__init__(f"camera {camera!r}: field {field!r}: {reason}")
        self.camera = camera
        self.field = field
        self.reason = reason


def _frozen_array(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64)  # always a copy
    a.setflags(write=False)
    return a


def _as_float_array(
    value: object, shape: tuple[int, ...], camera: str, name: str
) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidCameraError(camera, name, f"not a numeric array ({exc})") from None
    if a.shape != shape:
        if len(shape) == 1 and a.ndim == 2 and 1 in a.shape and a.size == shape[0]:
            a = a.reshape(shape)  # accept (3, 1) / (1, 3) for vectors, as OpenCV writes them
        else:
            raise InvalidCameraError(camera, name, f"expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidCameraError(camera, name, "contains NaN or inf")
    return a


def _as_dist(value: object, camera: str) -> np.ndarray:
    if value is None:
        return np.zeros(5)
    try:
        d = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidCameraError(camera, "dist", f"not a numeric array ({exc})") from None
    if not np.all(np.isfinite(d)):
        raise InvalidCameraError(camera, "dist", "contains NaN or inf")
    if d.size > 5:
        if np.any(d[5:] != 0):
            raise InvalidCameraError(
                camera, "dist",
                f"{d.size} coefficients given; only OpenCV's k1, k2, p1, p2, k3 are supported "
                "(the rational / thin-prism / tilt terms must be zero)",
            )
        d = d[:5]
    return np.concatenate([d, np.zeros(5 - d.size)])


def _as_size(value: object, camera: str, name: str) -> int:
    try:
        n = operator.index(value)
    except TypeError:
        try:
            f = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise InvalidCameraError(camera, name, f"not an integer: {value!r}") from None
        if not np.isfinite(f) or f != int(f):
            raise InvalidCameraError(camera, name, f"not an integer: {value!r}") from None
        n = int(f)
    if n <= 0:
        raise InvalidCameraError(camera, name, f"must be positive, got {n}")
    return n


def check_rotation(R: np.ndarray, camera: str = "?", name: str = "R") -> None:
    """Raise :class:`InvalidCameraError` unless R: (3, 3) is a proper rotation
    (orthonormal to :data:`ROTATION_ATOL`, det +1)."""
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > ROTATION_ATOL:
        raise InvalidCameraError(camera, name, f"not orthonormal (max |R^T R - I| = {err:.3g})")
    det = np.linalg.det(R)
    if abs(det - 1.0) > ROTATION_ATOL:
        raise InvalidCameraError(camera, name, f"determinant is {det:.6g}, expected +1")


@dataclass(frozen=True, eq=False)
class Camera:
    """One calibrated camera.

    name: unique name within a rig.
    K: (3, 3) intrinsics [[fx, s, cx], [0, fy, cy], [0, 0, 1]], pixels.
    dist: (5,) OpenCV distortion (k1, k2, p1, p2, k3); fewer given are zero-padded, None = 0.
    R: (3, 3) world-to-camera rotation (``cam_R_world``).
    t: (3,) world-to-camera translation, metres (``cam_t_world``); (3, 1) is accepted.
    width, height: image size in pixels.

    Construction validates everything and raises :class:`InvalidCameraError` (a ValueError)
    naming the camera and the field. ``==`` is exact equality of all fields; see
    :meth:`allclose` for a tolerance.
    """

    name: str
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidCameraError(str(self.name), "name", "must be a non-empty string")
        cam = self.name
        K = _as_float_array(self.K, (3, 3), cam, "K")
        if K[1, 0] != 0 or np.any(K[2] != (0.0, 0.0, 1.0)):
            raise InvalidCameraError(
                cam, "K", f"must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got {K.tolist()}"
            )
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InvalidCameraError(
                cam, "K", f"focal lengths must be positive, got fx={K[0, 0]}, fy={K[1, 1]}"
            )
        R = _as_float_array(self.R, (3, 3), cam, "R")
        check_rotation(R, cam, "R")
        t = _as_float_array(self.t, (3,), cam, "t")
        dist = _as_dist(self.dist, cam)
        width = _as_size(self.width, cam, "width")
        height = _as_size(self.height, cam, "height")
        for name, value in (("K", K), ("dist", dist), ("R", R), ("t", t)):
            object.__setattr__(self, name, _frozen_array(value))
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "height", height)

    # --- derived quantities -------------------------------------------------------------------

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates, metres: ``-R.T @ t``."""
        return -self.R.T @ self.t

    @property
    def P(self) -> np.ndarray:
        """(3, 4) projection matrix ``K @ [R | t]`` (world -> homogeneous pixels, no
        distortion)."""
        return self.K @ np.concatenate([self.R, self.t[:, None]], axis=1)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return (self.width, self.height)

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    # --- copies -------------------------------------------------------------------------------

    def replace(self, **changes: object) -> Camera:
        """A copy with some fields changed (validated again)."""
        values = {f: getattr(self, f) for f in CAMERA_FIELDS}
        values.update(changes)
        return Camera(**values)  # type: ignore[arg-type]

    def scaled(self, factor: float) -> Camera:
        """The camera for the image resized by ``factor`` (e.g. 0.5 halves it).

        The new size is ``round(width * factor) x round(height * factor)``; the effective
        per-axis scales ``sx = new_width / width``, ``sy = new_height / height`` are what
        ``cv2.resize(image, (new_width, new_height))`` applies. With OpenCV's pixel-centre
        convention (pixel i covers [i - 0.5, i + 0.5]) a pixel coordinate maps as
        ``u' = sx * (u + 0.5) - 0.5``, hence ``K' = [[sx fx, sx s, sx (cx + 0.5) - 0.5],
        [0, sy fy, sy (cy + 0.5) - 0.5], [0, 0, 1]]``. (Plain ``diag(s, s, 1) @ K`` would be
        right for a corner-at-0 convention and is off by ``(1 - s) / 2`` pixels here.)
        Distortion acts on normalised coordinates and is unchanged.
        """
        factor = float(factor)
        if not np.isfinite(factor) or factor <= 0:
            raise ValueError(f"camera {self.name!r}: scale factor must be positive, got {factor}")
        new_w = max(1, round(self.width * factor))
        new_h = max(1, round(self.height * factor))
        sx, sy = new_w / self.width, new_h / self.height
        S = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
        return self.replace(K=S @ self.K, width=new_w, height=new_h)

    # --- comparison ---------------------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Camera):
            return NotImplemented
        return (
            self.name == other.name
            and self.size == other.size
            and all(np.array_equal(getattr(self, f), getattr(other, f))
                    for f in ("K", "dist", "R", "t"))
        )

    __hash__ = None  # type: ignore[assignment]

    def allclose(self, other: Camera, rtol: float = 1e-12, atol: float = 1e-12) -> bool:
        """Same name and size, and K, dist, R, t equal within ``np.allclose(rtol, atol)``."""
        return (
            self.name == other.name
            and self.size == other.size
            and all(np.allclose(getattr(self, f), getattr(other, f), rtol=rtol, atol=atol)
                    for f in ("K", "dist", "R", "t"))
        )


@dataclass(frozen=True, eq=False)
class Rig:
    """An ordered set of C cameras with unique names, and their parameters stacked.

    K: (C, 3, 3); dist: (C, 5); R: (C, 3, 3) ``cam_R_world``; t: (C, 3) ``cam_t_world``
    metres; sizes: (C, 2) int (width, height) pixels; centers: (C, 3) world metres;
    P: (C, 3, 4) undistorted projection matrices; names: tuple of C names.

    ``rig[i]`` / ``rig["name"]`` give a :class:`Camera`, ``rig[1:3]`` or ``rig[[0, 2]]`` a
    sub-rig; iterating yields cameras.
    """

    cameras: tuple[Camera, ...]
    K: np.ndarray = field(init=False, repr=False)
    dist: np.ndarray = field(init=False, repr=False)
    R: np.ndarray = field(init=False, repr=False)
    t: np.ndarray = field(init=False, repr=False)
    sizes: np.ndarray = field(init=False, repr=False)
    centers: np.ndarray = field(init=False, repr=False)
    P: np.ndarray = field(init=False, repr=False)
    names: tuple[str, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise ValueError("a rig needs at least one camera")
        for c in cams:
            if not isinstance(c, Camera):
                raise TypeError(f"rig cameras must be Camera, got {type(c).__name__}")
        names = tuple(c.name for c in cams)
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"duplicate camera names in rig: {dupes}")
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "names", names)
        stacked = {
            "K": np.stack([c.K for c in cams]),
            "dist": np.stack([c.dist for c in cams]),
            "R": np.stack([c.R for c in cams]),
            "t": np.stack([c.t for c in cams]),
            "centers": np.stack([c.center for c in cams]),
            "P": np.stack([c.P for c in cams]),
        }
        for name, value in stacked.items():
            object.__setattr__(self, name, _frozen_array(value))
        sizes = np.array([c.size for c in cams], dtype=np.int64)
        sizes.setflags(write=False)
        object.__setattr__(self, "sizes", sizes)

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self) -> Iterator[Camera]:
        return iter(self.cameras)

    def __getitem__(self, key: int | str | slice | Sequence[int]) -> Camera | Rig:
        if isinstance(key, str):
            try:
                return self.cameras[self.names.index(key)]
            except ValueError:
                raise KeyError(f"no camera named {key!r} in rig {list(self.names)}") from None
        if isinstance(key, slice):
            return Rig(self.cameras[key])
        if isinstance(key, (Sequence, np.ndarray)):
            return Rig(tuple(self.cameras[operator.index(i)] for i in key))
        return self.cameras[operator.index(key)]

    def index(self, name: str) -> int:
        """Position of the camera called ``name``."""
        return self.names.index(name)

    def scaled(self, factor: float) -> Rig:
        """The rig for images resized by ``factor``; see :meth:`Camera.scaled`."""
        return Rig(tuple(c.scaled(factor) for c in self.cameras))

    def scale_for(self, resolution: float) -> float:
        """The factor (<= 1) that brings the rig's longest image side to ``resolution`` px (images
        already smaller stay as they are): the internal scale of every silhouette computation."""
        if resolution <= 0:
            raise ValueError(f"resolution must be positive, got {resolution}")
        return min(1.0, resolution / float(np.max(self.sizes)))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Rig):
            return NotImplemented
        return len(self) == len(other) and all(
            a == b for a, b in zip(self.cameras, other.cameras, strict=True)
        )

    __hash__ = None  # type: ignore[assignment]

    def allclose(self, other: Rig, rtol: float = 1e-12, atol: float = 1e-12) -> bool:
        """Same cameras in the same order, parameters within tolerance
        (see :meth:`Camera.allclose`)."""
        return len(self) == len(other) and all(
            a.allclose(b, rtol=rtol, atol=atol)
            for a, b in zip(self.cameras, other.cameras, strict=True)
        )


def as_rig(cameras: Rig | Camera | Sequence[Camera]) -> Rig:
    """A :class:`Rig` from a rig, a single camera or a sequence of cameras."""
    if isinstance(cameras, Rig):
        return cameras
    if isinstance(cameras, Camera):
        return Rig((cameras,))
    return Rig(tuple(cameras))


def view_rigs(rig: Rig) -> tuple[Rig, ...]:
    """One-camera rigs of ``rig``'s views, for code that projects or undistorts view by view
    (build once: a rig is validated on construction, which costs more than projecting or
    undistorting a view's points, and passing a :class:`Camera` builds one on every call)."""
    return tuple(as_rig(cam) for cam in rig)


# --- rotations (pure numpy, batched) --------------------------------------------------------


def _skew(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) cross-product matrices: ``_skew(a) @ b == a x b``."""
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1),
                     np.stack([-y, x, z], -1)], -2)


def rotation_from_rodrigues(rvec: np.ndarray) -> np.ndarray:
    """Rodrigues (axis * angle, radians) vectors (..., 3) -> rotation matrices (..., 3, 3).
    Same as ``cv2.Rodrigues`` for one vector."""
    r = np.asarray(rvec, dtype=np.float64)
    if r.shape[-1:] != (3,):
        raise ValueError(f"Rodrigues vectors must have shape (..., 3), got {r.shape}")
    theta = np.linalg.norm(r, axis=-1)[..., None, None]
    small = theta < 1e-8
    safe = np.where(small, 1.0, theta)
    A = _skew(r)
    # sin(theta)/theta and (1 - cos theta)/theta^2, with their Taylor limits at 0.
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * A + b * (A @ A)


def rodrigues_from_rotation(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> Rodrigues vectors (..., 3) with angle in [0, pi].
    Same as ``cv2.Rodrigues`` for one matrix (up to the sign ambiguity at exactly pi)."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must have shape (..., 3, 3), got {R.shape}")
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], axis=-1)  # 2 sin(theta) * axis
    cos = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    sin = 0.5 * np.linalg.norm(w, axis=-1)
    theta = np.arctan2(sin, cos)
    # Small and moderate angles: axis from the antisymmetric part.
    safe_sin = np.where(sin < 1e-12, 1.0, sin)
    factor = np.where(sin < 1e-12, 0.5, theta / (2.0 * safe_sin))
    rvec = w * factor[..., None]
    # Angles near pi: axis from the symmetric part (R + R^T)/2 - cos I = (1 - cos) a a^T.
    near_pi = cos < -0.5
    if np.any(near_pi):
        S = 0.5 * (R + np.swapaxes(R, -1, -2)) - cos[..., None, None] * np.eye(3)
        S = S / np.where(near_pi, 1.0 - cos, 1.0)[..., None, None]
        col = np.argmax(np.diagonal(S, axis1=-2, axis2=-1), axis=-1)
        axis = np.take_along_axis(S, col[..., None, None], axis=-1)[..., 0]
        with np.errstate(invalid="ignore", divide="ignore"):  # rows not near pi: unused
            axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        sign = np.where(np.sum(axis * w, axis=-1) < 0, -1.0, 1.0)
        rvec = np.where(near_pi[..., None], axis * (sign * theta)[..., None], rvec)
    return rvec

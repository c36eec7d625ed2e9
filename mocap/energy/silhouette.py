"""The silhouette energy E_S (Zhang et al. 2013, Eq. 11): a symmetric chamfer distance.

Per view C, with S_C the observed silhouette, S^p_C the projected model, D_C and D^p_C their
Euclidean distance transforms (0 inside each silhouette):

    E_S^C = 1/|S^p_C| sum_{p in S^p_C} D_C(p)  +  1/|S_C| sum_{q in S_C} D^p_C(q)

(the absolute differences of Eq. 11 reduce to these because each transform is 0 on its own
silhouette). E_S is the mean over views. The observed side (downscaled masks, their
transforms) is computed once per frame in :class:`SilhouetteTarget`; per particle only the
model mask is rasterized, and its distance transform is taken on the bounding box of the
observed silhouette grown by ``margin`` pixels (pixels of S_C lie there, so the second term
is exact up to the margin while the transform costs a fraction of the full image), with
OpenCV's 5x5 chamfer mask (Borgefors), within about 2 % of the Euclidean distance and 3-4x
faster than the exact transform used on the observed side. Distances are in pixels of the
internal resolution.

Fallbacks, reported in ``SilhouetteTarget.ignored``: a view whose observed silhouette is
empty is ignored (the energy averages the other views); if every view is empty the target
cannot be built (ValueError). A particle whose model silhouette is empty in a view scores
``empty_penalty`` (the internal image diagonal) for each term of that view, never NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from mocap.body.energy_mesh import EnergyMesh
from mocap.cameras import Rig, camera_coordinates, project
from mocap.energy import fused
from mocap.render import distance_transform, get_rasterizer
from mocap.render.scaling import scaled_size

# "auto": the compiled kernel of mocap/energy/fused.py when numba imports, else numpy;
# "numba" / "numpy" force one (benchmarks compare the two in one process).
DEFAULT_BACKEND = "auto"
BACKENDS = ("auto", "numba", "numpy")


@dataclass(frozen=True)
class SilhouetteTarget:
    """Observed silhouettes of one frame at internal resolution.

    masks: (C, h, w) bool; dt: (C, h, w) float32 distance to the observed silhouette;
    area: (C,) pixel counts; boxes: (C, 4) int (x0, y0, x1, y1) exclusive, grown by the margin;
    valid: (C,) bool, views used; ignored: names of views ignored (empty silhouettes).
    """

    masks: np.ndarray
    dt: np.ndarray
    area: np.ndarray
    boxes: np.ndarray
    valid: np.ndarray
    ignored: tuple[str, ...] = ()

    @property
    def size(self) -> tuple[int, int]:
        return self.masks.shape[1], self.masks.shape[2]


def downscale_masks(masks: np.ndarray, scale: float) -> np.ndarray:
    """(C, H, W) bool -> (C, h, w) bool at ``scaled_size``; a pixel is set when at least
    half of the area it covers is (cv2.resize INTER_AREA, the scaling convention of
    :mod:`mocap.render.scaling`)."""
    masks = np.asarray(masks)
    if masks.ndim != 3:
        raise ValueError(f"masks must be (C, H, W), got {masks.shape}")
    H, W = masks.shape[1:]
    h, w = scaled_size(H, W, scale)
    if (h, w) == (H, W):
        return masks.astype(bool)
    out = np.empty((len(masks), h, w), dtype=bool)
    for c, m in enumerate(masks):
        # the 0 / 1 bytes of the bool mask, made 0 / 255 only on the crop that is resized
        # (a 0 / 255 copy of the whole 1004 px image: 1 MB written a view, ~0.1 ms)
        out[c] = _resize_area(np.asarray(m, dtype=bool).view(np.uint8), w, h, gain=255) >= 128
    return out


def _resize_area(image: np.ndarray, w: int, h: int, gain: int = 1) -> np.ndarray:
    """cv2.resize(gain * image, (w, h), INTER_AREA) of a 2D uint8 image that is mostly 0
    (``gain * image`` within uint8: e.g. 255 for a 0 / 1 mask), on the
    crop of whole resampling blocks around its nonzero pixels: the same image, bit for bit
    (tested), at a fraction of the cost for a person in a large frame (1004 -> 251 px:
    0.76 -> 0.25 ms).

    Per axis, W / gcd(W, w) source pixels map onto w / gcd(W, w) output
    pixels, and no output pixel reads outside its block, so blocks of zeros give zeros and
    a block-aligned crop resamples like the whole image, provided the scale W / w is exact
    in binary floating point (w / gcd a power of two: OpenCV's area tables then shift by
    whole source pixels); otherwise the whole image is resized."""
    H, W = image.shape
    x, y, bw, bh = cv2.boundingRect(image)
    if bw == 0:
        return np.zeros((h, w), np.uint8)
    gx, gy = math.gcd(W, w), math.gcd(H, h)
    sx, ox, sy, oy = W // gx, w // gx, H // gy, h // gy
    if ox & (ox - 1) or oy & (oy - 1):
        return cv2.resize(_gained(image, gain), (w, h), interpolation=cv2.INTER_AREA)
    bx0, bx1 = x // sx, -(-(x + bw) // sx)
    by0, by1 = y // sy, -(-(y + bh) // sy)
    out = np.zeros((h, w), np.uint8)
    out[by0 * oy:by1 * oy, bx0 * ox:bx1 * ox] = cv2.resize(
        _gained(image[by0 * sy:by1 * sy, bx0 * sx:bx1 * sx], gain),
        ((bx1 - bx0) * ox, (by1 - by0) * oy), interpolation=cv2.INTER_AREA)
    return out


def _gained(image: np.ndarray, gain: int) -> np.ndarray:
    """gain * image in uint8 (the image itself for gain 1)."""
    return image if gain == 1 else np.multiply(image, gain, dtype=np.uint8)


def silhouette_target(masks: np.ndarray, scale: float = 1.0, margin: int = 12,
                      view_names: tuple[str, ...] | None = None) -> SilhouetteTarget:
    """Observed side of Eq. 11 from (C, H, W) camera-resolution masks."""
    small = downscale_masks(masks, scale)
    C, h, w = small.shape
    area = np.count_nonzero(small.reshape(C, -1), axis=1)
    valid = area > 0
    names = view_names or tuple(f"view {c}" for c in range(C))
    if not valid.any():
        raise ValueError("every observed silhouette is empty: nothing to track in this frame")
    dt = distance_transform(small, empty_value=0.0)
    boxes = np.zeros((C, 4), dtype=np.int64)
    for c in np.flatnonzero(valid):
        x, y, bw, bh = cv2.boundingRect(small[c].view(np.uint8))    # the set pixels' box
        boxes[c] = (max(0, x - margin), max(0, y - margin),
                    min(w, x + bw + margin), min(h, y + bh + margin))
    return SilhouetteTarget(masks=small, dt=dt, area=area, boxes=boxes, valid=valid,
                            ignored=tuple(n for n, v in zip(names, valid, strict=True) if not v))


def chamfer_energy(model: np.ndarray, target: SilhouetteTarget) -> np.ndarray:
    """Per-view symmetric chamfer of model masks (P, C, h, w) bool -> (P, C) float64.

    Views not ``valid`` in the target are NaN here (callers average the valid ones).
    """
    P, C, h, w = model.shape
    if (h, w) != target.size or C != len(target.masks):
        raise ValueError(f"model masks {model.shape[1:]} do not match the target "
                         f"{(len(target.masks),) + target.size}")
    penalty = float(np.hypot(h, w))
    out = np.full((P, C), np.nan)
    flat = model.reshape(P, C, h * w)
    model_area = np.count_nonzero(flat, axis=2)
    for c in np.flatnonzero(target.valid):
        x0, y0, x1, y1 = (int(v) for v in target.boxes[c])
        # term 1: observed DT averaged over the model silhouette (whole image)
        t1 = flat[:, c].astype(np.float32) @ target.dt[c].ravel()
        t1 = np.where(model_area[:, c] > 0, t1 / np.maximum(model_area[:, c], 1), penalty)
        # term 2: model DT averaged over the observed silhouette, inside its grown box
        obs_idx = np.flatnonzero(target.masks[c, y0:y1, x0:x1])
        crop = np.ascontiguousarray(model[:, c, y0:y1, x0:x1])
        background = (~crop).view(np.uint8)
        t2 = np.full(P, penalty)
        buf = np.empty(crop.shape[1:], np.float32)
        for p in range(P):
            if background[p].all():
                continue
            cv2.distanceTransform(background[p], cv2.DIST_L2, cv2.DIST_MASK_5, dst=buf)
            t2[p] = float(buf.ravel()[obs_idx].sum()) / target.area[c]
        out[:, c] = t1 + t2
    return out


class SilhouetteEnergy:
    """E_S for a shaped body seen by a rig at an internal resolution ``scale``.

    backend: "numba" runs :mod:`mocap.energy.fused` (rasterise + chamfer in one compiled pass
    per particle-view), "numpy" the scanline rasterizer and :func:`chamfer_energy` (same
    energies up to summation order), "auto" / None the compiled one when numba imports
    (``DEFAULT_BACKEND`` when None).
    mesh: an :class:`~mocap.body.energy_mesh.EnergyMesh` to rasterise instead of the full
    body mesh (fewer triangles and vertices per particle-view), None for the full mesh.
    """

    def __init__(self, shaped, rig: Rig, scale: float = 0.25, backend: str | None = None,
                 mesh: EnergyMesh | None = None):
        self.shaped = shaped
        self.rig = rig
        self.scale = float(scale)
        self.internal = rig.scaled(self.scale)
        w, h = (int(x) for x in self.internal.sizes[0])
        self.size = (h, w)
        if mesh is not None and mesh.num_source != shaped.model.num_vertices:
            raise ValueError(f"the energy mesh reads {mesh.num_source} vertices, the body has "
                             f"{shaped.model.num_vertices}")
        self.mesh = mesh
        self._basis = None if mesh is None else mesh.skinning_basis(shaped.skinning_basis)
        faces = shaped.model.faces if mesh is None else mesh.faces
        num_vertices = shaped.model.num_vertices if mesh is None else mesh.num_vertices
        self.rasterizer = get_rasterizer(faces, num_vertices)
        backend = DEFAULT_BACKEND if backend is None else backend
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if backend == "numba" and not fused.HAVE_NUMBA:
            raise RuntimeError("backend='numba' but numba is not installed")
        use_numba = backend == "numba" or (backend == "auto" and fused.numba_available())
        self.backend = "numba" if use_numba else "numpy"
        self.fused = fused.FusedSilhouetteEnergy(faces, num_vertices) if use_numba else None

    def energy_vertices(self, vertices: np.ndarray) -> np.ndarray:
        """(P, V, 3) posed body vertices -> the vertices this energy rasterises."""
        return vertices if self.mesh is None else self.mesh.apply(vertices)

    def model_masks(self, vertices: np.ndarray) -> np.ndarray:
        """(P, V, 3) posed body vertices -> (P, C, h, w) bool silhouettes at internal
        resolution (of the energy mesh where there is one)."""
        return self._rasterize(self.energy_vertices(vertices))

    def _rasterize(self, vertices: np.ndarray) -> np.ndarray:
        px, depth = project(self.internal, vertices, return_depth=True)
        return self.rasterizer(px, *self.size, depth, near=0.05)

    def per_view(self, chi: np.ndarray, target: SilhouetteTarget) -> np.ndarray:
        """(P, D) -> (P, C) chamfer per view (NaN for ignored views)."""
        vertices = self.shaped.vertices(chi, self._basis)       # of the energy mesh
        if self.fused is None:
            return chamfer_energy(self._rasterize(vertices), target)
        return self.fused(camera_coordinates(self.internal, vertices), self.internal, target,
                          near=0.05)

    def __call__(self, chi: np.ndarray, target: SilhouetteTarget) -> np.ndarray:
        """(P, D) -> (P,) E_S, the mean over valid views."""
        return np.nanmean(self.per_view(chi, target)[:, target.valid], axis=1)

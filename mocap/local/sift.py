"""Texture correspondences (Zhang et al. 2013, Sec. 4.1, Fig. 4): SIFT matches between the
previous and the current image of each camera.

Keypoints of the previous image that lie on the visible model surface (under the previous
estimate) are given 3D model points by casting their pixel rays onto the mesh: a face and
barycentric coordinates, so the point stays attached to the body as the pose changes. Their
matches in the current image (Lowe's ratio test) give image points, whose rays become the
Plücker lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import trimesh

from mocap.body.model import BodyModel
from mocap.cameras import Rig, pixel_rays, plucker_from_rays, project
from mocap.energy.fallback import warn_once
from mocap.local.raycast import HAVE_NUMBA, first_hits
from mocap.local.settings import SiftSettings
from mocap.local.solver import PointLines
from mocap.render import get_rasterizer


def surface_hits(verts: np.ndarray, faces: np.ndarray, origin: np.ndarray,
                 directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First hits of rays from ``origin`` on the mesh: (ray ids, triangles, barycentric (H, 3)),
    compiled (:mod:`mocap.local.raycast`) or, without numba, trimesh's ray caster."""
    if HAVE_NUMBA:
        ray, tri, _, bary = first_hits(verts, faces, origin, directions)
        return ray, tri, bary
    warn_once("raycast", "SIFT keypoints are cast onto the body by trimesh (~100x slower)")
    mesh = trimesh.Trimesh(verts, faces, process=False)
    loc, ray, tri = mesh.ray.intersects_location(np.repeat(np.asarray(origin)[None], len(directions), 0),
                                                 directions, multiple_hits=False)
    return ray, tri, trimesh.triangles.points_to_barycentric(mesh.triangles[tri], loc)


@dataclass(frozen=True)
class SurfacePairs:
    """Model surface points (their triangles' vertex ids (N, 3), barycentric (N, 3)) and their
    rays (d, m)."""

    triangles: np.ndarray
    bary: np.ndarray
    limbs: np.ndarray
    d: np.ndarray
    m: np.ndarray
    weight: float

    def correspondences(self, verts: np.ndarray) -> PointLines:
        X = np.einsum("nk,nkc->nc", self.bary, verts[self.triangles])
        return PointLines(X, self.limbs, self.d, self.m, np.full(len(X), self.weight))


@dataclass
class _Memory:
    descriptors: np.ndarray
    faces: np.ndarray
    bary: np.ndarray


_D = SiftSettings()   # the defaults of the keyword arguments


class SiftTracker:
    """Keeps each view's keypoints on the body from the last frame, matches the next frame."""

    def __init__(self, body: BodyModel, rig: Rig, scale: float = _D.scale, ratio: float = _D.ratio,
                 max_features: int = _D.max_features, weight: float = _D.weight,
                 mask_margin_px: int = _D.mask_margin_px):
        self.body, self.rig = body, rig
        self.scale, self.ratio, self.weight = scale, ratio, weight
        self.sift = cv2.SIFT_create(nfeatures=max_features)
        self.matcher = cv2.BFMatcher(cv2.NORM_L2)
        self.small = rig.scaled(scale)
        w, h = (int(v) for v in self.small.sizes[0])
        self.size = (h, w)
        self.raster = get_rasterizer(body.faces, body.num_vertices)
        self.margin = mask_margin_px
        self.memory: list[_Memory | None] = [None] * len(rig)
        self._current: list | None = None     # this frame's detections, reused by remember()

    def _detect(self, image: np.ndarray, mask: np.ndarray):
        """Keypoints (camera pixels (K, 2)) and descriptors (K, 128) inside ``mask`` (small
        resolution); SIFT runs on the mask's bounding box only (its pyramid would otherwise
        cover the whole image)."""
        h, w = self.size
        empty = np.zeros((0, 2)), np.zeros((0, 128), np.float32)
        ys, xs = np.nonzero(mask)
        if len(ys) == 0:
            return empty
        pad = 16
        y0, y1 = max(0, ys.min() - pad), min(h, ys.max() + 1 + pad)
        x0, x1 = max(0, xs.min() - pad), min(w, xs.max() + 1 + pad)
        small = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
        gray = cv2.cvtColor(np.ascontiguousarray(small[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
        kps, desc = self.sift.detectAndCompute(gray, mask[y0:y1, x0:x1].astype(np.uint8) * 255)
        if desc is None or not kps:
            return empty
        pts = np.array([k.pt for k in kps], np.float64) + [x0, y0]
        # keypoint coordinates of the small image -> camera pixels (pixel-centre convention)
        sx, sy = w / self.rig.sizes[0][0], h / self.rig.sizes[0][1]
        return np.c_[(pts[:, 0] + 0.5) / sx - 0.5, (pts[:, 1] + 0.5) / sy - 0.5], desc

    def remember(self, images: np.ndarray, verts: np.ndarray) -> dict:
        """Keypoints of these images on the visible surface of the body posed as ``verts``."""
        h, w = self.size
        px, depth = project(self.small, verts, return_depth=True)
        masks = self.raster(px, h, w, depth, near=0.05)
        k = np.ones((3, 3), np.uint8)
        kept = []
        for c, cam in enumerate(self.rig):
            inner = cv2.erode(masks[c].astype(np.uint8), k, iterations=2)
            if self._current is not None and self._current[c] is not None:
                pts, desc = self._current[c]
                sx, sy = w / self.rig.sizes[c][0], h / self.rig.sizes[c][1]
                u = np.round((pts[:, 0] + 0.5) * sx - 0.5).astype(int).clip(0, w - 1)
                v = np.round((pts[:, 1] + 0.5) * sy - 0.5).astype(int).clip(0, h - 1)
                on = inner[v, u] > 0
                pts, desc = pts[on], desc[on]
            else:
                pts, desc = self._detect(images[c], inner)
            if len(pts) == 0:
                self.memory[c] = None
                kept.append(0)
                continue
            origin, direction = pixel_rays(cam, pts)
            ray, tri, bary = surface_hits(verts, self.body.faces, cam.center, direction)
            if len(ray) == 0:
                self.memory[c] = None
                kept.append(0)
                continue
            self.memory[c] = _Memory(desc[ray], tri.astype(np.int64), bary)
            kept.append(int(len(ray)))
        self._current = None
        return {"remembered_per_view": kept}

    def match(self, images: np.ndarray, prev_verts: np.ndarray) -> tuple[SurfacePairs | None, dict]:
        """Pairs from the remembered keypoints to this frame's images (None: nothing matched)."""
        if all(m is None for m in self.memory):
            return None, {"sift_matches_per_view": [0] * len(self.rig),
                          "note": "no keypoints from a previous frame"}
        h, w = self.size
        px, depth = project(self.small, prev_verts, return_depth=True)
        masks = self.raster(px, h, w, depth, near=0.05)
        grow = np.ones((2 * self.margin + 1,) * 2, np.uint8)
        faces, bary, D, M, counts = [], [], [], [], []
        self._current = [None] * len(self.rig)
        for c, cam in enumerate(self.rig):
            mem = self.memory[c]
            if mem is None:
                counts.append(0)
                continue
            pts, desc = self._detect(images[c], cv2.dilate(masks[c].astype(np.uint8), grow))
            self._current[c] = (pts, desc)
            if len(pts) < 2 or len(mem.descriptors) < 2:
                counts.append(0)
                continue
            pairs = self.matcher.knnMatch(mem.descriptors, desc, k=2)
            good = [(a.queryIdx, a.trainIdx) for a, b in (p for p in pairs if len(p) == 2)
                    if a.distance < self.ratio * b.distance]
            if not good:
                counts.append(0)
                continue
            qi, ti = np.array(good).T
            origin, direction = pixel_rays(cam, pts[ti])
            d, m = plucker_from_rays(origin, direction)
            faces.append(mem.faces[qi])
            bary.append(mem.bary[qi])
            D.append(d)
            M.append(m)
            counts.append(int(len(qi)))
        info = {"sift_matches_per_view": counts}
        if not faces:
            info["note"] = "no SIFT matches in this frame"
            return None, info
        tris = self.body.faces[np.concatenate(faces)]
        limbs = self.body.part_labels[tris[:, 0]]
        return SurfacePairs(tris, np.concatenate(bary), limbs, np.concatenate(D), np.concatenate(M),
                            self.weight), info

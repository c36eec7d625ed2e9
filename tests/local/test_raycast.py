"""Compiled first hits of rays from one point (mocap/local/raycast.py) against trimesh's ray
caster, the independent reference."""

import numpy as np
import pytest
import trimesh

pytest.importorskip("numba")

from mocap.local.raycast import first_hits  # noqa: E402


def trimesh_hits(verts, faces, origin, dirs):
    mesh = trimesh.Trimesh(verts, faces, process=False)
    loc, ray, tri = mesh.ray.intersects_location(np.repeat(origin[None], len(dirs), 0), dirs,
                                                 multiple_hits=False)
    order = np.argsort(ray)
    return ray[order], tri[order], loc[order]


@pytest.mark.parametrize("origin", [(0.3, -3.0, 1.2), (2.5, 1.0, 3.0), (0.0, 0.2, 5.0)])
def test_first_hits_equal_trimesh_on_the_posed_body(body64, origin):
    rng = np.random.default_rng(1)
    chi = body64.zero_pose()
    chi[6:] = rng.normal(0, 0.3, body64.num_dofs - 6)
    chi = np.clip(chi, body64.limits[:, 0], body64.limits[:, 1])
    verts = body64.shaped(rng.normal(size=body64.num_shape)).pose(chi).vertices[0]
    origin = np.asarray(origin, float)
    # aimed at the body (most hit), some beside it (miss), unnormalised
    target = verts[rng.integers(len(verts), size=300)] + rng.normal(0, 0.08, (300, 3))
    dirs = (target - origin) * rng.uniform(0.5, 3.0, (300, 1))
    ray, tri, loc, bary = first_hits(verts, body64.faces, origin, dirs)
    ray2, tri2, loc2 = trimesh_hits(verts, body64.faces, origin, dirs)
    assert 50 < len(ray) < 300
    np.testing.assert_array_equal(ray, ray2)
    np.testing.assert_allclose(loc, loc2, atol=1e-9)
    assert np.mean(tri == tri2) > 0.99          # a ray through a shared edge may pick either
    np.testing.assert_allclose(np.einsum("nk,nkc->nc", bary, verts[body64.faces[tri]]), loc, atol=1e-9)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(axis=1), 1.0)


def test_rays_all_around_and_from_inside_use_every_triangle():
    """Rays spread over the whole sphere (no direction grid) from inside a closed box hit
    its walls where trimesh says; rays pointing away from a mesh in front hit nothing."""
    box = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    rng = np.random.default_rng(2)
    dirs = rng.normal(size=(200, 3))
    origin = np.array([0.1, -0.2, 0.3])
    ray, tri, loc, _ = first_hits(box.vertices, box.faces, origin, dirs)
    ray2, _, loc2 = trimesh_hits(box.vertices, box.faces, origin, dirs)
    np.testing.assert_array_equal(ray, ray2)
    np.testing.assert_allclose(loc, loc2, atol=1e-9)
    assert len(ray) == 200
    away = first_hits(box.vertices, box.faces, np.array([0.0, 0.0, 10.0]),
                      np.tile([0.0, 0.0, 1.0], (5, 1)))
    assert len(away[0]) == 0
    empty = first_hits(box.vertices, box.faces, origin, np.zeros((0, 3)))
    assert all(len(a) == 0 for a in empty)
    with pytest.raises(ValueError, match="directions"):
        first_hits(box.vertices, box.faces, origin, np.zeros(3))


def test_sift_surface_hits_without_numba_give_the_same_surface_points(body64, monkeypatch):
    from mocap.energy import fallback
    from mocap.local import sift

    verts = body64.shaped().pose(body64.zero_pose()).vertices[0]
    origin = np.array([0.2, -3.0, 1.0])
    dirs = verts[::97] - origin
    ray, tri, bary = sift.surface_hits(verts, body64.faces, origin, dirs)
    monkeypatch.setattr(sift, "HAVE_NUMBA", False)
    monkeypatch.setattr(fallback, "WARNED", set())
    with pytest.warns(RuntimeWarning, match="trimesh"):
        ray2, tri2, bary2 = sift.surface_hits(verts, body64.faces, origin, dirs)
    order = np.argsort(ray2)
    np.testing.assert_array_equal(ray, ray2[order])
    points = np.einsum("nk,nkc->nc", bary, verts[body64.faces[tri]])
    points2 = np.einsum("nk,nkc->nc", bary2[order], verts[body64.faces[tri2[order]]])
    np.testing.assert_allclose(points, points2, atol=1e-9)

"""The point chamfer (mocap/energy/point_chamfer.py, issue 38): equal to an independent numpy /
scipy reading of its definition; unchanged when the image and the cameras move by the same whole
pixels; near 0 for a body against its own render and growing with a shift of the render; ranks
the rendered pose first among perturbed ones, agreeing in rank with E_S."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.ndimage import map_coordinates
from scipy.spatial import cKDTree
from scipy.stats import spearmanr

import mocap
from mocap.body.energy_mesh import energy_mesh_for
from mocap.cameras import Rig, project
from mocap.energy.point_chamfer import PointChamferEnergy, contour_samples, observed_samples
from mocap.energy.silhouette import SilhouetteEnergy, SilhouetteTarget, silhouette_target

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def walk():
    body = mocap.load_body("paper22")
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=1, seed=3)
    return body, seq, 256 / float(np.max(seq.rig.sizes))


def _perturbed(body, chi, scales, seed=0):
    rng = np.random.default_rng(seed)
    s = np.repeat(scales, 8)[:, None]
    poses = np.vstack([chi[None], chi + s * rng.normal(size=(len(s), body.num_dofs))])
    return np.clip(poses, body.limits[:, 0], body.limits[:, 1])


def test_the_point_chamfer_equals_a_scipy_reading_of_its_definition(walk):
    """term 1: the observed transform read bilinearly at the projected points (map_coordinates,
    order 1; a point outside the image at the nearest image point, plus its distance to it),
    weighted by the vertices' areas (a third of each triangle's, computed here per triangle);
    term 2: each observed sample's distance to the nearest projected point (a k-d tree)."""
    body, seq, scale = walk
    mesh = energy_mesh_for(body, 500)
    shaped = body.shaped()
    target = silhouette_target(seq.masks[0], scale)
    energy = PointChamferEnergy(shaped, seq.rig, scale, mesh=mesh, samples=48)
    poses = _perturbed(body, seq.gt.chi[0], [0.1, 0.3], seed=2)      # some leave the image
    got = energy.per_view(poses, target)
    px = project(energy.internal, shaped.vertices(poses, energy._basis))          # (P, C, V, 2)
    samples, counts = observed_samples(target.masks, 48)
    assert (counts == 96).all()
    rest = mesh.apply(shaped.vertices(np.zeros((1, body.num_dofs))))[0].astype(np.float64)
    tri = rest[mesh.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    weights = np.bincount(mesh.faces.ravel(), np.repeat(area / 3, 3), minlength=len(rest))
    assert ((px < 0) | (px[..., 1:] > target.size[0] - 1)).any()           # the clamp is exercised
    for p in range(len(poses)):
        for c in range(len(seq.rig)):
            xy = px[p, c].astype(np.float64)
            inside = np.clip(xy, 0, [target.size[1] - 1, target.size[0] - 1])
            t1 = np.average(map_coordinates(target.dt[c].astype(np.float64), [inside[:, 1], inside[:, 0]],
                                            order=1) + np.hypot(*(xy - inside).T), weights=weights)
            t2 = cKDTree(xy).query(samples[c].T.astype(np.float64))[0].mean()
            np.testing.assert_allclose(got[p, c], t1 + t2, rtol=2e-4, atol=2e-4)


def test_the_point_chamfer_is_unchanged_when_image_and_cameras_move_by_whole_pixels(walk):
    body, seq, scale = walk
    shaped, mesh = body.shaped(), energy_mesh_for(body, 500)
    energy = PointChamferEnergy(shaped, seq.rig, scale, mesh=mesh)
    target = silhouette_target(seq.masks[0], scale)
    dx, dy = 5, -3
    poses = _perturbed(body, seq.gt.chi[0], [0.03, 0.08])
    px = project(energy.internal, shaped.vertices(poses, energy._basis))        # (P, C, V, 2)
    last = [target.size[1] - 1, target.size[0] - 1]
    poses = poses[np.all([((q >= 0) & (q <= last)).all(axis=(1, 2, 3)) for q in (px, px + [dx, dy])], axis=0)]
    assert len(poses) >= 8                       # poses whose points stay in the image either way
    before = energy(poses, target)
    moved = SilhouetteTarget(masks=np.roll(target.masks, (dy, dx), axis=(1, 2)),
                             dt=np.roll(target.dt, (dy, dx), axis=(1, 2)), area=target.area,
                             boxes=target.boxes + [dx, dy, dx, dy], valid=target.valid)
    shift = np.array([[0, 0, dx], [0, 0, dy], [0, 0, 0]])
    energy.internal = Rig(tuple(dataclasses.replace(cam, K=cam.K + shift) for cam in energy.internal))
    np.testing.assert_allclose(energy(poses, moved), before, rtol=1e-5, atol=1e-5)


def test_the_point_chamfer_of_a_body_against_its_own_render_is_near_zero_and_grows_with_a_shift(walk):
    """Against its own render only the sampling remains: the nearest surface point to an observed
    sample lies up to about half a vertex spacing away (< 1 px on the body's own vertices, 256
    px); the render moved by k px in every view costs what E_S says it does, within a factor 1.2
    (E_S itself: about k / 2, the half of the model outside the moved silhouette's strip)."""
    body, seq, scale = walk
    shaped = body.shaped(seq.gt.alpha) if getattr(seq.gt, "alpha", None) is not None else body.shaped()
    energy = PointChamferEnergy(shaped, seq.rig, scale, mesh=None, samples=128)
    chi = seq.gt.chi[0][None]
    target = silhouette_target(seq.masks[0], scale)
    own = float(energy(chi, target)[0])
    assert 0 <= own < 1.0, own                                  # 0.58 px measured
    sil = SilhouetteEnergy(shaped, seq.rig, scale)
    assert float(sil(chi, target)[0]) < 0.1                     # E_S of its own render: ~0
    for k in (4, 8, 16):
        moved = silhouette_target(np.roll(seq.masks[0], int(round(k / scale)), axis=2), scale)
        rise = float(energy(chi, moved)[0]) - own
        want = float(sil(chi, moved)[0])
        assert want / 1.2 < rise < 1.2 * want, (k, rise, want)


def test_the_point_chamfer_ranks_the_rendered_pose_first_and_agrees_with_the_silhouette_energy(walk):
    """Among poses perturbed by 0.1-0.4 rad (the early layers' spread; at 0.05 rad one of eight
    scores within its sampling bias, 0.01 px, below the rendered pose)."""
    body, seq, scale = walk
    shaped = body.shaped()
    target = silhouette_target(seq.masks[0], scale)
    poses = _perturbed(body, seq.gt.chi[0], [0.1, 0.2, 0.4])
    points = PointChamferEnergy(shaped, seq.rig, scale, mesh=energy_mesh_for(body, 500))(poses, target)
    own = SilhouetteEnergy(shaped, seq.rig, scale, mesh=energy_mesh_for(body, 2000))(poses, target)
    assert np.argmin(points) == 0 and np.argmin(own) == 0
    assert spearmanr(points, own)[0] > 0.9


def test_the_contour_samples_lie_on_the_outer_contour_evenly():
    mask = np.zeros((1, 40, 50), bool)
    mask[0, 10:30, 5:45] = True                               # a 40 x 20 rectangle: 116 contour pixels
    samples, counts = contour_samples(mask, 29)
    assert counts.tolist() == [29]
    x, y = samples[0]
    on_edge = (np.isin(x, [5, 44]) & (y >= 10) & (y <= 29)) | (np.isin(y, [10, 29]) & (x >= 5) & (x <= 44))
    assert on_edge.all()
    assert len({(a, b) for a, b in zip(x, y, strict=True)}) == 29           # every 4th pixel, distinct
    assert contour_samples(np.zeros((1, 8, 8), bool), 5)[1].tolist() == [0]
    with pytest.raises(ValueError, match="count"):
        contour_samples(mask, 0)
    both, n = observed_samples(mask, 29)                   # then 29 of the 800 set pixels
    assert n.tolist() == [58]
    np.testing.assert_array_equal(both[0, :, :29], samples[0])
    assert mask[0, both[0, 1, 29:].astype(int), both[0, 0, 29:].astype(int)].all()
    assert len({(a, b) for a, b in zip(*both[0, :, 29:], strict=True)}) == 29

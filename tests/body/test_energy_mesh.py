"""The coarse energy mesh (mocap/body/energy_mesh.py): a closed surface close to the body's,
posed exactly like the body it rides on, and an energy that ranks poses like the full mesh."""

import numpy as np
import pytest
import trimesh
from scipy.stats import spearmanr

from mocap.body.energy_mesh import energy_mesh_for, make_energy_mesh
from mocap.cameras import ring_rig
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.trackers.tracker_settings import ENERGY_MESH_FACES


def random_poses(body, n, std, seed=0):
    rng = np.random.default_rng(seed)
    chi = body.zero_pose(n).astype(np.float64)
    chi[:, :3] += rng.normal(0, 0.03, (n, 3))
    chi[:, 6:] += rng.normal(0, std, (n, body.num_dofs - 6))
    return np.clip(chi, body.limits[:, 0], body.limits[:, 1]).astype(body.dtype)


def test_posing_the_coarse_basis_equals_mapping_the_posed_full_mesh(body64):
    mesh = energy_mesh_for(body64, 2000)
    sb = body64.shaped(np.random.default_rng(1).normal(size=body64.num_shape))
    chi = random_poses(body64, 5, 0.4)
    direct = sb.vertices(chi, mesh.skinning_basis(sb.skinning_basis))
    mapped = mesh.apply(sb.pose(chi).vertices)
    assert direct.shape == (5, mesh.num_vertices, 3)
    np.testing.assert_allclose(direct, mapped, atol=1e-9)


def test_coarse_mesh_is_closed_and_lies_on_the_body_within_a_centimetre(body64):
    mesh = energy_mesh_for(body64, 2000)
    assert 1900 <= len(mesh.faces) <= 2000
    np.testing.assert_allclose(mesh.weight.sum(axis=1), 1.0, atol=1e-12)
    sb = body64.shaped()
    full = trimesh.Trimesh(sb.rest_vertices, body64.faces, process=False)
    coarse = trimesh.Trimesh(mesh.apply(sb.rest_vertices), mesh.faces, process=False)
    # closed for the scan fill: every edge has as many faces on each side (even counts,
    # consistent winding), so no row of a silhouette is left open
    _, counts = np.unique(np.sort(coarse.edges, axis=1), axis=0, return_counts=True)
    assert np.all(counts % 2 == 0) and coarse.is_winding_consistent
    # every full-mesh vertex within 15 mm of the coarse surface (independent: trimesh's
    # closest-point query; measured 10.7 mm), 95 % within 6 mm (5.1); the coarse vertices lie
    # on the body, so its chords cut inside it: 4.5 % less volume, within 6 %
    _, dist, _ = trimesh.proximity.closest_point(coarse, sb.rest_vertices)
    assert dist.max() < 0.015 and np.quantile(dist, 0.95) < 0.006
    assert 0.94 < coarse.volume / full.volume < 1.0


def test_coarse_energy_ranks_poses_like_the_full_mesh_and_finds_the_truth(body):
    rig = ring_rig(6, 3.5, 1.5, 256, 256, fov_deg=50, look_at=(0, 0, 0.9))
    sb = body.shaped()
    truth = random_poses(body, 1, 0.3, seed=5)
    full = SilhouetteEnergy(sb, rig, scale=1.0)
    coarse = SilhouetteEnergy(sb, rig, scale=1.0, mesh=energy_mesh_for(body, 2000))
    target = silhouette_target(full.model_masks(sb.pose(truth).vertices)[0], 1.0)
    chi = np.repeat(truth, 60, axis=0)                    # the truth and 59 poses around it
    chi[1:, 6:] += np.random.default_rng(7).normal(0, 0.15, (59, body.num_dofs - 6)).astype(body.dtype)
    e_full, e_coarse = full(chi, target), coarse(chi, target)
    assert spearmanr(e_full, e_coarse).correlation > 0.98
    assert np.argmin(e_coarse) == 0            # the pose that made the silhouettes wins
    assert e_coarse[0] < 0.1 * np.median(e_coarse)
    # its silhouettes overlap the full mesh's
    a = full.model_masks(sb.pose(chi[:5]).vertices)
    b = coarse.model_masks(sb.pose(chi[:5]).vertices)
    iou = (a & b).sum(axis=(2, 3)) / (a | b).sum(axis=(2, 3))
    assert iou.min() > 0.95


def test_energy_mesh_is_deterministic_and_refuses_bad_input(body, body64):
    a = make_energy_mesh(body.data.mean, body.faces, 1500)
    b = make_energy_mesh(body.data.mean, body.faces, 1500)
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.index, b.index)
    assert energy_mesh_for(body, None) is None and energy_mesh_for(body, 0) is None
    for bad in (2, len(body.faces)):
        with pytest.raises(ValueError, match="energy mesh faces"):
            make_energy_mesh(body.data.mean, body.faces, bad)
    with pytest.raises(ValueError, match="reads"):
        a.apply(np.zeros((2, 100, 3)))
    # a body whose mesh has other vertices than the one the energy mesh reads
    sub = type("Shaped", (), {"model": type("M", (), {"num_vertices": 10, "faces": body.faces})(),
                              "skinning_basis": np.zeros((4, 10))})()
    with pytest.raises(ValueError, match="energy mesh reads"):
        SilhouetteEnergy(sub, ring_rig(2, 3.5, 1.5, 64, 64, fov_deg=50), scale=1.0, mesh=a)


def test_apf_trackers_take_the_option(body):
    from functools import partial

    from mocap.trackers.presets import make_tracker

    make_apf_tracker, make_hybrid_tracker = partial(make_tracker, "apf"), partial(make_tracker, "hybrid")

    rig = ring_rig(4, 3.5, 1.5, 128, 128, fov_deg=50, look_at=(0, 0, 0.9))
    rng = np.random.default_rng(0)
    apf = make_apf_tracker(body=body, rig=rig, rng=rng, particles=4, layers=1, energy_mesh=1000)
    apf.initialize(body.zero_pose(), np.zeros(body.num_shape))
    assert apf.energy.mesh is not None and len(apf.energy.mesh.faces) <= 1000
    hybrid = make_hybrid_tracker(body=body, rig=rig, rng=rng, apf={"energy_mesh": 1000})
    assert hybrid.energy_mesh is apf.energy.mesh          # built once per body and size
    default = make_apf_tracker(body=body, rig=rig, rng=rng, particles=4, layers=1)
    default.initialize(body.zero_pose(), np.zeros(body.num_shape))
    assert len(default.energy.mesh.faces) <= ENERGY_MESH_FACES == 2000
    full = make_apf_tracker(body=body, rig=rig, rng=rng, particles=4, layers=1, energy_mesh=None)
    full.initialize(body.zero_pose(), np.zeros(body.num_shape))
    assert full.energy.mesh is None and len(full.energy.rasterizer.faces) == len(body.faces)


def test_energy_mesh_gives_the_same_energies_on_the_numpy_and_compiled_paths(body):
    pytest.importorskip("numba")
    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=50, look_at=(0, 0, 0.9))
    sb = body.shaped()
    mesh = energy_mesh_for(body, 2000)
    compiled = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba", mesh=mesh)
    numpy_path = SilhouetteEnergy(sb, rig, scale=1.0, backend="numpy", mesh=mesh)
    target = silhouette_target(compiled.model_masks(sb.pose(body.zero_pose(1)).vertices)[0], 1.0)
    chi = random_poses(body, 8, 0.3, seed=9)
    np.testing.assert_allclose(compiled.per_view(chi, target), numpy_path.per_view(chi, target),
                               rtol=1e-5, atol=1e-5)

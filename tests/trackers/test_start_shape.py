"""The start's shape searched with its pose (``InitSettings.shape_pose_searches``,
:mod:`mocap.trackers.start_shape`): the pose that follows a shape change keeps the posed surface
where it was; a body whose start has the wrong shape, posed as well as that shape allows, is brought
back towards the true body (a search over the pose alone makes it no better); off (0, the default),
the start and its cache key are the old ones."""

import numpy as np
import pytest

from mocap.cameras import project, ring_rig
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.render import get_rasterizer
from mocap.trackers.apf import run_apf
from mocap.trackers.init_cache import SHAPE_POSE_FIELDS, settings_text
from mocap.trackers.start_shape import pose_compensation, search_shape_with_pose, shape_pose_energy
from mocap.trackers.tracker_settings import APFSettings, InitSettings

C = 8
SIZE = 256
TRUE_SHAPE = (0.5, -0.5, 0.5, -1.0, 1.0, -0.5, 1.0, 0.0)
BENT = {"l_hip_flex": 0.5, "r_hip_flex": -0.3, "l_knee_flex": 0.8, "r_knee_flex": 0.3,
        "l_shoulder_abd": -0.4, "r_shoulder_abd": -0.4, "l_elbow_flex": 0.5, "r_elbow_flex": 0.3}


def subject(body):
    """A body of known shape in a bent pose, its exact masks in 6 views (256 px)."""
    rig = ring_rig(6, 3.5, 1.5, SIZE, SIZE, fov_deg=45, look_at=(0, 0, 0.9))
    alpha = np.zeros(body.num_shape)
    alpha[:C] = TRUE_SHAPE
    chi = np.zeros(body.num_dofs)
    for name, value in BENT.items():
        chi[body.dof_index(name)] = value
    px, depth = project(rig, body.pose(chi[None], alpha[None]).vertices[0], return_depth=True)
    masks = get_rasterizer(body.faces, body.num_vertices)(px, SIZE, SIZE, depth, near=0.05)
    return rig, alpha, chi, masks


def vertex_error_mm(body, alpha, chi, alpha_true, chi_true) -> float:
    got = body.pose(chi[None], alpha[None]).vertices[0]
    want = body.pose(chi_true[None], alpha_true[None]).vertices[0]
    return 1000 * float(np.linalg.norm(got - want, axis=1).mean())


def test_the_following_pose_keeps_the_surface_nearer_than_the_held_pose(body):
    """Least squares over the vertices: to first order the posed surface moves less with the pose
    following the shape than with the pose held, and exactly so for a small step."""
    rig, alpha, chi, _ = subject(body)
    M = pose_compensation(body, chi, alpha, C)
    assert M.shape == (body.num_dofs, C)
    for k in range(C):
        a = alpha.copy()
        a[k] += 0.05
        held = vertex_error_mm(body, a, chi, alpha, chi)
        followed = vertex_error_mm(body, a, chi + 0.05 * M[:, k], alpha, chi)
        assert followed <= held * (1 + 1e-6), (k, held, followed)
    leg = np.zeros(C)
    leg[:4] = 1.0
    a = alpha.copy()
    a[:C] += 0.05 * leg
    held = vertex_error_mm(body, a, chi, alpha, chi)
    assert vertex_error_mm(body, a, chi + 0.05 * M @ leg, alpha, chi) < 0.6 * held


def test_the_energy_scores_each_particle_with_its_own_shape(body):
    """A particle of the true shape and pose has E_S 0 on its own masks (as SilhouetteEnergy of
    that shape), another shape's does not; with the pose following, the pose scored is
    chi + (a - a0) M^T."""
    rig, alpha, chi, masks = subject(body)
    target = silhouette_target(masks, 1.0)
    wrong = alpha.copy()
    wrong[0] += 1.5
    energy = shape_pose_energy(body, rig, target, alpha, C)
    e = energy(np.stack([np.r_[chi, alpha[:C]], np.r_[chi, wrong[:C]]]))
    ref = SilhouetteEnergy(body.shaped(wrong), rig, 1.0)(chi[None], target)[0]
    assert e[0] == pytest.approx(0.0, abs=1e-9)
    assert e[1] == pytest.approx(ref, rel=1e-4) and e[1] > 0.05
    M = pose_compensation(body, chi, alpha, C)
    follow = shape_pose_energy(body, rig, target, alpha, C, follow=(M, alpha[:C]))
    x = np.r_[chi, wrong[:C]][None]
    want = np.clip(chi + M @ (wrong[:C] - alpha[:C]), body.limits[:, 0], body.limits[:, 1])
    np.testing.assert_allclose(follow.pose(x)[0], want)
    ref = SilhouetteEnergy(body.shaped(wrong), rig, 1.0)(want[None], target)[0]
    assert follow(x)[0] == pytest.approx(ref, rel=1e-4)


def test_a_wrong_shape_the_pose_search_cannot_fix_is_brought_back(body):
    """The start: the first four coefficients wrong by 1.2 (height, build), posed as well as that
    shape allows (the pose following the shape from the truth). The pose alone, searched as the
    start searches it (an APF of the same size), ends no nearer the true surface; the shape with
    the pose brings the surface within 20 mm (from 30) and E_S falls by more than half."""
    rig, alpha, chi, masks = subject(body)
    wrong = alpha.copy()
    wrong[:4] += [-1.2, 1.2, -1.2, 1.2]
    start = np.clip(chi + pose_compensation(body, chi, alpha, C) @ (wrong[:C] - alpha[:C]),
                    body.limits[:, 0], body.limits[:, 1])
    before = vertex_error_mm(body, wrong, start, alpha, chi)
    assert before > 25
    coarse, fine_target = silhouette_target(masks, 0.5), silhouette_target(masks, 1.0)
    small = rig.scaled(0.5)

    def fine(a, c):
        return float(SilhouetteEnergy(body.shaped(a), rig, 1.0)(c[None], fine_target)[0])

    apf = APFSettings(particles=60, layers=8, diffusion=0.7, shrink=0.9, estimate="best")
    pose_std = np.r_[np.full(3, 0.0125), np.full(3, 0.0375), np.full(body.num_dofs - 6, 0.075)]
    sil = SilhouetteEnergy(body.shaped(wrong), small, 1.0)
    posed, _ = run_apf(lambda x: sil(x, coarse), start, pose_std, body.limits, apf, np.random.default_rng(0),
                       root_point=sil.shaped.rest_joints[0])
    assert vertex_error_mm(body, wrong, posed, alpha, chi) > 0.9 * before      # the pose alone: no nearer

    def make_energy(c, a):
        return shape_pose_energy(body, small, coarse, a, C, follow=(pose_compensation(body, c, a, C), a[:C]))

    got, shape, report = search_shape_with_pose(body, start, wrong, make_energy, fine, lambda a, c: c, C,
                                                np.zeros(body.num_dofs), 0.5, 2, apf,
                                                np.random.default_rng(1))
    after = vertex_error_mm(body, shape, got, alpha, chi)
    assert report[0]["kept"]
    assert after < 20 and after < 0.7 * before, (before, after)
    assert fine(shape, got) < 0.5 * fine(wrong, start)
    np.testing.assert_array_equal(shape[C:], wrong[C:])                 # only the first C searched


def test_on_for_the_silhouette_only_hybrids_only():
    from mocap.trackers.presets import preset_settings

    assert InitSettings().shape_pose_searches == 0
    for name in ("hybrid", "hybrid_prior", "hybrid_100x15", "hybrid_prior_real"):
        assert preset_settings(name).initialization.shape_pose_searches > 0, name
    assert preset_settings("hybrid_kp").initialization.shape_pose_searches == 0


def test_off_by_default_and_the_cache_key_changes_only_when_on():
    """The settings' text (the init cache's key) is the old one while the search is off, whatever
    its other fields, and names them when it is on."""
    off = InitSettings(limb_hypotheses=200)
    assert off.shape_pose_searches == 0
    assert not any(name in settings_text(off) for name in SHAPE_POSE_FIELDS)
    assert settings_text(off) == settings_text(InitSettings(limb_hypotheses=200, shape_pose_particles=7))
    on = InitSettings(limb_hypotheses=200, shape_pose_searches=2)
    assert all(f"{name}=" in settings_text(on) for name in SHAPE_POSE_FIELDS)
    assert settings_text(on) != settings_text(InitSettings(limb_hypotheses=200, shape_pose_searches=3))


def test_bad_shape_pose_settings_are_refused_naming_the_field():
    with pytest.raises(ValueError, match="shape_pose_searches"):
        InitSettings(shape_pose_searches=-1)
    with pytest.raises(ValueError, match="shape_pose_shape_std"):
        InitSettings(shape_pose_shape_std=0.0)


def test_in_the_start_it_only_lowers_the_fine_energy_and_leaves_the_tracking_draws(body):
    """Last step of the start: the steps before draw the same numbers as without it, its result is
    kept only where the fine E_S falls, and it draws from a copy of the generator (what follows the
    start draws the same numbers as without it)."""
    from mocap.data.generate import make_synthetic
    from mocap.trackers.initialization import initialize_from_silhouettes

    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="walk", frames=1, fps=25, seed=2, images=False)
    cheap = dict(headings=4, hypotheses=1, keep=1, rounds=1, resolution=96, select_resolution=160,
                 pose_particles=12, pose_layers=3, shape_particles=10, shape_layers=3, local_iterations=2)
    runs = {}
    for searches in (0, 2):
        rng = np.random.default_rng(0)
        settings = InitSettings(shape_pose_searches=searches, shape_pose_particles=30, shape_pose_layers=4,
                                **cheap)
        chi, alpha, diag = initialize_from_silhouettes(body, rig, seq.masks[0], rng, settings)
        runs[searches] = chi, alpha, diag, rng.random()
    target = silhouette_target(seq.masks[0], 1.0)

    def fine(chi, alpha):
        return SilhouetteEnergy(body.shaped(alpha), rig, 1.0)(chi[None], target)[0]

    (c0, a0, _, r0), (c2, a2, diag, r2) = runs[0], runs[2]
    assert r2 == r0                                             # the generator left where it was
    assert len(diag["shape_pose"]) == 2
    assert diag["shape_pose"][0]["before"] == pytest.approx(fine(c0, a0), rel=1e-6)
    assert diag["shape_pose"][0]["kept"]                 # cheap settings leave shape to find: -17 %
    assert fine(c2, a2) == pytest.approx(min(s["after"] for s in diag["shape_pose"]), rel=1e-6)
    assert fine(c2, a2) < 0.95 * fine(c0, a0)

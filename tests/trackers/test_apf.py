import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.energy.total import FrameEnergy
from mocap.energy.weights import EnergyWeights
from mocap.eval.metrics import joint_errors
from mocap.trackers.apf import (
    APFSettings,
    find_beta,
    perturb,
    reflect_into,
    run_apf,
    survival_rate,
    systematic_resample,
)
from mocap.trackers.run import frame_of
from mocap.trackers.silhouette_tracker import APFTracker


def test_beta_search_hits_the_target_survival_rate():
    rng = np.random.default_rng(0)
    for target in (0.2, 0.5, 0.8):
        for _ in range(5):
            E = rng.gamma(2.0, 3.0, size=100)
            beta = find_beta(E, target)
            assert survival_rate(np.exp(-beta * (E - E.min()))) == pytest.approx(target, abs=1e-3)
    assert find_beta(np.ones(10), 0.5) == 0.0


def test_compiled_beta_bisection_equals_the_numpy_reference():
    """The compiled bisection (numba) visits the numpy reference's midpoints: same betas to
    the bisection's precision (two steps of 24 / 2^30 decades; in practice bit for bit),
    and each reaches the target survival rate."""
    from mocap.trackers import apf

    if not apf.HAVE_NUMBA:
        pytest.skip("numba is not installed")
    rng = np.random.default_rng(4)
    step = 24.0 / 2**apf.BETA_ITERATIONS
    for trial in range(200):
        G, P = rng.integers(1, 9), rng.integers(2, 250)
        E = rng.gamma(rng.uniform(0.3, 3.0), 1.0, (G, P)) * 10.0 ** rng.uniform(-5, 5)
        if trial % 5 == 0:
            E[0] = 2.5                                   # a flat set: beta 0
        target = rng.uniform(0.05, 0.95)
        ref = apf._find_betas_numpy(E, target)
        fast = apf.find_betas(E, target)
        assert np.array_equal(ref == 0.0, fast == 0.0)
        ok = ref > 0
        assert np.all(np.abs(np.log10(fast[ok] / ref[ok])) <= 2 * step)
        np.testing.assert_array_equal(apf.find_betas(E, target, compiled=False), ref)
        for g in np.flatnonzero(ok & (fast < 1e11)):
            rate = survival_rate(np.exp(-fast[g] * (E[g] - E[g].min())))
            assert rate == pytest.approx(target, abs=1e-6)


def test_particle_spread_is_numpys_std_bit_for_bit_and_the_root_spread_on_se3():
    from mocap.body.root_motion import root_spread
    from mocap.trackers.apf import particle_spread

    rng = np.random.default_rng(5)
    for P, D in ((100, 22), (2, 2), (257, 31), (50, 1)):
        x = rng.normal(size=(P, D)) * 10.0 ** rng.uniform(-3, 3, D)
        np.testing.assert_array_equal(particle_spread(x, None), x.std(axis=0))
    x = rng.normal(0.0, 0.2, (100, 22))
    root = np.array([0.0, 0.1, 0.9])
    std = particle_spread(x, root)
    np.testing.assert_array_equal(std[6:], x[:, 6:].std(axis=0))
    np.testing.assert_allclose(std[:6], root_spread(x[:, :6], root, compiled=False), atol=1e-14)


def test_systematic_resampling_preserves_the_weighted_mean_in_expectation():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(50, 3))
    w = rng.random(50) ** 3
    w /= w.sum()
    means = np.stack([x[systematic_resample(w, rng)].mean(axis=0) for _ in range(4000)])
    np.testing.assert_allclose(means.mean(axis=0), w @ x, atol=0.01)
    counts = np.bincount(systematic_resample(w, rng), minlength=50)
    assert np.all(np.abs(counts - 50 * w) < 1.0 + 1e-9)      # systematic: within one copy


def test_diffused_particles_never_leave_the_joint_limits(body):
    rng = np.random.default_rng(2)
    x = np.tile(body.zero_pose().astype(np.float64), (500, 1))
    std = np.full(body.num_dofs, 3.0)
    for root in (None, np.array([0.0, 0.0, 0.9])):
        y = perturb(x, std, body.limits, rng, root)
        assert np.all(y >= body.limits[:, 0]) and np.all(y <= body.limits[:, 1])
    lim = np.array([[-1.0, 1.0]])
    np.testing.assert_allclose(reflect_into(np.array([[1.5], [-1.25], [0.3], [7.0]]), lim),
                               [[0.5], [-0.75], [0.3], [1.0]])


def test_local_root_perturbation_rotates_about_the_root_point(body):
    rng = np.random.default_rng(3)
    x = body.zero_pose(200).astype(np.float64)
    x[:, 0] = 1.0                                              # the body stands 1 m away
    std = np.zeros(body.num_dofs)
    std[3:6] = 0.2                                             # rotation only
    y = perturb(x, std, body.limits, rng, root_point=np.array([0.0, 0.0, 0.9]))
    from mocap.body.twists import se3_exp

    T = se3_exp(y[:, :6])
    p = T[:, :3, :3] @ np.array([0.0, 0.0, 0.9]) + T[:, :3, 3]
    np.testing.assert_allclose(p, np.tile([1.0, 0.0, 0.9], (200, 1)), atol=1e-9)


@pytest.fixture(scope="module")
def frame_setup(body):
    rig = ring_rig(8, 3.5, 1.5, 320, 240, fov_deg=45, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="walk", frames=2, fps=25, seed=0)
    return rig, seq


PERTURBED = ("l_shoulder_flex", "r_shoulder_abd", "l_elbow_flex", "r_hip_flex", "l_knee_flex")


def _perturbed(body, chi):
    out = chi.astype(np.float64).copy()
    idx = [body.dof_index(n) for n in PERTURBED]
    out[idx] += np.deg2rad(20.0) * np.array([1, -1, 1, -1, 1])
    return np.clip(out, body.limits[:, 0], body.limits[:, 1])


def _search(body, rig, seq, seed, free):
    shaped = body.shaped(seq.gt.alpha)
    energy = FrameEnergy(EnergyWeights(smoothness=0.0), SilhouetteEnergy(shaped, rig, 1.0),
                         silhouette_target(seq.masks[1], 1.0), None, None)
    start = _perturbed(body, seq.gt.chi[1])
    std = np.r_[np.full(6, 0.02), np.full(body.num_dofs - 6, 0.25)]
    est, diag = run_apf(energy, start, std, body.limits,
                        APFSettings(particles=100, layers=15), np.random.default_rng(seed),
                        free=free, root_point=shaped.rest_joints[0])
    err = lambda c: joint_errors(shaped.joints(c), seq.gt.joints[1:2], body.joint_names).mean()  # noqa: E731
    return err(start), err(est), est, diag


def test_apf_over_the_perturbed_limbs_recovers_the_pose_and_is_deterministic(body, frame_setup):
    rig, seq = frame_setup
    free = np.zeros(body.num_dofs, bool)
    free[[body.dof_index(n) for n in PERTURBED]] = True
    before, after, est, diag = _search(body, rig, seq, 0, free)
    assert after < before / 4, (before, after)
    assert len(diag.beta) == 15 and diag.evaluations == 1500
    np.testing.assert_allclose(diag.survival, 0.5, atol=0.02)
    _, _, again, _ = _search(body, rig, seq, 0, free)
    np.testing.assert_array_equal(again, est)


def test_apf_over_all_dofs_reduces_the_error(body, frame_setup):
    # 22 free DOFs and 1,500 evaluations: a weaker search than over the perturbed limbs
    rig, seq = frame_setup
    before, after, _, _ = _search(body, rig, seq, 0, None)
    assert after < before / 1.5, (before, after)


def test_apf_rejects_a_nan_initial_pose(body, frame_setup):
    rig, seq = frame_setup
    tracker = APFTracker(body, rig, APFSettings(particles=10, layers=2), EnergyWeights(),
                         np.random.default_rng(0))
    bad = seq.gt.chi[0].copy()
    bad[8] = np.nan
    with pytest.raises(ValueError, match="initial pose must be a finite"):
        tracker.initialize(bad, seq.gt.alpha)


def test_apf_with_an_empty_view_ignores_it_and_says_so(body, frame_setup):
    rig, seq = frame_setup
    tracker = APFTracker(body, rig, APFSettings(particles=10, layers=2), EnergyWeights(),
                         np.random.default_rng(0))
    tracker.initialize(seq.gt.chi[0], seq.gt.alpha)
    frame = frame_of(seq, 1)
    masks = frame.masks.copy()
    masks[1] = False
    est = tracker.step(type(frame)(index=1, masks=masks))
    assert est.diagnostics["ignored_views"] == [rig.names[1]]
    assert np.all(np.isfinite(est.chi))


def test_run_apf_only_moves_free_dofs():
    rng = np.random.default_rng(0)
    limits = np.array([[-5.0, 5.0]] * 4)
    free = np.array([True, False, True, False])
    center = np.array([1.0, 2.0, 3.0, 4.0])
    est, _ = run_apf(lambda x: ((x - 0.5) ** 2).sum(1), center, np.full(4, 0.5), limits,
                     APFSettings(particles=50, layers=8), rng, free=free)
    assert est[1] == 2.0 and est[3] == 4.0
    assert abs(est[0] - 0.5) < abs(center[0] - 0.5) and abs(est[2] - 0.5) < abs(center[2] - 0.5)

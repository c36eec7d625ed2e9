"""Kinematically constrained propagation (truncated Gaussians) and the annealing loop with
crossover (mocap/trackers/markers/propagation.py, marker_anneal.py)."""

import numpy as np
import pytest
from scipy.stats import truncnorm

from mocap.body.catalogue import dof_moves, make_landmark_set
from mocap.trackers.apf import find_beta, find_betas
from mocap.trackers.markers.crossover import part_groups, run_annealing
from mocap.trackers.markers.propagation import (
    gibbs_truncated_normal,
    propagate_truncated,
    truncated_normal,
)
from mocap.trackers.tracker_settings import APFSettings


def test_truncated_normal_matches_scipy_truncnorm_moments():
    rng = np.random.default_rng(0)
    mean, std, lo, hi = 0.3, 0.5, 0.0, 0.6
    x = truncated_normal(np.full(200_000, mean), std, lo, hi, rng)
    assert x.min() >= lo and x.max() <= hi
    ref = truncnorm((lo - mean) / std, (hi - mean) / std, loc=mean, scale=std)
    assert x.mean() == pytest.approx(ref.mean(), abs=2e-3)
    assert x.std() == pytest.approx(ref.std(), abs=2e-3)
    np.testing.assert_array_equal(truncated_normal(np.array([0.1]), 0.0, 0.0, 1.0, rng), [0.1])


def test_gibbs_sampler_respects_the_box_and_the_correlation():
    rng = np.random.default_rng(1)
    cov = np.array([[1.0, 0.8], [0.8, 1.0]])
    x = gibbs_truncated_normal(np.zeros((20_000, 2)), cov, np.array([-10, -10.0]), np.array([10, 10.0]),
                               rng, sweeps=20)
    assert np.corrcoef(x.T)[0, 1] == pytest.approx(0.8, abs=0.03)      # a loose box: the Gaussian
    y = gibbs_truncated_normal(np.zeros((5_000, 2)), cov, np.array([-0.5, 0.0]), np.array([0.5, 2.0]),
                               rng, sweeps=10)
    assert y[:, 0].min() >= -0.5 and y[:, 0].max() <= 0.5 and y[:, 1].min() >= 0.0


def test_propagation_keeps_joint_angles_inside_the_limits_and_moves_the_root(body):
    rng = np.random.default_rng(2)
    x = np.tile(body.limits[:, 0].clip(-1, 1), (500, 1))               # every angle at its lower limit
    x[:, :6] = 0.0
    std = np.full(body.num_dofs, 2.0)
    y = propagate_truncated(x, std, body.limits, rng, np.array([0, 0, 0.9]))
    assert np.all(y[:, 6:] >= body.limits[6:, 0]) and np.all(y[:, 6:] <= body.limits[6:, 1])
    assert np.all(y[:, 6:].std(axis=0) > 0.1) and np.abs(y[:, :3]).max() > 1.0


def test_batched_beta_search_agrees_with_the_apf_one():
    rng = np.random.default_rng(3)
    E = rng.gamma(2.0, 3.0, size=(5, 80))
    np.testing.assert_allclose(find_betas(E, 0.5), [find_beta(e, 0.5) for e in E], rtol=1e-3)
    assert find_betas(np.ones((1, 10)), 0.5)[0] == 0.0


def test_body_parts_for_crossover_are_the_four_limbs(body):
    lms = make_landmark_set(body)
    groups = part_groups(dof_moves(body, lms))
    names = sorted(tuple(body.dof_names[d] for d in g.dofs) for g in groups)
    assert len(groups) == 4
    assert ("l_shoulder_flex", "l_shoulder_abd", "l_shoulder_rot", "l_elbow_flex") in names
    knee = [g for g in groups if body.dof_index("r_knee_flex") in g.dofs][0]
    assert {lms.names[i] for i in knee.landmarks} == {"r_knee", "r_ankle", "r_toe"}


def test_annealing_with_crossover_solves_a_separable_problem_better_than_without():
    # 6 "root" DOFs and four 4-DOF limbs; the energy of landmark g depends on limb g only
    D, target = 22, np.linspace(-0.5, 0.5, 22)
    moves = np.zeros((D, 5), bool)
    moves[:6] = True
    for g in range(4):
        moves[6 + 4 * g: 10 + 4 * g, g] = True

    def costs(x):
        out = np.stack([((x[:, 6 + 4 * g: 10 + 4 * g] - target[6 + 4 * g: 10 + 4 * g]) ** 2).sum(1)
                        for g in range(4)] + [((x[:, :6] - target[:6]) ** 2).sum(1)], axis=1)
        return out

    limits = np.array([[-np.inf, np.inf]] * 6 + [[-1.0, 1.0]] * 16)
    s = APFSettings(particles=60, layers=8)
    err = {}
    for name, groups in (("plain", ()), ("crossover", part_groups(moves))):
        e = []
        for seed in range(3):
            est, diag = run_annealing(costs, np.zeros(D), np.full(D, 0.3), limits, s,
                                      np.random.default_rng(seed), groups=groups)
            assert diag.evaluations == 60 * 8
            e.append(np.abs(est - target).mean())
        err[name] = np.mean(e)
    assert err["crossover"] < 0.6 * err["plain"]


def _reference_truncated_normal(mean, std, lo, hi, rng):
    """The inverse-CDF sampler as first written (broadcast, masked), for the test below."""
    from scipy.special import ndtr, ndtri

    mean, std = np.broadcast_arrays(np.asarray(mean, np.float64), np.asarray(std, np.float64))
    lo = np.broadcast_to(np.asarray(lo, np.float64), mean.shape)
    hi = np.broadcast_to(np.asarray(hi, np.float64), mean.shape)
    safe = np.where(std > 0, std, 1.0)
    with np.errstate(invalid="ignore"):
        a, b = ndtr((lo - mean) / safe), ndtr((hi - mean) / safe)
    u = a + rng.random(mean.shape) * (b - a)
    x = mean + safe * ndtri(np.clip(u, 1e-300, 1.0 - 1e-16))
    return np.where(std > 0, np.clip(x, lo, hi), mean)


def test_truncated_normal_equals_the_masked_reference_bit_for_bit():
    """The unmasked fast path (every std > 0) and the masked one draw the same uniforms and
    return the same samples as the reference, for (P, D) means with (D,) or (P, D) stds,
    zero stds and infinite bounds."""
    rng = np.random.default_rng(7)
    for trial in range(60):
        P, D = rng.integers(1, 120), rng.integers(1, 18)
        lo, hi = rng.uniform(-3, 0, D), rng.uniform(0, 3, D)
        lo[0], hi[-1] = -np.inf, np.inf
        mean = rng.uniform(np.maximum(lo, -3), np.minimum(hi, 3), (P, D))
        std = rng.uniform(0.01, 2.0, D if trial % 2 else (P, D))
        if trial % 3 == 0:
            std[..., rng.integers(D)] = 0.0
        seed = int(rng.integers(1 << 30))
        got = truncated_normal(mean, std, lo, hi, np.random.default_rng(seed))
        want = _reference_truncated_normal(mean, std, lo, hi, np.random.default_rng(seed))
        assert got.shape == want.shape
        np.testing.assert_array_equal(got, want)
        assert np.all((got >= lo) & (got <= hi))


def test_propagation_equals_perturb_then_truncated_normal_bit_for_bit(body):
    """The root part is exactly perturb(x, root std)[:, :6] (same normals drawn for all D
    columns), the joint angles the truncated Gaussian drawn after them, with or without a
    root point and with a still root."""
    from mocap.trackers.apf import perturb

    rng = np.random.default_rng(8)
    x = np.clip(rng.normal(0.0, 0.3, (120, body.num_dofs)), body.limits[:, 0], body.limits[:, 1])
    point = np.array([0.0, 0.1, 0.9])
    for root, root_on in ((point, True), (None, True), (point, False)):
        std = rng.uniform(0.01, 0.3, body.num_dofs)
        if not root_on:
            std[:6] = 0.0
        got = propagate_truncated(x, std, body.limits, np.random.default_rng(9), root)
        ref_rng = np.random.default_rng(9)
        root_std = np.where(np.arange(body.num_dofs) < 6, std, 0.0)
        want = perturb(x, root_std, body.limits, ref_rng, root) if root_on else x.copy()
        want[:, 6:] = truncated_normal(x[:, 6:], std[6:], body.limits[6:, 0], body.limits[6:, 1], ref_rng)
        np.testing.assert_array_equal(got, want)

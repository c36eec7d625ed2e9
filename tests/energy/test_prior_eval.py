"""Held-out log-likelihood machinery: kernel densities and bandwidth rules against direct sums."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import cdist
from scipy.stats import multivariate_normal

from mocap.energy.prior import ParzenPrior
from mocap.energy.prior_eval import (
    defensive_log_density,
    heldout_table,
    kde_log_density,
    parzen_log_density,
    scott_bandwidth,
    select_bandwidth_scale,
    silverman_bandwidth,
    uniform_log_density,
)


def test_parzen_log_density_is_the_n_dimensional_kernel_density():
    rng = np.random.default_rng(0)
    s, x = rng.normal(size=(12, 3)), rng.normal(size=(5, 3))
    prior = ParzenPrior.fit(s, ("a", "b", "c"))
    sig = prior.sigma
    direct = np.log(np.exp(-cdist(x, s, "sqeuclidean") / (2 * sig**2)).sum(1)
                    / (len(s) * (2 * np.pi * sig**2) ** 1.5))
    np.testing.assert_allclose(parzen_log_density(prior, x), direct, rtol=1e-12)
    # the energy's 1-D normalisation differs from it by a constant only
    diff = -prior.energy(x) - direct
    np.testing.assert_allclose(diff, diff[0], rtol=1e-12)
    np.testing.assert_allclose(diff[0], np.log((2 * np.pi) ** 1.0 * sig**2), rtol=1e-12)


def test_per_dof_bandwidth_density_is_the_mean_of_gaussians_at_the_samples():
    rng = np.random.default_rng(1)
    s, x = rng.normal(size=(40, 2)) * [1.0, 0.3], rng.normal(size=(7, 2))
    h = np.array([0.4, 0.1])
    ref = np.mean([multivariate_normal(m, np.diag(h**2)).pdf(x) for m in s], axis=0)
    np.testing.assert_allclose(kde_log_density(x, s, h), np.log(ref), rtol=1e-10)
    # it integrates to 1 (2-D grid)
    g = np.linspace(-6, 6, 401)
    X, Y = np.meshgrid(g, g)
    p = np.exp(kde_log_density(np.c_[X.ravel(), Y.ravel()], s, h)).sum() * (g[1] - g[0]) ** 2
    assert p == pytest.approx(1.0, abs=1e-6)


def test_leave_one_group_out_drops_the_own_group():
    rng = np.random.default_rng(2)
    s = rng.normal(size=(30, 2))
    groups = np.repeat([0, 1, 2], 10)
    got = kde_log_density(s, s, 0.5, groups, groups)
    for i in (0, 15, 29):
        other = s[groups != groups[i]]
        np.testing.assert_allclose(got[i], kde_log_density(s[i:i + 1], other, 0.5)[0], rtol=1e-12)


def test_bandwidth_rules_and_leave_one_clip_out_selection():
    rng = np.random.default_rng(3)
    s = rng.normal(size=(500, 4)) * [1.0, 2.0, 0.5, 1.0]
    T, n = s.shape
    np.testing.assert_allclose(scott_bandwidth(s), s.std(0, ddof=1) * T ** (-1 / 8))
    np.testing.assert_allclose(silverman_bandwidth(s), (4 / 6) ** (1 / 8) * s.std(0, ddof=1) * T ** (-1 / 8))
    # clips are tight clusters of near-identical poses: leaving out single samples would pick the
    # smallest kernel; leaving out whole clips picks one near the clusters' spread
    centres = rng.normal(size=(40, 2))
    clips = np.repeat(np.arange(40), 25)
    pts = centres[clips] + 1e-3 * rng.normal(size=(1000, 2))
    scales = np.geomspace(0.01, 3, 30)
    c, ll = select_bandwidth_scale(pts, clips, 1.0, scales)
    assert 0.15 < c < 1.5 and ll.argmax() not in (0, len(scales) - 1)
    c_single, _ = select_bandwidth_scale(pts, np.arange(1000), 1.0, scales)
    assert c_single == scales[0]


def test_uniform_and_defensive_mixture_densities():
    limits = np.array([[-1.0, 1.0], [0.0, 0.5]])
    assert uniform_log_density(limits) == pytest.approx(-np.log(2.0 * 0.5))
    log_p = np.log(np.array([1e-300, 0.2, 3.0]))
    got = defensive_log_density(log_p, np.log(0.5), 0.1)
    np.testing.assert_allclose(np.exp(got), 0.9 * np.exp(log_p) + 0.1 * 0.5, rtol=1e-12)
    with pytest.raises(ValueError, match="eps=1.0"):
        defensive_log_density(log_p, 0.0, 1.0)


def test_heldout_table_is_mean_log_likelihood_per_dof():
    rng = np.random.default_rng(4)
    poses = {"a": rng.normal(size=(10, 3)), "b": rng.normal(size=(6, 3)) + 1}
    dens = {"std": lambda x: -0.5 * (x**2).sum(1) - 1.5 * np.log(2 * np.pi)}
    t = heldout_table(dens, poses)
    for k in ("a", "b"):
        assert t[k]["std"] == pytest.approx(dens["std"](poses[k]).mean() / 3)
    assert t["all"]["std"] == pytest.approx(dens["std"](np.r_[poses["a"], poses["b"]]).mean() / 3)


def test_parzen_energy_with_many_samples_equals_the_direct_sum():
    # above 1000 samples the squared distances come from one matrix product
    rng = np.random.default_rng(5)
    s, x = rng.normal(size=(1500, 16)) * 0.5, rng.normal(size=(25, 16)) * 0.5
    prior = ParzenPrior(s, tuple(map(str, range(16))), 0.3)
    d2 = cdist(x, s, "sqeuclidean")
    direct = -(np.log(np.exp(-d2 / (2 * 0.3**2)).sum(1)) - np.log(np.sqrt(2 * np.pi) * 0.3 * len(s)))
    np.testing.assert_allclose(prior.squared_distances(x), d2, atol=1e-12)
    np.testing.assert_allclose(prior.energy(x), direct, rtol=1e-10)
    self_d2 = np.diag(prior.squared_distances(s[:3]))
    assert np.all(self_d2 >= 0) and np.all(self_d2 < 1e-12)          # clipped at 0, never negative

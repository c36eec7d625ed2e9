"""The Gaussian mixture's EM against known answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from experiments.tools.gmm import GaussianMixture, fit_gmm


def test_em_recovers_a_known_two_component_mixture():
    rng = np.random.default_rng(0)
    means = np.array([[0.0, 0.0, 0.0], [4.0, -3.0, 2.0]])
    covs = np.array([np.diag([1.0, 0.5, 0.2]), [[1.0, 0.6, 0.0], [0.6, 1.0, 0.0], [0.0, 0.0, 0.3]]])
    n = 6000
    label = rng.random(n) < 0.3
    x = np.where(label[:, None], rng.multivariate_normal(means[0], covs[0], n),
                 rng.multivariate_normal(means[1], covs[1], n))
    gmm, trace = fit_gmm(x, 2, np.random.default_rng(1), reg=1e-6)
    order = np.argsort(gmm.means[:, 0])
    np.testing.assert_allclose(gmm.weights[order], [0.3, 0.7], atol=0.02)
    np.testing.assert_allclose(gmm.means[order], means, atol=0.08)
    np.testing.assert_allclose(gmm.covariances[order], covs, atol=0.1)
    assert np.all(np.diff(trace) > -1e-9)                    # EM never lowers the likelihood
    truth = GaussianMixture(np.array([0.3, 0.7]), means, covs)
    assert trace[-1] >= truth.log_density(x).mean() - 1e-6   # the fit is at least as likely


def test_one_component_fit_is_the_sample_gaussian():
    rng = np.random.default_rng(2)
    x = rng.multivariate_normal([1.0, -2.0], [[2.0, 0.7], [0.7, 0.5]], 500)
    q = rng.normal(size=(20, 2))
    for cov_kind in ("full", "diag"):
        gmm, _ = fit_gmm(x, 1, rng, covariance=cov_kind, reg=1e-3)
        c = np.cov(x.T, bias=True) + 1e-3 * np.eye(2)
        if cov_kind == "diag":
            c = np.diag(np.diag(c))
        ref = multivariate_normal(x.mean(0), c).logpdf(q)
        np.testing.assert_allclose(gmm.log_density(q), ref, rtol=1e-10)


def test_bad_settings_raise():
    x = np.zeros((3, 2))
    with pytest.raises(ValueError, match="covariance='spherical'"):
        fit_gmm(x, 1, np.random.default_rng(0), covariance="spherical")
    with pytest.raises(ValueError, match="N >= k"):
        fit_gmm(x, 5, np.random.default_rng(0))

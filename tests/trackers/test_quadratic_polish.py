"""The two-cue fit's last step (mocap/trackers/quadratic_polish.py): a quadratic fitted to samples
is the quadratic that made them, and the trust region on such models finds a known minimum in a
narrow diagonal valley, with and without noise on the energy."""

import numpy as np

from mocap.trackers.quadratic_polish import fit_quadratic, newton_step, quadratic_polish


def valley(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A rotated quadratic's Hessian (eigenvalues 1e-2 to 1e2: a valley along no axis) and minimiser."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Q * np.logspace(-2, 2, n)) @ Q.T, rng.normal(size=n)


def test_the_fitted_quadratic_is_the_one_that_made_the_samples():
    """Exact samples of c + g.d + d^T H d / 2 in 5 dimensions: c, g and H come back to 1e-8."""
    H, _ = valley(5, 0)
    g, c = np.arange(5.0) - 2.0, 3.0
    d = np.random.default_rng(1).normal(size=(60, 5))
    e = c + d @ g + 0.5 * np.einsum("pi,ij,pj->p", d, H, d)
    c2, g2, H2 = fit_quadratic(d, e)
    assert abs(c2 - c) < 1e-8 and np.allclose(g2, g, atol=1e-8) and np.allclose(H2, H, atol=1e-8)


def test_the_newton_step_is_the_minimiser_cut_to_the_radius():
    """Inside the radius: -H^-1 g exactly; beyond it: the same direction at the radius's length;
    with a negative curvature the step still descends."""
    H, _ = valley(4, 2)
    g = np.ones(4)
    full = -np.linalg.solve(H, g)
    assert np.allclose(newton_step(g, H, 1e6), full)
    cut = newton_step(g, H, 0.1)
    assert np.isclose(np.linalg.norm(cut), 0.1) and np.allclose(cut / 0.1, full / np.linalg.norm(full))
    assert g @ newton_step(g, -H, 1.0) < 0


def test_the_polish_finds_a_known_minimum_in_a_diagonal_valley():
    """An 8-dimensional quadratic valley (condition 1e4), started 3 units from its minimum: exact,
    10 iterations end within 1e-4 of it; with uniform noise of amplitude 0.05 on every energy
    value (the silhouettes' pixel noise), the true energy within 0.1 of its floor (from over 100x
    that: along the flattest direction 0.1 is half a unit); and bounds are kept."""
    H, x_star = valley(8, 3)

    rng = np.random.default_rng(5)

    def energy(x, noise=0.0):
        d = np.atleast_2d(x) - x_star
        return 0.5 * np.einsum("pi,ij,pj->p", d, H, d) + noise * rng.uniform(-1, 1, len(d))

    start = x_star + 3.0 * np.eye(8)[0] @ np.linalg.qr(np.random.default_rng(4).normal(size=(8, 8)))[0]
    x, e, report = quadratic_polish(energy, start, 1.0, 10, np.random.default_rng(0))
    assert np.linalg.norm(x - x_star) < 1e-4 and report["moved"] >= 1 and report["start"] > e
    x, e, _ = quadratic_polish(lambda p: energy(p, 0.05), start, 1.0, 10, np.random.default_rng(0))
    assert energy(x)[0] < 0.1 < 0.01 * energy(start)[0]
    hi = x_star + 0.5
    x, _, _ = quadratic_polish(energy, start - 2.0, 1.0, 10, np.random.default_rng(0), upper=hi)
    assert np.all(x <= hi + 1e-12)

"""The local step solved within the joint limits (``active_limits``, issue 34 item 4): the box-bounded
quadratic's minimiser equals scipy's bounded least squares (BVLS) on the same system; a step whose
free solution stays inside the limits is the plain step; and where the true pose lies beyond a
limit (a wrist the elbow cannot reach: the case traced on the walk), the bounded steps end at a
lower point-line error than steps clipped after the solve, every pose within the limits."""

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from mocap.body.jacobian import dof_frames
from mocap.local.optimize import optimize_pose
from mocap.local.solver import bounded_solve, gauss_newton_step, normal_equations
from tests.local.test_solver import exact_correspondences, scene  # noqa: F401  (the fixture)


def _bvls(H, g, lo, hi):
    """min 0.5 d^T H d + g^T d in the box as least squares: ||L^T d + L^-1 g||^2 / 2, H = L L^T."""
    L = np.linalg.cholesky(H)
    return lsq_linear(L.T, -np.linalg.solve(L, g), bounds=(lo, hi), method="bvls", tol=1e-14).x


@pytest.mark.parametrize("seed", range(6))
def test_bounded_solve_equals_scipys_bounded_least_squares(seed):
    rng = np.random.default_rng(seed)
    D = 22
    M = rng.normal(size=(60, D))
    H = M.T @ M + 0.1 * np.eye(D)
    g = rng.normal(0, 5, D)
    free = np.linalg.solve(H, -g)
    lo = np.where(rng.random(D) < 0.3, -np.inf, -np.abs(free) * rng.uniform(0.2, 1.5, D))
    hi = np.where(rng.random(D) < 0.3, np.inf, np.abs(free) * rng.uniform(0.2, 1.5, D))
    lo[:6], hi[:6] = -np.inf, np.inf                       # the root: unbounded
    ours = bounded_solve(H, g, lo, hi)
    lo_f, hi_f = np.where(np.isfinite(lo), lo, -1e6), np.where(np.isfinite(hi), hi, 1e6)
    np.testing.assert_allclose(ours, _bvls(H, g, lo_f, hi_f), atol=1e-7)
    assert np.any(ours <= lo + 1e-12) or np.any(ours >= hi - 1e-12)        # a bound was reached
    np.testing.assert_allclose(bounded_solve(H, g, np.full(D, -np.inf), np.full(D, np.inf)), free, atol=1e-9)


def _beyond_a_limit(sb, truth):
    """The true pose with the left elbow bent 0.35 rad past its lower limit, and a start at it."""
    body = sb.model
    j = body.dof_index("l_elbow_flex")
    target = truth.copy()
    target[j] = body.limits[j, 0] - 0.35
    start = truth.copy()
    start[j] = body.limits[j, 0]
    return target, start, j


def test_a_step_inside_the_limits_is_the_plain_step_and_one_across_them_is_bvls(scene):  # noqa: F811
    sb, truth, rig, vid = scene
    body = sb.model
    start = truth.copy()
    start[6:] += 0.01
    corr, _ = exact_correspondences(sb, truth, rig, vid)(sb.vertices(start)[0].astype(np.float64))
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, start)
    plain = gauss_newton_step(body, start, corr, w, q, damping=1e-3)
    bounded = gauss_newton_step(body, start, corr, w, q, damping=1e-3, active_limits=True)
    np.testing.assert_allclose(bounded.delta, plain.delta, atol=1e-12)

    target, start, j = _beyond_a_limit(sb, truth)
    corr, _ = exact_correspondences(sb, target, rig, vid)(sb.vertices(start)[0].astype(np.float64))
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, start)
    step = gauss_newton_step(body, start, corr, w, q, damping=1e-3, max_step=10.0, active_limits=True)
    H, g, _ = normal_equations(body, corr, w, q)
    Hd = H + 1e-3 * np.diag(np.maximum(np.diag(H), 1e-12)) + 1e-9 * np.eye(len(H))
    lo, hi = body.limits[:, 0] - start, body.limits[:, 1] - start
    lo[:6], hi[:6] = -1e6, 1e6
    np.testing.assert_allclose(step.delta, _bvls(Hd, g, lo, hi), atol=1e-7)
    assert step.delta[j] == pytest.approx(0.0, abs=1e-12)          # held at its limit
    plain = gauss_newton_step(body, start, corr, w, q, damping=1e-3, max_step=10.0)
    assert plain.delta[j] < -0.1                                    # the free step goes past it


def test_bounded_steps_fit_a_pose_past_a_limit_better_than_clipped_ones(scene):  # noqa: F811
    sb, truth, rig, vid = scene
    body = sb.model
    target, start, _ = _beyond_a_limit(sb, truth)
    correspond = exact_correspondences(sb, target, rig, vid)
    clipped, d_clip = optimize_pose(sb, start, correspond, iterations=10, tolerance=1e-10)
    bounded, d_bound = optimize_pose(sb, start, correspond, iterations=10, tolerance=1e-10,
                                     active_limits=True)
    for chi in (clipped, bounded):
        assert np.all(chi[6:] >= body.limits[6:, 0] - 1e-12) and np.all(chi[6:] <= body.limits[6:, 1] + 1e-12)
    assert d_bound["rms_m"][-1] < 0.8 * d_clip["rms_m"][-1]

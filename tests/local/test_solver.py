import dataclasses

import numpy as np
import pytest

from mocap.body.jacobian import dof_frames, point_jacobians
from mocap.cameras import plucker_from_rays, ring_rig
from mocap.local.optimize import optimize_pose
from mocap.local.solver import PointLines, apply_delta, gauss_newton_step


@pytest.fixture(scope="module")
def scene(body64):
    rng = np.random.default_rng(0)
    sb = body64.shaped(rng.normal(0, 0.5, body64.num_shape))
    truth = body64.zero_pose().astype(np.float64)
    truth[:3] = [0.3, -0.2, 0.0]
    truth[3:6] = [0.0, 0.0, 0.4]
    lo, hi = body64.limits[6:, 0] + 0.1, body64.limits[6:, 1] - 0.1     # strictly inside
    truth[6:] = np.clip(rng.uniform(-0.3, 0.3, body64.num_dofs - 6), lo, hi)
    rig = ring_rig(4, 3.5, 1.5, 500, 500, fov_deg=45)
    vid = rng.choice(body64.num_vertices, 600, replace=False)
    return sb, truth, rig, vid


def exact_correspondences(sb, truth, rig, vid):
    """Rays from each camera centre through the true positions of the chosen vertices."""
    target = sb.pose(truth).vertices[0][vid].astype(np.float64)

    def correspond(verts):
        pts, d, m, limbs = [], [], [], []
        for cam in rig:
            dd, mm = plucker_from_rays(np.broadcast_to(cam.center, target.shape), target - cam.center)
            pts.append(verts[vid])
            d.append(dd)
            m.append(mm)
            limbs.append(sb.model.part_labels[vid])
        n = len(vid) * len(rig)
        return PointLines(np.concatenate(pts), np.concatenate(limbs), np.concatenate(d),
                          np.concatenate(m), np.ones(n)), {}

    return correspond


def test_linearised_jacobian_matches_finite_differences(scene):
    sb, truth, _, vid = scene
    body = sb.model
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, truth)
    X = sb.pose(truth).vertices[0][vid].astype(np.float64)
    # rigidly attached points (one joint each): vertices skinned to a single joint
    single = body.weights[vid].max(axis=1) > 0.999
    Jac = point_jacobians(body, X, body.part_labels[vid], w, q)
    eps = 1e-6
    for k in range(body.num_dofs):
        delta = np.zeros(body.num_dofs)
        delta[k] = eps
        Xp = sb.pose(apply_delta(body, truth, delta)).vertices[0][vid]
        Xm = sb.pose(apply_delta(body, truth, -delta)).vertices[0][vid]
        fd = (Xp - Xm) / (2 * eps)
        np.testing.assert_allclose(Jac[single, :, k], fd[single], atol=1e-6, err_msg=body.dof_names[k])


def test_gauss_newton_converges_to_the_true_pose_from_a_small_offset(scene):
    sb, truth, rig, vid = scene
    body = sb.model
    start = truth.copy()
    start[:3] += [0.03, -0.02, 0.01]
    start[3:6] += [0.02, -0.01, 0.03]
    start[6:] += np.deg2rad(5.0) * np.random.default_rng(1).choice([-1, 1], body.num_dofs - 6)
    start = np.clip(start, body.limits[:, 0], body.limits[:, 1])
    chi, diag = optimize_pose(sb, start, exact_correspondences(sb, truth, rig, vid), iterations=8,
                              tolerance=1e-10)
    J_true, J_est = sb.joints(truth)[0], sb.joints(chi)[0]
    assert 1e3 * np.linalg.norm(J_est - J_true, axis=1).max() < 0.5       # < 0.5 mm
    assert diag["rms_m"][-1] < 1e-4 and diag["rms_m"][0] > 1e-2


def test_too_few_correspondences_skip_the_update_and_say_so(scene):
    sb, truth, _, _ = scene
    body = sb.model
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, truth)
    z = np.zeros((3, 3))
    few = PointLines(z + 1.0, np.zeros(3, int), np.tile([0.0, 0.0, 1.0], (3, 1)), z, np.ones(3))
    step = gauss_newton_step(body, truth, few, w, q)
    assert not step.ok and "too few correspondences" in step.reason
    np.testing.assert_array_equal(step.chi, truth)
    chi, diag = optimize_pose(sb, truth, lambda v: (few, {}))
    assert np.all(np.isfinite(chi)) and diag["skipped"]


def test_assembled_system_equals_the_one_from_the_full_jacobian(scene):
    """linear_system builds A = -[d]x J column block by column block; the reference goes
    through the (N, 3, D) Jacobian."""
    from mocap.local.solver import linear_system, linear_system_reference

    sb, truth, rig, vid = scene
    body = sb.model
    start = truth.copy()
    start[6:] += 0.1
    corr, _ = exact_correspondences(sb, truth, rig, vid)(sb.pose(start).vertices[0].astype(np.float64))
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, start)
    free = np.random.default_rng(3).random(body.num_dofs) < 0.7
    for f in (None, free):
        got, ref = linear_system(body, corr, w, q, f), linear_system_reference(body, corr, w, q, f)
        for a, b in zip(got, ref, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def test_compiled_normal_equations_equal_the_full_jacobian_ones(scene, monkeypatch):
    """H = A^T W A and g = A^T W e0 accumulated per correspondence on the active DOFs only
    (compiled) equal the products of the reference (N, 3, D) Jacobian system, with and
    without free-DOF masks and with uneven weights; without numba the numpy path gives them
    too."""
    from mocap.energy import fallback
    from mocap.local import normal_equations as kernel
    from mocap.local.solver import linear_system_reference, normal_equations

    pytest.importorskip("numba")
    sb, truth, rig, vid = scene
    body = sb.model
    start = truth.copy()
    start[6:] += 0.1
    corr, _ = exact_correspondences(sb, truth, rig, vid)(sb.pose(start).vertices[0].astype(np.float64))
    rng = np.random.default_rng(5)
    corr = dataclasses.replace(corr, weights=rng.uniform(0.2, 2.0, len(corr)))
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, start)
    free = rng.random(body.num_dofs) < 0.7
    for f in (None, free):
        e0, A, wt = linear_system_reference(body, corr, w, q, f)
        H, g, rms = normal_equations(body, corr, w, q, f)
        np.testing.assert_allclose(H, A.T @ (wt[:, None] * A), rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(g, A.T @ (wt * e0), rtol=1e-10, atol=1e-12)
        assert rms == pytest.approx(np.sqrt((wt * e0**2).sum() / wt.sum()), rel=1e-12)
        monkeypatch.setattr(kernel, "HAVE_NUMBA", False)
        monkeypatch.setattr(fallback, "WARNED", set())
        with pytest.warns(RuntimeWarning, match="numpy path"):
            H2, g2, rms2 = normal_equations(body, corr, w, q, f)
        monkeypatch.undo()
        np.testing.assert_allclose(H2, H, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(g2, g, rtol=1e-10, atol=1e-12)


def test_energy_tolerance_stops_once_the_fit_stops_improving(scene):
    """Rays through noisy targets: the RMS falls to the noise floor; the rule ends the loop
    there, where the full 10 iterations gain nothing."""
    sb, truth, rig, vid = scene
    body = sb.model
    start = truth.copy()
    start[6:] += np.deg2rad(4.0)
    start = np.clip(start, body.limits[:, 0], body.limits[:, 1])
    noise = np.random.default_rng(4).normal(0, 0.005, (len(rig), len(vid), 3))
    target = sb.pose(truth).vertices[0][vid].astype(np.float64)

    def correspond(verts):
        d, m = zip(*(plucker_from_rays(np.broadcast_to(cam.center, target.shape),
                                       target + noise[c] - cam.center) for c, cam in enumerate(rig)),
                   strict=True)
        n = len(vid) * len(rig)
        return PointLines(np.tile(verts[vid], (len(rig), 1)), np.tile(body.part_labels[vid], len(rig)),
                          np.concatenate(d), np.concatenate(m), np.ones(n)), {}

    chi_full, full = optimize_pose(sb, start, correspond, iterations=10, tolerance=0.0)
    chi, diag = optimize_pose(sb, start, correspond, iterations=10, tolerance=0.0, energy_tolerance=0.02)
    assert full["iterations"] == 10 and full["stopped"] == "iterations"
    assert diag["stopped"] == "energy decrease below tolerance" and 2 <= diag["iterations"] <= 5
    rms = diag["rms_m"]
    assert rms[-2] - rms[-1] < 0.02 * rms[-2]                # the rule that fired, as stated
    assert all(a - b >= 0.02 * a for a, b in zip(rms[:-2], rms[1:-1], strict=True))
    # stopping early costs nothing measurable: joints within 0.1 mm of the 10-iteration fit
    J_full, J = sb.joints(chi_full)[0], sb.joints(chi)[0]
    assert 1e3 * np.linalg.norm(J - J_full, axis=1).max() < 0.1


def test_percentile90_is_numpys_percentile_bit_for_bit():
    from mocap.local.contour import percentile90

    rng = np.random.default_rng(11)
    for n in [*range(1, 40), 101, 1000, 4321]:
        x = rng.exponential(5.0, n)
        assert percentile90(x) == np.percentile(x, 90)


@pytest.mark.parametrize("offset_m", [0.0, 40.0])
def test_per_limb_moments_equal_the_per_correspondence_blocks(scene, offset_m):
    """The normal equations from per-limb 6 x 6 moments chained through the tree (the kernel
    used) equal the per-correspondence blocks on the active DOFs (the kernel before), with a
    free-DOF mask, uneven weights, limbs without correspondences, and a subject 40 m from the
    world origin (the moments are taken about a point of each limb)."""
    pytest.importorskip("numba")
    from mocap.local.normal_equations import accumulate, accumulate_per_correspondence
    from mocap.local.solver import _tree_tables

    sb, truth, rig, vid = scene
    body = sb.model
    start = truth.copy()
    start[0] += offset_m
    start[6:] += 0.1
    target = truth.copy()
    target[0] += offset_m
    corr, _ = exact_correspondences(sb, target, rig, vid)(sb.pose(start).vertices[0].astype(np.float64))
    rng = np.random.default_rng(7)
    keep = body.part_labels[np.tile(vid, len(rig))] != body.part_labels[vid[0]]   # one limb without
    wt = rng.uniform(0.2, 2.0, len(corr))
    w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, start)
    for free in (np.ones(body.num_dofs, bool), rng.random(body.num_dofs) < 0.7):
        args = (corr.points[keep], corr.d[keep], corr.m[keep], wt[keep], corr.limbs[keep],
                _tree_tables(body)[1], q, w, free)
        H, g, sq = accumulate(*args)
        H0, g0, sq0 = accumulate_per_correspondence(*args)
        assert np.all(H[~free] == 0) and np.all(g[~free] == 0)
        np.testing.assert_allclose(H, H0, rtol=1e-11, atol=1e-11 * np.abs(H0).max())
        np.testing.assert_allclose(g, g0, rtol=1e-11, atol=1e-11 * np.abs(g0).max())
        assert sq == sq0


def test_compiled_pose_maths_equal_the_numpy_functions(scene):
    """The compiled DOF frames and pose update (mocap.local.posing) equal dof_frames and
    apply_delta to rounding: random poses and steps, a global rotation near pi (so3_log's
    axis branch), a zero rotation (the series), and steps past the joint limits (clipped)."""
    pytest.importorskip("numba")
    from mocap.local.posing import apply_delta_compiled, dof_frames_compiled

    sb, truth, _, _ = scene
    body = sb.model
    rng = np.random.default_rng(9)
    for k in range(8):
        chi = truth.copy()
        chi[:6] = rng.normal(0, 0.6, 6)
        chi[6:] = rng.uniform(body.limits[6:, 0], body.limits[6:, 1])
        if k == 1:
            chi[3:6] = [0.0, 0.0, 0.0]
        if k == 2:
            chi[3:6] = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5]) * (np.pi - 1e-7)
        w, q, _ = dof_frames(body, sb.axes, sb.rest_joints, chi)
        w2, q2 = dof_frames_compiled(body, sb.axes, sb.rest_joints, chi)
        np.testing.assert_allclose(w2, w, rtol=0, atol=1e-13)
        np.testing.assert_allclose(q2, q, rtol=0, atol=1e-13)
        delta = rng.normal(0, 0.05 if k < 6 else 2.0, body.num_dofs)        # big: past the limits
        if k == 3:
            delta[3:6] = 0.0
        want = apply_delta(body, chi, delta)
        got = apply_delta_compiled(body, chi, delta)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 if k == 2 else 1e-13)
        if k >= 6:
            assert np.any(got[6:] == body.limits[6:, 1]) or np.any(got[6:] == body.limits[6:, 0])

"""Projection, undistortion, rays, Plücker lines, epipolar geometry and triangulation,
checked against OpenCV and against independent geometric constructions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from mocap.cameras import (
    Rig,
    epipolar_distance,
    fundamental_matrices,
    fundamental_matrix,
    pixel_rays,
    plucker_from_rays,
    point_line_distance,
    project,
    rodrigues_from_rotation,
    triangulate,
    undistort_points,
)

from .helpers import points_near_origin, random_camera, random_rig


@pytest.mark.parametrize("seed", range(5))
def test_project_equals_cv2_projectPoints_with_distortion(seed):
    rng = np.random.default_rng(seed)
    rig = random_rig(seed, num_cameras=3)
    X = points_near_origin(rng, 200)
    pixels = project(rig, X)
    assert pixels.shape == (3, 200, 2)
    for c, cam in enumerate(rig):
        assert cam.has_distortion
        ref, _ = cv2.projectPoints(X, rodrigues_from_rotation(cam.R), cam.t, cam.K, cam.dist)
        assert np.abs(pixels[c] - ref[:, 0]).max() < 1e-6


def test_project_without_distortion_equals_the_projection_matrix_also_with_skew(rng):
    cam = random_camera(rng, "c", distortion=False)
    K = cam.K.copy()
    K[0, 1] = 2.5
    cam = cam.replace(K=K)
    X = points_near_origin(rng, 50)
    x_h = np.concatenate([X, np.ones((50, 1))], axis=1) @ cam.P.T
    assert np.allclose(project(cam, X), x_h[:, :2] / x_h[:, 2:], rtol=0, atol=1e-9)


def test_project_of_a_batch_equals_one_call_per_particle(rig, rng):
    X = rng.normal([0, 0, 1], 0.4, size=(6, 50, 3))
    pixels, depth = project(rig, X, return_depth=True)
    assert pixels.shape == (6, 4, 50, 2) and depth.shape == (6, 4, 50)
    for p in range(6):
        single, single_depth = project(rig, X[p], return_depth=True)
        assert np.array_equal(pixels[p], single)
        assert np.array_equal(depth[p], single_depth)


def test_project_with_one_camera_drops_the_view_axis(rig, rng):
    X = rng.normal([0, 0, 1], 0.4, size=(3, 20, 3))
    assert np.array_equal(project(rig[2], X), project(rig, X)[:, 2])
    assert project(rig[2], X[0]).shape == (20, 2)


def test_depth_is_the_z_coordinate_in_each_camera(rig, rng):
    X = points_near_origin(rng, 30)
    _, depth = project(rig, X, return_depth=True)
    for c, cam in enumerate(rig):
        assert np.allclose(depth[c], (X @ cam.R.T + cam.t)[:, 2], atol=1e-12)
    assert np.all(depth > 0)


def test_float32_points_project_in_float32_close_to_float64(rig, rng):
    X = points_near_origin(rng, 100)
    p32 = project(rig, X.astype(np.float32))
    assert p32.dtype == np.float32
    assert np.abs(p32 - project(rig, X)).max() < 2e-3


def test_undistort_points_matches_cv2_and_inverts_projection(rig, rng):
    X = points_near_origin(rng, 100)
    pixels = project(rig, X)
    undistorted = undistort_points(rig, pixels)
    ideal = project(Rig(tuple(c.replace(dist=None) for c in rig)), X)
    assert np.abs(undistorted - ideal).max() < 1e-8
    for c, cam in enumerate(rig):
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
        ref = cv2.undistortPoints(pixels[c][:, None], cam.K, cam.dist, R=None, P=cam.K,
                                  criteria=criteria)[:, 0]
        assert np.abs(undistort_points(cam, pixels[c]) - ref).max() < 1e-6


def test_pixel_ray_passes_through_the_point_that_projected_to_it(rig, rng):
    X = points_near_origin(rng, 100)
    pixels = project(rig, X)  # with distortion
    origins, directions = pixel_rays(rig, pixels)
    assert origins.shape == directions.shape == (4, 100, 3)
    assert np.allclose(np.linalg.norm(directions, axis=-1), 1.0)
    to_point = X[None] - origins
    along = np.sum(to_point * directions, axis=-1)
    assert np.all(along > 0)  # the ray points into the scene, towards the point
    miss = np.linalg.norm(to_point - along[..., None] * directions, axis=-1)
    assert miss.max() < 1e-9
    # single camera form
    o1, d1 = pixel_rays(rig[1], pixels[1, :5])
    assert np.allclose(d1, directions[1, :5]) and np.allclose(o1, rig[1].center)


def _distance_to_line(x, origin, direction):
    """Independent reference: remove the component along the line."""
    u = direction / np.linalg.norm(direction, axis=-1, keepdims=True)
    v = x - origin
    return np.linalg.norm(v - np.sum(v * u, axis=-1, keepdims=True) * u, axis=-1)


def test_plucker_distance_is_zero_on_the_line_and_euclidean_off_it(rng):
    origin = rng.normal(size=(50, 3))
    direction = rng.normal(size=(50, 3)) * rng.uniform(0.1, 5.0, size=(50, 1))
    d, m = plucker_from_rays(origin, direction)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
    on_line = origin + rng.uniform(-10, 10, size=(50, 1)) * direction
    assert np.abs(point_line_distance(on_line, d, m)).max() < 1e-10
    off_line = rng.normal(scale=3.0, size=(50, 3))
    assert np.allclose(point_line_distance(off_line, d, m),
                       _distance_to_line(off_line, origin, direction), rtol=1e-10, atol=1e-12)
    # the moment does not depend on which point of the line is the origin
    _, m2 = plucker_from_rays(on_line, direction)
    assert np.allclose(m, m2, atol=1e-10)


def test_point_line_distance_broadcasts_particles_against_view_rays(rig, rng):
    X = rng.normal([0, 0, 1], 0.3, size=(5, 7, 3))  # (P, N, 3)
    origins, directions = pixel_rays(rig, project(rig, X[0]))  # (C, N, 3) rays of particle 0
    d, m = plucker_from_rays(origins, directions)
    dist = point_line_distance(X[:, None], d, m)  # (P, C, N)
    assert dist.shape == (5, 4, 7)
    assert dist[0].max() < 1e-9
    assert np.allclose(dist, _distance_to_line(X[:, None], origins, directions))


def _reference_fundamental(cam_a, cam_b):
    """Hartley & Zisserman (9.1): F = [e_b]_x P_b P_a^+ with e_b = P_b C_a."""
    e = cam_b.P @ np.append(cam_a.center, 1.0)
    ex = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    F = ex @ cam_b.P @ np.linalg.pinv(cam_a.P)
    return F / np.linalg.norm(F)


def test_fundamental_matrix_satisfies_the_epipolar_constraint(rig, rng):
    X = points_near_origin(rng, 300)
    undistorted = undistort_points(rig, project(rig, X))
    for a in range(len(rig)):
        for b in range(len(rig)):
            if a == b:
                continue
            F = fundamental_matrix(rig[a], rig[b])
            ref = _reference_fundamental(rig[a], rig[b])
            assert min(np.abs(F - ref).max(), np.abs(F + ref).max()) < 1e-9
            xa = np.concatenate([undistorted[a], np.ones((300, 1))], axis=1)
            xb = np.concatenate([undistorted[b], np.ones((300, 1))], axis=1)
            algebraic = np.einsum("ni,ij,nj->n", xb, F, xa)
            wrong = np.einsum("ni,ij,nj->n", np.roll(xb, 1, axis=0), F, xa)
            assert np.abs(algebraic).max() < 1e-9 * np.abs(wrong).max()
            good = epipolar_distance(F, undistorted[a], undistorted[b])
            bad = epipolar_distance(F, undistorted[a], np.roll(undistorted[b], 1, axis=0))
            assert good.max() < 1e-6
            assert np.median(bad) > 5.0 and np.mean(bad > 0.5) > 0.95


def test_fundamental_matrices_hold_every_ordered_pair(rig):
    F = fundamental_matrices(rig)
    assert F.shape == (4, 4, 3, 3)
    for a in range(4):
        assert np.all(F[a, a] == 0)
        for b in range(4):
            if a != b:
                assert np.allclose(F[a, b], fundamental_matrix(rig[a], rig[b]))
                assert np.array_equal(F[b, a], F[a, b].T)


def test_triangulation_recovers_points_from_noiseless_distorted_projections(rig, rng):
    X = points_near_origin(rng, 500)
    estimate = triangulate(rig, project(rig, X))
    assert estimate.shape == (500, 3)
    assert np.abs(estimate - X).max() < 1e-7


def test_triangulation_uses_only_valid_views_and_needs_two(rig, rng):
    X = points_near_origin(rng, 60)
    pixels = project(rig, X)
    valid = np.ones((4, 60), dtype=bool)
    valid[:, :20] = False
    valid[1, :10] = True        # points 0-9: one view  -> NaN
    valid[[0, 3], 10:20] = True  # points 10-19: two views -> exact
    pixels[~valid] = rng.uniform(0, 500, size=(np.count_nonzero(~valid), 2))  # garbage
    pixels[2, 20:25] = np.nan   # NaN pixels in a view count as missing
    estimate = triangulate(rig, pixels, valid)
    assert np.all(np.isnan(estimate[:10]))
    assert np.abs(estimate[10:] - X[10:]).max() < 1e-7


def test_triangulation_with_pixel_noise_is_centimetre_accurate(rng):
    rig = random_rig(11, num_cameras=6)
    X = points_near_origin(rng, 200)
    noisy = project(rig, X) + rng.normal(scale=0.5, size=(6, 200, 2))
    error = np.linalg.norm(triangulate(rig, noisy) - X, axis=-1)
    assert np.median(error) < 0.005 and error.max() < 0.03


def test_triangulation_weights_ignore_zero_weight_outliers(rig, rng):
    X = points_near_origin(rng, 40)
    pixels = project(rig, X)
    pixels[0] += 40.0  # a badly wrong view
    weights = np.ones((4, 40))
    weights[0] = 0.0
    assert np.abs(triangulate(rig, pixels, weights=weights) - X).max() < 1e-7
    assert np.abs(triangulate(rig, pixels) - X).max() > 1e-3


def test_triangulation_accepts_a_sequence_of_cameras(rig, rng):
    X = points_near_origin(rng, 10)
    cams = [random_camera(np.random.default_rng(s), f"c{s}") for s in range(3)]
    assert np.abs(triangulate(cams, project(Rig(tuple(cams)), X)) - X).max() < 1e-7


def test_cross3_is_numpys_cross_float_for_float():
    from mocap.cameras.projection import cross3

    rng = np.random.default_rng(2)
    for sa, sb in (((7, 3), (7, 3)), ((4, 5, 3), (3,)), ((1, 6, 3), (4, 1, 3)), ((3,), (3,))):
        for dt in (np.float32, np.float64):
            a, b = rng.normal(size=sa).astype(dt), rng.normal(size=sb).astype(dt)
            got, want = cross3(a, b), np.cross(a, b)
            assert got.dtype == want.dtype and got.shape == want.shape
            np.testing.assert_array_equal(got, want)

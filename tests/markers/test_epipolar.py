"""The symmetric epipolar distance and its N-view generalisation (mocap/energy/epipolar.py)."""

import numpy as np
import pytest

from mocap.cameras import Camera, Rig, fundamental_matrices, project, ring_rig
from mocap.energy.epipolar import (
    generalized_symmetric_epipolar_distance,
    pairwise_symmetric_sq,
    symmetric_epipolar_distance,
)


@pytest.fixture(scope="module")
def rig() -> Rig:
    return ring_rig(4, 3.5, 1.6, 640, 480, fov_deg=45, look_at=(0, 0, 0.9), start_deg=30)


@pytest.fixture(scope="module")
def points() -> np.ndarray:
    return np.random.default_rng(0).uniform([-0.5, -0.5, 0.2], [0.5, 0.5, 1.8], size=(50, 3))


def test_symmetric_epipolar_distance_is_zero_for_exact_correspondences(rig, points):
    F = fundamental_matrices(rig)
    px = project(rig, points)                                          # (C, N, 2)
    for a in range(4):
        for b in range(4):
            if a != b:
                np.testing.assert_allclose(symmetric_epipolar_distance(F[a, b], px[a], px[b]), 0.0, atol=1e-6)
    D = generalized_symmetric_epipolar_distance(F, np.moveaxis(px, 0, 1))
    np.testing.assert_allclose(D, 0.0, atol=1e-6)


def test_symmetric_epipolar_distance_is_symmetric_in_its_two_views(rig, points):
    F = fundamental_matrices(rig)
    rng = np.random.default_rng(1)
    px = project(rig, points) + rng.normal(0, 5.0, (4, len(points), 2))
    d_ab = symmetric_epipolar_distance(F[0, 2], px[0], px[2])
    d_ba = symmetric_epipolar_distance(F[2, 0], px[2], px[0])
    np.testing.assert_allclose(d_ab, d_ba, rtol=1e-10)
    assert np.all(d_ab > 0)
    sq = pairwise_symmetric_sq(F, np.moveaxis(px, 0, 1))               # (N, C, C)
    np.testing.assert_allclose(sq, np.swapaxes(sq, -1, -2), rtol=1e-10)


def test_symmetric_epipolar_distance_grows_with_offset_across_the_epipolar_line(rig, points):
    F = fundamental_matrices(rig)
    px = project(rig, points[:1])[:, 0]                                # (C, 2)
    line = F[0, 1] @ np.r_[px[0], 1.0]                                 # epipolar line in view 1
    normal = line[:2] / np.linalg.norm(line[:2])
    offsets = np.linspace(0.0, 20.0, 11)
    d = symmetric_epipolar_distance(F[0, 1], px[0], px[1] + offsets[:, None] * normal)
    assert d[0] < 1e-6 and np.all(np.diff(d) > 0)
    # in view 1 the point moved exactly `offset` from the line; the other half of d_sym adds to it
    assert np.all(d[1:] >= offsets[1:] - 1e-9)
    along = np.array([normal[1], -normal[0]])
    d_along = symmetric_epipolar_distance(F[0, 1], px[0], px[1] + 15.0 * along)
    assert d_along < 1e-6      # two views cannot see a slide along the epipolar line ...


def test_a_third_view_catches_what_two_views_cannot(rig, points):
    F = fundamental_matrices(rig)
    px = project(rig, points[:1])[:, 0]
    line = F[0, 1] @ np.r_[px[0], 1.0]
    along = np.array([line[1], -line[0]]) / np.linalg.norm(line[:2])
    x = px.copy()
    x[1] += 15.0 * along                                               # ... three views can
    assert generalized_symmetric_epipolar_distance(F, x, np.array([1, 1, 0, 0], bool)) < 1e-6
    assert generalized_symmetric_epipolar_distance(F, x, np.array([1, 1, 1, 0], bool)) > 1.0
    assert np.isnan(generalized_symmetric_epipolar_distance(F, x, np.array([1, 0, 0, 0], bool)))


def test_rectified_stereo_gives_the_known_distance():
    # two identical cameras 0.5 m apart along x: epipolar lines are the image rows, so
    # d_sym^2 = (y_b - y_a)^2 + (y_a - y_b)^2
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    a = Camera("a", K, None, np.eye(3), np.zeros(3), 640, 480)
    b = Camera("b", K, None, np.eye(3), np.array([-0.5, 0.0, 0.0]), 640, 480)
    F = fundamental_matrices(Rig((a, b)))
    d = symmetric_epipolar_distance(F[0, 1], np.array([100.0, 200.0]), np.array([37.0, 203.0]))
    assert d == pytest.approx(np.sqrt(2 * 3.0**2), rel=1e-9)

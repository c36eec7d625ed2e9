"""The global twist across a heading of ±180°: rotation vectors of nearly equal poses point in
opposite directions there, so a coordinate-wise mean or spread of twists is wrong. The SE(3)
mean, spread, interpolation and prediction (mocap.body.root_motion) and the annealing core
must give the answers computed by hand."""

import numpy as np
import pytest

from mocap.body.root_motion import interpolate_root, predict_root, root_mean, root_spread
from mocap.body.twists import se3_exp, se3_log
from mocap.trackers.apf import anneal
from mocap.trackers.tracker_settings import APFSettings

ROOT = np.array([0.0, 0.0, 0.9])     # rest root point


def twist(heading: float, position=(0.0, 0.0, 0.9)) -> np.ndarray:
    """Twist (6,) of a pose turned by ``heading`` about z with the root point at ``position``."""
    c, s = np.cos(heading), np.sin(heading)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = np.asarray(position) - T[:3, :3] @ ROOT
    return se3_log(T[None])[0]


def heading_of(xi: np.ndarray) -> float:
    R = se3_exp(np.atleast_2d(xi))[0, :3, :3]
    return float(np.arctan2(R[1, 0], R[0, 0]))


def root_of(xi: np.ndarray) -> np.ndarray:
    T = se3_exp(np.atleast_2d(xi))[0]
    return T[:3, :3] @ ROOT + T[:3, 3]


def wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def test_twists_either_side_of_180_point_opposite_ways():
    a, b = twist(np.radians(178)), twist(np.radians(-178))
    assert np.dot(a[3:], b[3:]) < 0                 # the trap a coordinate-wise mean falls in
    assert abs(heading_of((a + b) / 2)) < np.radians(5)


def test_mean_of_headings_178_and_minus_178_is_180():
    xi = np.stack([twist(np.radians(178), (1.0, 2.0, 0.9)), twist(np.radians(-178), (1.2, 2.0, 0.9))])
    m = root_mean(xi, np.array([0.5, 0.5]), ROOT)
    assert abs(wrap(heading_of(m) - np.pi)) < 1e-9
    np.testing.assert_allclose(root_of(m), [1.1, 2.0, 0.9], atol=1e-9)
    # weighted 3:1 -> 179 degrees (chordal mean of two rotations about one axis: the angle of
    # the weighted sum of their unit vectors, atan2(0.75 s1 + 0.25 s2, 0.75 c1 + 0.25 c2))
    m = root_mean(xi, np.array([0.75, 0.25]), ROOT)
    h1, h2 = np.radians(178), np.radians(-178)
    expected = np.arctan2(0.75 * np.sin(h1) + 0.25 * np.sin(h2), 0.75 * np.cos(h1) + 0.25 * np.cos(h2))
    assert abs(wrap(heading_of(m) - expected)) < 1e-9


def test_spread_across_180_is_the_angular_spread():
    hs = np.radians([177.0, 179.0, -179.0, -177.0])           # +-1 and +-3 degrees about 180
    xi = np.stack([twist(h) for h in hs])
    s = root_spread(xi, ROOT)
    np.testing.assert_allclose(s[:3], 0.0, atol=1e-9)          # root point does not move
    assert s[5] == pytest.approx(np.radians(np.sqrt((1 + 9 + 1 + 9) / 4)), rel=1e-6)
    assert s[3] == pytest.approx(0.0, abs=1e-9) and s[4] == pytest.approx(0.0, abs=1e-9)


def test_interpolation_and_prediction_cross_180_the_short_way():
    # turning on the spot (the screw axis passes through the root point, which stays put)
    a, b = twist(np.radians(178), (0.3, 0.1, 0.9)), twist(np.radians(-178), (0.3, 0.1, 0.9))
    mid = interpolate_root(a, b, np.array([0.25, 0.5]))
    assert abs(wrap(heading_of(mid[0]) - np.radians(179))) < 1e-9
    assert abs(wrap(heading_of(mid[1]) - np.pi)) < 1e-9
    np.testing.assert_allclose(root_of(mid[1]), [0.3, 0.1, 0.9], atol=1e-9)
    nxt = predict_root(a, b, 1.0)                              # one more step of 4 degrees
    assert abs(wrap(heading_of(nxt) - np.radians(-174))) < 1e-9
    np.testing.assert_allclose(root_of(nxt), [0.3, 0.1, 0.9], atol=1e-9)
    half = predict_root(a, b, 0.5)                             # damped: half a step
    assert abs(wrap(heading_of(half) - np.radians(-176))) < 1e-9
    # walking straight while facing 180 degrees: the root moves along the line
    c, d = twist(np.pi, (0.0, 0.0, 0.9)), twist(np.pi, (-0.1, 0.0, 0.9))
    np.testing.assert_allclose(root_of(predict_root(c, d, 1.0)), [-0.2, 0.0, 0.9], atol=1e-9)


def test_annealing_finds_a_pose_facing_180_degrees():
    """A 6-DOF search whose energy is the distance to a target turned by 180 degrees, started
    at 176 degrees: the estimate (SE(3) mean of the last layer) lands near 180, not near 0."""
    target = twist(np.pi, (0.5, -0.3, 0.9))
    R_t = se3_exp(target[None])[0, :3, :3]
    p_t = root_of(target)

    def energy(x):
        T = se3_exp(x)
        p = T[:, :3, :3] @ ROOT + T[:, :3, 3]
        cos = (np.einsum("pij,ij->p", T[:, :3, :3], R_t) - 1) / 2
        return 50 * np.sum((p - p_t) ** 2, axis=1) + 10 * (1 - cos)

    limits = np.tile([-10.0, 10.0], (6, 1))
    start = twist(np.radians(176), (0.45, -0.25, 0.9))
    est, trace = anneal(energy, start, np.array([0.05] * 3 + [0.05] * 3), limits,
                        APFSettings(particles=200, layers=8), np.random.default_rng(0), root_point=ROOT)
    assert len(trace.layers) == 8
    assert abs(wrap(heading_of(est) - np.pi)) < np.radians(2)
    assert np.linalg.norm(root_of(est) - p_t) < 0.02

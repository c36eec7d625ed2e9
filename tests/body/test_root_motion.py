"""The compiled (numba) root maps of mocap.body.root_motion against their numpy references and
against known answers: the per-particle exp / log / relative-rotation loops must equal the
numpy formulas of mocap.body.twists to rounding (ill-conditioned only within ~1e-6 rad of a
half turn, where the log itself loses half its digits)."""

import numpy as np
import pytest

from mocap.body import root_motion as rm
from mocap.body.twists import se3_exp, se3_log, so3_exp, so3_log

pytestmark = pytest.mark.skipif(not rm.HAVE_NUMBA, reason="numba is not installed")

ROOT = np.array([0.1, -0.2, 0.9])


def twists(rng, n, near_pi=False, tiny=False):
    xi = rng.normal(0.0, 1.0, (n, 6))
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    if near_pi:
        angle = np.pi - 10.0 ** rng.uniform(-12, -2, n)
    elif tiny:
        angle = 10.0 ** rng.uniform(-12, -3, n)
    else:
        angle = rng.uniform(0.0, 3.0, n)
    xi[:, 3:] = axis * angle[:, None]
    return xi


@pytest.mark.parametrize("kind", ["generic", "tiny"])
def test_compiled_root_maps_equal_the_numpy_formulas(kind):
    rng = np.random.default_rng(0)
    xi = twists(rng, 200, tiny=kind == "tiny")
    noise = twists(rng, 200, tiny=kind == "tiny") * 0.2
    R, p = rm.root_frames(xi, ROOT, compiled=True)
    T = se3_exp(xi)
    np.testing.assert_allclose(R, T[:, :3, :3], atol=1e-14)
    np.testing.assert_allclose(p, T[:, :3, :3] @ ROOT + T[:, :3, 3], atol=1e-13)
    np.testing.assert_allclose(rm.root_spread(xi * 0.3, ROOT, compiled=True),
                               rm.root_spread(xi * 0.3, ROOT, compiled=False), atol=1e-13)
    np.testing.assert_allclose(rm.perturb_root(xi, noise, ROOT, compiled=True),
                               rm.perturb_root(xi, noise, ROOT, compiled=False), atol=1e-12)
    u = np.linspace(-0.5, 2.0, 40)
    for a, b in zip(xi[:20], xi[20:40], strict=True):
        np.testing.assert_allclose(rm.interpolate_root(a * 0.5, b * 0.5, u, compiled=True),
                                   rm.interpolate_root(a * 0.5, b * 0.5, u, compiled=False), atol=1e-12)


def test_compiled_root_maps_near_a_half_turn():
    """Near a half turn so3_log (arccos of the trace) is ill-conditioned: the sine of an
    angle pi - d is recovered with a relative error ~ eps / d^2 (1e-4 at d = 1e-6), in the
    numpy formulas as much as in the compiled copy, and rounding differences of 1e-16 in
    the matrix move the result by that much. Both paths must still reproduce the composed
    motion to that conditioning, and agree to rounding a little away from pi."""
    rng = np.random.default_rng(1)
    xi = twists(rng, 200, near_pi=True)
    noise = twists(rng, 200, tiny=True)
    T = se3_exp(xi)
    p = T[:, :3, :3] @ ROOT + T[:, :3, 3]
    dR = so3_exp(noise[:, 3:])
    truth = T.copy()
    truth[:, :3, :3] = dR @ T[:, :3, :3]
    truth[:, :3, 3] = (dR @ T[:, :3, 3:])[..., 0] + p - (dR @ p[..., None])[..., 0] + noise[:, :3]
    for compiled in (True, False):
        np.testing.assert_allclose(se3_exp(rm.perturb_root(xi, noise, ROOT, compiled=compiled)), truth,
                                   atol=2e-3)
    np.testing.assert_allclose(rm.root_spread(xi[:50], ROOT, compiled=True),
                               rm.root_spread(xi[:50], ROOT, compiled=False), atol=1e-3)
    away = twists(rng, 200)
    away[:, 3:] *= (np.pi - 1e-2) / np.linalg.norm(away[:, 3:], axis=1, keepdims=True)
    np.testing.assert_allclose(rm.perturb_root(away, noise, ROOT, compiled=True),
                               rm.perturb_root(away, noise, ROOT, compiled=False), atol=1e-9)


def test_root_spread_equals_the_reference_formula():
    """std of the posed root point, RMS of log(R_mean^T R_i) about the SVD chordal mean."""
    rng = np.random.default_rng(2)
    xi = twists(rng, 100) * 0.2
    xi[:, 3:] += [0.0, 0.0, 3.0]                       # about a half turn: wraps in twist coordinates
    T = se3_exp(xi)
    R = T[:, :3, :3]
    p = R @ ROOT + T[:, :3, 3]
    U, _, Vt = np.linalg.svd(R.mean(axis=0))
    Rm = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    rel = so3_log(np.einsum("ji,pjk->pik", Rm, R))
    expected = np.concatenate([p.std(axis=0), np.sqrt((rel**2).mean(axis=0))])
    for compiled in (True, False):
        np.testing.assert_allclose(rm.root_spread(xi, ROOT, compiled=compiled), expected, atol=1e-13)


def test_perturb_root_rotates_about_the_posed_root_point():
    """Delta exp(xi): the posed root point moves by the translation noise only, the rotation
    is the noise rotation composed on the left."""
    rng = np.random.default_rng(3)
    xi = twists(rng, 50) * 0.5
    noise = rng.normal(0.0, 0.1, (50, 6))
    for compiled in (True, False):
        out = se3_exp(rm.perturb_root(xi, noise, ROOT, compiled=compiled))
        T = se3_exp(xi)
        before = T[:, :3, :3] @ ROOT + T[:, :3, 3]
        after = out[:, :3, :3] @ ROOT + out[:, :3, 3]
        np.testing.assert_allclose(after - before, noise[:, :3], atol=1e-12)
        np.testing.assert_allclose(out[:, :3, :3], so3_exp(noise[:, 3:]) @ T[:, :3, :3], atol=1e-12)


def test_interpolation_ends_at_the_start_and_the_end():
    rng = np.random.default_rng(4)
    a, b = twists(rng, 2) * 0.7
    for compiled in (True, False):
        ends = rm.interpolate_root(a, b, np.array([0.0, 1.0]), compiled=compiled)
        np.testing.assert_allclose(se3_exp(ends), se3_exp(np.stack([a, b])), atol=1e-12)
        mid = rm.interpolate_root(a, b, np.array([0.5]), compiled=compiled)[0]
        Ta, Tb = se3_exp(a), se3_exp(b)
        half = se3_exp(0.5 * se3_log(Tb @ np.linalg.inv(Ta)))
        np.testing.assert_allclose(se3_exp(mid), half @ Ta, atol=1e-12)
    np.testing.assert_allclose(rm.predict_root(a, b, 1.0, compiled=True),
                               rm.predict_root(a, b, 1.0, compiled=False), atol=1e-12)


def test_root_mean_compiled_equals_numpy_and_known_means():
    rng = np.random.default_rng(5)
    for _ in range(20):
        xi = rng.normal(0.0, 0.3, (100, 6))
        xi[:, 3:] += rng.normal(0.0, 1.0, 3)
        w = rng.random(100) ** 3
        w /= w.sum()
        np.testing.assert_allclose(rm.root_mean(xi, w, ROOT, compiled=True),
                                   rm.root_mean(xi, w, ROOT, compiled=False), atol=1e-10)
    one = twists(rng, 1)[0] * 0.5
    for compiled in (True, False):
        # identical particles: their own twist
        np.testing.assert_allclose(rm.root_mean(np.tile(one, (7, 1)), np.full(7, 1 / 7), ROOT, compiled),
                                   one, atol=1e-12)
        # two rotations about z through the root point, equal weights: the half-way rotation
        # (chordal mean of +-a about one axis is the identity), the root point stays put
        a = 0.4
        pair = np.zeros((2, 6))
        pair[:, 5] = [a, -a]
        pair[:, :3] = -np.cross(pair[:, 3:], ROOT)                    # rotation about the root point
        mean = rm.root_mean(pair, np.array([0.5, 0.5]), ROOT, compiled)
        np.testing.assert_allclose(mean, np.zeros(6), atol=1e-12)

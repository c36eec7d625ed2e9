import numpy as np
import pytest
from scipy.spatial.distance import cdist
from scipy.special import logsumexp

from mocap.energy.prior import ParzenPrior, PosePrior, joint_limit_energy, logsumexp_rows
from mocap.energy.smoothness import predict_constant_velocity, smoothness_energy
from mocap.energy.train_prior import training_poses


def test_parzen_sigma_is_the_maximum_nearest_neighbour_distance():
    rng = np.random.default_rng(0)
    s = rng.normal(size=(60, 5))
    d = cdist(s, s)
    np.fill_diagonal(d, np.inf)
    prior = ParzenPrior.fit(s, tuple("abcde"))
    assert prior.sigma == pytest.approx(d.min(axis=1).max(), rel=1e-12)


def test_parzen_energy_is_minus_log_of_the_kernel_density():
    rng = np.random.default_rng(1)
    s = rng.normal(size=(30, 3))
    prior = ParzenPrior.fit(s, ("a", "b", "c"))
    x = rng.normal(size=(4, 3))
    sig = prior.sigma
    p = np.exp(-cdist(x, s, "sqeuclidean") / (2 * sig**2)).sum(1) / (np.sqrt(2 * np.pi) * sig * len(s))
    np.testing.assert_allclose(prior.energy(x), -np.log(p), rtol=1e-10)
    far = prior.energy(np.full((1, 3), 1e3))
    assert np.isfinite(far).all() and far[0] > 1e5


def test_joint_limit_energy_is_zero_inside_and_quadratic_outside():
    limits = np.array([[-1.0, 1.0], [0.0, 2.0]])
    inside = np.array([[0.0, 1.0], [-1.0, 2.0], [0.99, 0.01]])
    np.testing.assert_array_equal(joint_limit_energy(inside, limits, 0.1), 0.0)
    for d in (0.1, 0.2, 0.4):
        assert joint_limit_energy(np.array([[1.0 + d, 1.0]]), limits, 0.1)[0] == pytest.approx(d**2 / 0.01)
        assert joint_limit_energy(np.array([[0.0, -d]]), limits, 0.1)[0] == pytest.approx(d**2 / 0.01)


def test_prior_trained_on_training_motions_file_round_trip(body, tmp_path):
    poses = training_poses(body, samples=100)
    assert poses.shape == (100, body.num_dofs - 6)
    prior = ParzenPrior.fit(poses, body.dof_names[6:], source="test")
    back = ParzenPrior.load(prior.save(tmp_path / "p.npz"))
    np.testing.assert_array_equal(back.samples, prior.samples)
    assert back.sigma == prior.sigma and back.dof_names == prior.dof_names
    pp = PosePrior(body.dof_names, body.limits, back)
    chi = body.zero_pose(2).astype(np.float64)
    chi[1, 6:] = poses[3]
    e = pp(chi)
    assert e[1] < e[0]          # a training pose is more probable than the rest pose


def test_missing_or_foreign_prior_file_gives_a_clear_error(body, tmp_path):
    with pytest.raises(FileNotFoundError, match="pose prior file not found"):
        ParzenPrior.load(tmp_path / "none.npz")
    np.savez(tmp_path / "x.npz", samples=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="not a pose prior file"):
        ParzenPrior.load(tmp_path / "x.npz")
    other = ParzenPrior.fit(np.random.default_rng(0).normal(size=(5, 2)), ("spine_rot", "neck_rot"))
    with pytest.raises(ValueError, match="DOFs the body lacks: spine_rot, neck_rot"):
        PosePrior(body.dof_names, body.limits, other)


def test_smoothness_prediction_and_energy():
    a, b = np.zeros(10), np.zeros(10)
    a[:3], b[:3] = [0.0, 1.0, 0.0], [1.0, 1.5, 0.0]          # pure translations
    a[6:], b[6:] = 0.1, 0.3
    pred = predict_constant_velocity([a, b])
    np.testing.assert_allclose(pred[:3], [2.0, 2.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pred[6:], 0.5)
    np.testing.assert_allclose(predict_constant_velocity([b]), b)
    chi = np.stack([pred, pred + 1.0])
    np.testing.assert_allclose(smoothness_energy(chi, pred), [0.0, 10.0])


def test_prediction_of_a_heading_across_pi_continues_the_turn():
    from mocap.body.twists import se3_exp, so3_log

    a, b = np.zeros(6), np.zeros(6)
    a[5], b[5] = np.pi - 0.1, -(np.pi - 0.1)                 # turning by +0.2 rad across pi
    pred = predict_constant_velocity([a, b])
    R = se3_exp(pred)[:3, :3]
    expected = se3_exp(np.r_[0, 0, 0, 0, 0, np.pi + 0.3])[:3, :3]
    np.testing.assert_allclose(R, expected, atol=1e-9)
    assert abs(np.linalg.norm(so3_log(R)) - (np.pi - 0.3)) < 1e-9


def test_logsumexp_rows_is_scipys_logsumexp_bit_for_bit():
    """The prior's log-sum-exp without scipy's dispatch: the same bits as scipy's, ties of the
    maximum included, and scipy's answer for a row with -inf or inf."""
    rng = np.random.default_rng(3)
    for shape in [(25, 3000), (1, 5), (7, 1), (4, 2)]:
        for scale in [1e-3, 1.0, 50.0, 1e4]:
            a = -rng.random(shape) * scale
            a[:, -1] = a.max(axis=1)                  # a tie of the maximum (or a 1-wide row)
            got, ref = logsumexp_rows(a), logsumexp(a, axis=1)
            assert got.dtype == ref.dtype and got.shape == ref.shape
            assert np.array_equal(got, ref), (shape, scale)
    a = np.array([[0.0, -1.0], [-np.inf, -np.inf], [np.inf, 0.0]])
    np.testing.assert_array_equal(logsumexp_rows(a), logsumexp(a, axis=1))
    with pytest.raises(ValueError, match="must be"):
        logsumexp_rows(np.zeros(3))

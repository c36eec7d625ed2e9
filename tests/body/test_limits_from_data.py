"""Joint limits widened from data (:func:`mocap.body.limits_from_data.widened_limits`): the widened
limits contain the data (by the margin), a limit the data do not reach is kept, never narrowed, a
DOF without data (NaN) and the unbounded root are untouched, and a quantile leaves that share out."""

import numpy as np
import pytest

from mocap.body.limits_from_data import widened_limits


def test_widened_limits_contain_the_data_and_never_narrow(body):
    rng = np.random.default_rng(0)
    D = body.num_dofs
    angles = np.full((500, D), np.nan)
    lo, hi = body.limits[:, 0], body.limits[:, 1]
    j_out, j_in = body.dof_index("l_elbow_flex"), body.dof_index("r_knee_flex")
    angles[:, j_out] = rng.uniform(lo[j_out] - 0.4, hi[j_out] - 0.5, 500)        # past the lower limit
    angles[:, j_in] = rng.uniform(lo[j_in] + 0.2, hi[j_in] - 0.2, 500)           # inside
    out = widened_limits(body.limits, angles, margin=0.01)
    assert out[j_out, 0] == pytest.approx(angles[:, j_out].min() - 0.01)
    assert out[j_out, 1] == hi[j_out]                                          # not reached: kept
    assert np.all((angles[:, j_out] >= out[j_out, 0]) & (angles[:, j_out] <= out[j_out, 1]))
    np.testing.assert_array_equal(out[j_in], body.limits[j_in])                 # inside: kept
    others = np.setdiff1d(np.arange(D), [j_out, j_in])
    np.testing.assert_array_equal(out[others], body.limits[others])             # no data, root: kept
    assert np.all(out[:, 0] <= body.limits[:, 0]) and np.all(out[:, 1] >= body.limits[:, 1])


def test_a_quantile_leaves_that_share_of_the_data_out(body):
    j = body.dof_index("l_elbow_flex")
    angles = np.full((1001, body.num_dofs), np.nan)
    angles[:, j] = np.linspace(body.limits[j, 0] - 1.0, body.limits[j, 0], 1001)
    out = widened_limits(body.limits, angles, margin=0.0, quantile=0.1)
    assert np.mean(angles[:, j] < out[j, 0]) == pytest.approx(0.1, abs=2e-3)


@pytest.mark.parametrize("kwargs", [{"quantile": 0.5}, {"margin": -0.1}])
def test_bad_arguments_are_refused(body, kwargs):
    with pytest.raises(ValueError, match="widened_limits"):
        widened_limits(body.limits, np.zeros((3, body.num_dofs)), **kwargs)

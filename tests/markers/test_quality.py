"""Quality flags of a run (mocap/eval/quality.py) and the shape model's bone-length bounds
(mocap/body/bone_lengths.py)."""

from pathlib import Path

import numpy as np
import pytest

from mocap.body import load_body
from mocap.body.bone_lengths import skeleton_length_model
from mocap.eval.quality import lost_runs, quality_flags
from mocap.trackers.base import Estimate

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def body():
    return load_body("paper22")


def test_linearised_bone_spread_matches_sampled_bodies(body):
    model, _ = skeleton_length_model(body)
    alpha = np.random.default_rng(0).standard_normal((400, body.num_shape))
    _, joints = body.rest(alpha)
    lengths = model.lengths(np.asarray(joints, np.float64))              # (400, B)
    np.testing.assert_allclose(lengths.std(axis=0), model.sigma, rtol=0.2)
    np.testing.assert_allclose(lengths.mean(axis=0), model.mean, atol=0.1 * model.sigma.max())


def estimates(n, reproj, views):
    return [Estimate(chi=np.zeros(3), alpha=np.zeros(1),
                     diagnostics={"reprojection_px": reproj, "views_per_landmark": views(f)})
            for f in range(n)]


def test_a_good_run_has_no_flags(body):
    q = quality_flags(body, np.zeros(body.num_shape), estimates(10, 8.0, lambda f: {"a": 4, "b": 3}), 800.0)
    assert q["flags"] == [] and q["bone_length_z_max"] == 0.0


def test_absurd_shape_high_reprojection_and_lost_subject_are_flagged(body):
    alpha = np.zeros(body.num_shape)
    alpha[0] = 8.0                                                       # far outside the model
    lost = lambda f: {"a": 0, "b": 1, "c": 1, "d": 4} if 3 <= f <= 9 else {"a": 4, "b": 4, "c": 4, "d": 2}  # noqa: E731
    q = quality_flags(body, alpha, estimates(12, 101.0, lost), 800.0, extra_flags=["mean shape used"])
    text = " | ".join(q["flags"])
    assert "implausible bone lengths" in text and q["implausible_bones"]
    assert "high reprojection error: median 101.0 px" in text
    assert "lost subject" in text and "frames 3-9" in text
    assert q["flags"][-1] == "mean shape used"


def test_lost_runs_keeps_only_long_runs():
    lost = np.array([0, 1, 1, 0, 1, 1, 1, 1, 1, 0, 1, 1, 1, 1, 1], bool)
    assert lost_runs(lost, 5) == [(4, 8), (10, 14)]

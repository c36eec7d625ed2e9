"""FailureInjection: skipped frames never reach the tracker, a perturbation restarts it from a
perturbed pose, and a tracker that converges back recovers in the number of frames expected."""

import numpy as np
import pytest

from mocap.eval.recovery import recovery_figures
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.failures import FailureInjection, FrameSkip, Perturbation

BIAS = 0.010        # the converging tracker's steady error (m, along x)


class Converging:
    """Halves its distance to the (biased) truth pose each step; remembers what it was given."""

    name = "converging"

    def __init__(self, truth: np.ndarray):
        self.truth, self.seen, self.starts = truth + np.r_[BIAS, np.zeros(len(truth) - 1)], [], []

    def initialize(self, chi, alpha):
        self.chi, self.alpha = np.asarray(chi, float), alpha
        self.starts.append(self.chi.copy())

    def step(self, frame: Frame) -> Estimate:
        self.seen.append(frame.index)
        self.chi = self.truth + 0.5 * (self.chi - self.truth)
        return Estimate(chi=self.chi, alpha=self.alpha)


def run(body, skips=(), perturbations=(), frames=10):
    truth = body.zero_pose(1)[0].astype(float)
    inner = Converging(truth)
    tracker = FailureInjection(inner, body, skips, perturbations, rng=np.random.default_rng(0))
    tracker.initialize(inner.truth, np.zeros(body.num_shape))
    estimates = [tracker.step(Frame(index=f)) for f in range(1, frames)]
    return inner, truth, [Estimate(chi=inner.truth, alpha=None)] + estimates


def test_skipped_frames_never_reach_the_tracker_and_hold_the_last_estimate(body):
    inner, _, est = run(body, skips=[FrameSkip(3, 2)])
    assert inner.seen == [1, 2, 5, 6, 7, 8, 9]
    assert est[3].diagnostics.injection.skipped and est[4].diagnostics.injection.skipped
    assert np.array_equal(est[3].chi, est[2].chi) and np.array_equal(est[4].chi, est[2].chi)
    assert est[5].diagnostics.injection is None


def test_perturbation_restarts_from_a_perturbed_last_estimate(body):
    p = Perturbation(4, degrees=20.0, dofs=3, translation=(0.1, -0.1, 0.0))
    inner, _, est = run(body, perturbations=[p])
    assert len(inner.starts) == 2 and est[4].diagnostics.injection.perturbed
    moved = inner.starts[1] - est[3].chi
    assert np.allclose(moved[:3], [0.1, -0.1, 0.0])
    # three joint angles moved by +-20 deg (less where a limit clipped them), the rest untouched
    assert np.count_nonzero(moved[6:]) <= 3 and np.all(np.abs(moved[6:]) <= np.deg2rad(20) + 1e-12)
    assert np.count_nonzero(moved[3:6]) == 0


def test_converging_tracker_recovers_in_the_expected_frames(body):
    # restart 120 mm off: the error goes 10 (steady) -> 70, 40, 25, 17.5 mm; under 2 x 10 mm after 3 frames
    p = Perturbation(5, degrees=0.0, dofs=0, translation=(0.12, 0.0, 0.0))
    _, truth, est = run(body, perturbations=[p])
    errors = [1000 * abs(e.chi[0] - truth[0]) for e in est]
    assert np.allclose(errors[5:9], [70, 40, 25, 17.5])
    fig = recovery_figures(errors, 5, window=3)
    assert fig["error_before_mm"] == pytest.approx(10) and fig["frames_to_recover"] == 3
    assert fig["recovered_at_frame"] == 8


def test_perturbation_on_a_skipped_frame_is_refused(body):
    with pytest.raises(ValueError, match="skipped"):
        FailureInjection(Converging(np.zeros(body.num_dofs)), body, [FrameSkip(3, 2)], [Perturbation(4)])

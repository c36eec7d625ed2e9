"""The silhouette-only hybrid's start search (``start_search``, HybridTracker.search_start): off, the
start is the self-initialisation's pose bit for bit; on, an arm raised where the silhouettes show it
hanging (vertices outside the masks, observed arm pixels unexplained) is brought back by the
limb-chain searches, and the frame's E_S falls."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of

FAST = {"local": {"iterations": 3}}
ARM = ("l_elbow", "l_wrist")


@pytest.fixture(scope="module")
def seq(body):
    rig = ring_rig(6, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    return make_synthetic(body, rig, motion="walk", frames=1, fps=25, seed=0, images=False)


def raised_arm(body, chi):
    """The pose with the left arm lifted sideways by 1.2 rad and its elbow bent by 1 rad: the arm
    leaves the silhouettes of most views."""
    out = np.array(chi, np.float64)
    out[body.dof_index("l_shoulder_abd")] += 1.2
    out[body.dof_index("l_elbow_flex")] += 1.0
    return np.clip(out, body.limits[:, 0], body.limits[:, 1])


def arm_error_mm(body, alpha, chi, truth) -> float:
    idx = [body.joint_names.index(j) for j in ARM]
    shaped = body.shaped(alpha)
    got, want = shaped.joints(chi[None])[0][idx], shaped.joints(truth[None])[0][idx]
    return 1000 * float(np.linalg.norm(got - want, axis=1).mean())


def test_off_the_start_is_kept_bit_for_bit(body, seq):
    start = raised_arm(body, seq.gt.chi[0])
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(3), **FAST)
    chi, alpha, report = t.refine_initial(frame_of(seq, 0), start, seq.gt.alpha)
    assert report == {} and chi is start and alpha is seq.gt.alpha


def test_the_start_search_brings_a_raised_arm_back(body, seq):
    truth = seq.gt.chi[0]
    start = raised_arm(body, truth)
    before = arm_error_mm(body, seq.gt.alpha, start, truth)
    assert before > 150                                              # the arm is far off
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(3), start_search=True,
                     **FAST)
    chi, alpha, report = t.refine_initial(frame_of(seq, 0), start, seq.gt.alpha)
    np.testing.assert_array_equal(alpha, seq.gt.alpha)               # the shape is not searched
    r = report["start_search"]
    assert r["energy_after"] < r["energy_before"]
    assert "l_shoulder" in r["chains_kept"]
    after = arm_error_mm(body, seq.gt.alpha, chi, truth)
    assert after < 0.3 * before and after < 60, (before, after)

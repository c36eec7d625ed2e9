"""The hybrid's heading repair (``apf.heading_chains``, :mod:`mocap.trackers.heading`): a pose turned
about the vertical through its pelvis moves every joint by that rotation and leaves the pelvis where it
is; a body whose tracked heading is 30 (60) degrees off the truth is turned back by the search (the
step): the local steps from the turned poses and the lowest E_S; off (the default), the repair is the
limb search alone."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.local.misalignment import limb_chains
from mocap.settings import SettingError
from mocap.trackers.heading import flagged_chains, turned_by
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of
from mocap.trackers.tracker_settings import HybridSearchSettings

FAST = {"local": {"iterations": 5}}


@pytest.fixture(scope="module")
def seq(body):
    rig = ring_rig(6, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    return make_synthetic(body, rig, motion="walk", frames=1, fps=25, seed=0, images=False)


def joints_mm(body, alpha, a, b) -> float:
    shaped = body.shaped(alpha)
    ja, jb = shaped.joints(np.stack([a, b]))
    return 1000 * float(np.linalg.norm(ja - jb, axis=1).mean())


def test_a_turn_rotates_every_joint_about_the_vertical_through_the_pelvis(body, seq):
    shaped = body.shaped(seq.gt.alpha)
    chi = seq.gt.chi[0]
    angles = np.deg2rad([-90.0, 30.0, 180.0])
    out = turned_by(shaped.rest_joints[0], chi, angles)
    j0, *jt = shaped.joints(np.vstack([chi[None], out]))
    pelvis = j0[0]
    for a, j in zip(angles, jt, strict=True):
        c, s = np.cos(a), np.sin(a)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        np.testing.assert_allclose(j, (j0 - pelvis) @ R.T + pelvis, atol=1e-6)   # float32 joints
    np.testing.assert_array_equal(out[:, 6:], np.repeat(chi[None, 6:], 3, axis=0))   # angles kept
    back = turned_by(shaped.rest_joints[0], out[1], [-angles[1]])[0]
    np.testing.assert_allclose(back, chi, atol=1e-9)


def test_chains_count_once_whichever_of_their_joints_is_flagged(body):
    chains = limb_chains(body)
    flagged = np.zeros(body.num_joints, bool)
    assert flagged_chains(chains, flagged) == 0
    flagged[[body.joint_names.index(n) for n in ("l_elbow", "l_wrist", "r_knee")]] = True
    assert flagged_chains(chains, flagged) == 2


def test_a_heading_30_degrees_off_is_turned_back(body, seq):
    truth = seq.gt.chi[0]
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(3),
                     apf={"heading_chains": 3}, **FAST)
    t.initialize(truth, seq.gt.alpha)
    start = turned_by(t.shaped.rest_joints[0], truth, [np.deg2rad(30.0)])[0]
    before = joints_mm(body, seq.gt.alpha, start, truth)
    assert before > 60                                               # every limb is off
    chi = t.search_heading(frame_of(seq, 0), start)
    assert t.heading_turns == {0: -30.0}
    after = joints_mm(body, seq.gt.alpha, chi, truth)
    assert after < 20, (before, after)


def test_a_turned_body_is_repaired_in_the_step_only_with_the_heading_search(body, seq):
    """The frame tracked from a history 60 degrees off: the check flags three chains (an arm and both
    legs); with the heading search on, the step turns the body back and its joints come near the
    truth; without it the limb search leaves them more than twice as far."""
    truth = seq.gt.chi[0]
    errors = {}
    for chains in (0, 3):
        t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(3),
                         apf={"heading_chains": chains, "heading_angles": (-60.0, -30.0, 30.0, 60.0)}, **FAST)
        t.initialize(truth, seq.gt.alpha)
        start = turned_by(t.shaped.rest_joints[0], truth, [np.deg2rad(60.0)])[0]
        assert joints_mm(body, seq.gt.alpha, start, truth) > 120
        t.history = [start, start]
        est = t.step(frame_of(seq, 0))
        check = est.diagnostics.misalignment
        assert check.apf_called and check.apf_accepted
        errors[chains] = joints_mm(body, seq.gt.alpha, est.chi, truth)
        assert t.heading_turns == ({0: -60.0} if chains else {})
    assert errors[3] < 30 and errors[0] > 2 * errors[3], errors


@pytest.mark.parametrize("field, value", [("heading_chains", -1), ("heading_angles", ()),
                                          ("heading_angles", (200.0,)), ("heading_angles", (float("nan"),))])
def test_bad_heading_settings_are_refused_naming_the_field(field, value):
    with pytest.raises(SettingError, match=field):
        HybridSearchSettings(**{field: value})


def raised_arm(body, chi):
    """The pose with the left arm lifted sideways by 1.2 rad and its elbow bent by 1 rad."""
    out = np.array(chi, np.float64)
    out[body.dof_index("l_shoulder_abd")] += 1.2
    out[body.dof_index("l_elbow_flex")] += 1.0
    return np.clip(out, body.limits[:, 0], body.limits[:, 1])


@pytest.mark.parametrize("stuck_frames", [1, 2])
def test_a_chain_flagged_stuck_frames_in_a_row_gets_the_wide_search(body, seq, stuck_frames):
    """``apf.stuck_frames`` = N: the chain flagged on this frame (one in a row) is stuck for N = 1 (the
    search has ``stuck_particles`` x layers evaluations, its library draws bring the arm back), not
    for N = 2 (the usual 25 particles)."""
    truth = seq.gt.chi[0]
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(3),
                     apf={"stuck_frames": stuck_frames, "stuck_particles": 60}, **FAST)
    start = raised_arm(body, truth)
    t.initialize(start, seq.gt.alpha)
    est = t.step(frame_of(seq, 0))
    check = est.diagnostics.misalignment
    assert check.apf_called and "l_elbow" in check.limbs
    stuck = stuck_frames == 1
    assert t.stuck_searches == ([0] if stuck else [])
    assert est.diagnostics.anneal.evaluations == (60 if stuck else 25) * 10
    assert t.streak[[body.joint_names[r] for r, _ in t.chains].index("l_shoulder")] == 1
    if stuck:
        before, after = (joints_mm(body, seq.gt.alpha, c, truth) for c in (start, est.chi))
        assert after < 0.5 * before, (before, after)


def test_stuck_settings_out_of_range_are_refused():
    for field, value in (("stuck_frames", -1), ("stuck_particles", 1)):
        with pytest.raises(SettingError, match=field):
            HybridSearchSettings(**{field: value})

"""The hybrid's patrol limited to the arms (``apf.patrol_chains``): a forearm held wrong in front of
the torso stays inside every silhouette, so the misalignment check does not flag it and the repair
never runs; the arms' patrol searches the arm all the same and brings it back, the patrol over all
chains searches a leg on that frame and leaves it; a correct arm is left as it is (its search does
not lower E_S by the margin); bad settings are refused naming the field."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.data.synthetic import generate_sequence
from mocap.local.misalignment import limb_chains
from mocap.settings import SettingError
from mocap.trackers.hybrid_tracker import patrolled_chains
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of
from mocap.trackers.tracker_settings import HybridSearchSettings

#: the patrol as measured on dev (docs/results/surface.md); no local iterations, so that only the
#: search moves the pose
PATROL = {"patrol": 1, "patrol_agreement": 0.75, "patrol_margin": 0.01, "refine_iterations": 0}


@pytest.fixture(scope="module")
def truth_seq(body):
    """Four frames of one pose: a walking pose with the right forearm bent across the belly
    (shoulder flexed 0.4 rad, rotated 0.9 rad inwards, elbow flexed 1.7 rad), 6 views."""
    rig = ring_rig(6, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    walk = make_synthetic(body, rig, motion="walk", frames=1, fps=25, seed=0, images=False)
    truth = walk.gt.chi[0].copy()
    for name, value in (("r_shoulder_flex", 0.4), ("r_shoulder_rot", 0.9), ("r_elbow_flex", 1.7)):
        truth[body.dof_index(name)] = value
    seq = generate_sequence(body, rig, np.repeat(truth[None], 4, axis=0), walk.gt.alpha,
                            masks=True, images=False)
    return truth, seq


def wrist_mm(body, alpha, chi, truth) -> float:
    j = body.shaped(alpha).joints(np.stack([chi, truth]))
    w = body.joint_names.index("r_wrist")
    return 1e3 * float(np.linalg.norm(j[0, w] - j[1, w]))


def step(body, seq, start, chains):
    """Frame 3 tracked from a history of ``start`` alone (the prediction is ``start``)."""
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                     local={"iterations": 0}, apf={**PATROL, "patrol_chains": chains})
    t.initialize(start, seq.gt.alpha)
    return t.step(frame_of(seq, 3))


def test_the_arms_patrol_brings_back_a_forearm_the_check_does_not_see(body, truth_seq):
    """The right forearm pointing forward (shoulder not rotated) where the truth holds it across the
    belly: 133 mm at the wrist, the check flags nothing. On frame 3 the arms' patrol (arms in turn:
    left, right, left, right) searches the right arm's DOFs and keeps the search (E_S falls in
    enough views): the wrist within a quarter of its error. The patrol over all four chains searches
    the right leg on frame 3 (chains in turn: left arm, right arm, left leg, right leg) and leaves the
    arm where it was."""
    truth, seq = truth_seq
    wrong = truth.copy()
    wrong[body.dof_index("r_shoulder_rot")] = 0.0
    before = wrist_mm(body, seq.gt.alpha, wrong, truth)
    assert before > 100
    arms = step(body, seq, wrong, "arms")
    m = arms.diagnostics.misalignment
    assert m.limbs == () and m.patrol is True and m.apf_accepted is True        # not flagged, searched
    assert set(m.free_dofs) == {"r_shoulder_flex", "r_shoulder_abd", "r_shoulder_rot", "r_elbow_flex"}
    after = wrist_mm(body, seq.gt.alpha, arms.chi, truth)
    assert after < 0.25 * before, (before, after)
    every = step(body, seq, wrong, "all")
    m = every.diagnostics.misalignment
    assert m.limbs == () and m.patrol is True
    assert set(m.free_dofs) == {"r_hip_flex", "r_hip_abd", "r_hip_rot", "r_knee_flex"}
    assert wrist_mm(body, seq.gt.alpha, every.chi, truth) == pytest.approx(before, abs=1e-3)


def test_a_correct_arm_is_left_unchanged_by_the_patrol(body, truth_seq):
    """From the truth, the arms' patrol searches the right arm, its pose does not lower E_S by the
    margin, and the frame's pose is the truth to the bit (no local iterations)."""
    truth, seq = truth_seq
    e = step(body, seq, truth, "arms")
    m = e.diagnostics.misalignment
    assert m.patrol is True and m.apf_called is True and m.apf_accepted is False
    np.testing.assert_array_equal(e.chi, truth)


def test_the_patrolled_chains_are_those_named(body):
    """all: the four limb chains in their order; arms: those rooted at the shoulders; legs: at the
    hips."""
    chains = limb_chains(body)
    roots = {w: [body.joint_names[r] for r, _ in patrolled_chains(body, chains, w)]
             for w in ("all", "arms", "legs")}
    assert roots == {"all": ["l_shoulder", "r_shoulder", "l_hip", "r_hip"],
                     "arms": ["l_shoulder", "r_shoulder"], "legs": ["l_hip", "r_hip"]}


def test_bad_patrol_chains_are_refused_naming_the_field(body):
    with pytest.raises(SettingError, match=r"patrol_chains = 'torso' is out of range"):
        HybridSearchSettings(patrol_chains="torso")
    with pytest.raises(ValueError, match=r"apf.patrol_chains = 'torso' is out of range"):
        make_tracker("hybrid", body=body, rig=ring_rig(2, 3.5, 1.5, 40, 30, fov_deg=45),
                     rng=np.random.default_rng(0), apf={"patrol_chains": "torso"})
    with pytest.raises(ValueError, match=r"apf.patrol_chains: 'arms' names no limb chain of body"):
        patrolled_chains(body, [c for c in limb_chains(body) if "hip" in body.joint_names[c[0]]], "arms")

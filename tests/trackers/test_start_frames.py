"""The silhouette-only hybrid's start chosen over several frames (``start_frames``,
:mod:`mocap.trackers.start_frames`): the hypotheses are the start's exact left/right exchanges and its
180-degree turn; a body standing with straight limbs casts nearly the same outlines facing either way,
so one frame's silhouette energy hardly tells the start turned round from the truth, but once the knees
and elbows bend (they bend one way only) the turned body cannot follow: tracked over the frames, the
truth has the lower summed energy, the tracker starts again from it and revises the first frames;
with the setting off the wrong start is tracked on."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.synthetic import generate_sequence
from mocap.settings import SettingError
from mocap.trackers.contract import initial_estimate_of
from mocap.trackers.heading import turned_by
from mocap.trackers.initialization import mirror_map
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, run_frames
from mocap.trackers.start_frames import chain_pairs, chosen_hypothesis, start_hypotheses, swapped
from mocap.trackers.tracker_settings import StartOverFrames

FAST = {"local": {"iterations": 8}}
FRAMES = 6


def dof(body, name):
    return body.dof_index(name)


@pytest.fixture(scope="module")
def seq(body):
    """Standing, arms a little out, then knees, hips and elbows bend over the frames (a squat)."""
    t = np.linspace(0.0, 1.0, FRAMES)
    chi = np.zeros((FRAMES, body.num_dofs))
    for side in "lr":
        chi[:, dof(body, f"{side}_shoulder_abd")] = 0.35
        chi[:, dof(body, f"{side}_elbow_flex")] = 1.3 * t
        chi[:, dof(body, f"{side}_hip_flex")] = 0.7 * t
        chi[:, dof(body, f"{side}_knee_flex")] = 1.2 * t
    rig = ring_rig(6, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    return generate_sequence(body, rig, chi, np.zeros(body.num_shape), fps=25, seed=0)


def joints_mm(body, alpha, a, b) -> float:
    ja, jb = body.shaped(alpha).joints(np.stack([a, b]))
    return 1000 * float(np.linalg.norm(ja - jb, axis=1).mean())


def test_the_arms_and_legs_pairs_are_found_and_a_swap_exchanges_only_their_angles(body):
    pairs = dict(chain_pairs(body))
    assert sorted(pairs) == ["hip", "shoulder"]
    arms = pairs["shoulder"]
    assert {body.dof_names[i] for i in np.flatnonzero(arms)} == {
        f"{s}_{n}" for s in "lr" for n in ("shoulder_flex", "shoulder_abd", "shoulder_rot", "elbow_flex")}
    rng = np.random.default_rng(0)
    chi = np.r_[rng.normal(0, 0.3, 6), 0.3 * rng.uniform(body.limits[6:, 0], body.limits[6:, 1])]
    perm, sign = mirror_map(body)
    out = swapped(chi, arms, perm, sign, body.limits)
    np.testing.assert_array_equal(out[~arms], chi[~arms])                       # legs, root kept
    assert out[dof(body, "l_elbow_flex")] == chi[dof(body, "r_elbow_flex")]
    np.testing.assert_allclose(swapped(out, arms, perm, sign, body.limits), chi)  # twice: itself


def test_the_hypotheses_are_the_start_its_swaps_and_its_turns(body, seq):
    shaped = body.shaped(seq.gt.alpha)
    chi = seq.gt.chi[2]
    poses, names = start_hypotheses(body, shaped.rest_joints[0], chi)
    assert names == ["start", "swap_shoulder", "swap_hip", "swap_all", "turned", "turned_swap_all"]
    np.testing.assert_array_equal(poses[0], chi)
    perm, sign = mirror_map(body)
    np.testing.assert_allclose(poses[3, 6:], sign * chi[6:][perm])
    turn = turned_by(shaped.rest_joints[0], chi, [np.pi])[0]
    np.testing.assert_allclose(poses[4], turn)
    np.testing.assert_allclose(poses[5, :6], turn[:6])
    np.testing.assert_allclose(poses[5, 6:], poses[3, 6:])


def test_another_hypothesis_is_kept_only_where_it_is_lower_by_the_margin():
    assert chosen_hypothesis(np.array([1.0, 0.99, 1.2])) == 1
    assert chosen_hypothesis(np.array([1.0, 0.99, 1.2]), margin=0.05) == 0
    assert chosen_hypothesis(np.array([1.0, 0.9, 0.8]), margin=0.05) == 2
    assert chosen_hypothesis(np.array([1.0, 1.0])) == 0                      # a tie keeps the start


def test_bad_settings_are_refused_naming_the_field():
    with pytest.raises(SettingError, match="frames"):
        StartOverFrames(frames=-1)
    with pytest.raises(SettingError, match="margin"):
        StartOverFrames(margin=1.0)


def run(body, seq, frames: int):
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                     start_frames={"frames": frames}, **FAST)
    truth = seq.gt.chi[0]
    wrong = turned_by(body.shaped(seq.gt.alpha).rest_joints[0], truth, [np.pi])[0]
    result = run_frames(t, seq, {0: initial_estimate_of(wrong, seq.gt.alpha)})
    return t, np.stack([e.chi for e in result.estimates]), wrong


def test_a_start_turned_round_is_told_from_the_truth_over_frames_not_on_one(body, seq):
    truth = seq.gt.chi
    t, chis, wrong = run(body, seq, FRAMES - 1)
    # one frame's silhouettes hardly tell the turned body from the truth
    t.initialize(truth[0], seq.gt.alpha)
    e0 = t.sil.per_view(np.stack([truth[0], wrong]), t_target(t, seq, 0))[:, t_valid(t, seq, 0)].mean(axis=1)
    assert abs(e0[1] - e0[0]) < 0.25 * e0[0], e0
    choice = t.start_choice
    assert choice["chosen"] == "turned", choice
    total = dict(zip(choice["hypotheses"], choice["energy"], strict=True))
    assert total["turned"] < 0.7 * total["start"], total          # the motion tells them apart
    assert joints_mm(body, seq.gt.alpha, chis[0], truth[0]) < 25           # the revised frame 0
    assert joints_mm(body, seq.gt.alpha, chis[-1], truth[-1]) < 30
    # off: the turned start is tracked on and stays far
    _, off, _ = run(body, seq, 0)
    assert joints_mm(body, seq.gt.alpha, off[-1], truth[-1]) > 100


def t_target(t, seq, f):
    from mocap.energy.silhouette import silhouette_target

    return silhouette_target(frame_of(seq, f).masks, t.scale, view_names=tuple(seq.rig.names))


def t_valid(t, seq, f):
    return t_target(t, seq, f).valid

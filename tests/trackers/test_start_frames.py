"""The silhouette-only hybrid's start chosen over several frames (``start_frames``,
:mod:`mocap.trackers.start_frames`): the hypotheses are the start's exact left/right exchanges and its
180-degree turns; a start with the arms exchanged is restarted from the truth and the first frames
revised (off: the start is kept); a toy whose every frame is ambiguous in sign and whose wrong sign
meets a limit as the motion goes on is a tie on one frame and told apart over frames."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.synthetic import generate_sequence
from mocap.settings import SettingError
from mocap.trackers.contract import initial_estimate_of
from mocap.trackers.heading import turned_by
from mocap.trackers.initialization import mirror_map
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import run_frames
from mocap.trackers.start_frames import (
    chain_pairs,
    chosen_hypothesis,
    start_hypotheses,
    swapped,
    track_hypotheses,
)
from mocap.trackers.tracker_settings import StartOverFrames

FAST = {"local": {"iterations": 8}}
FRAMES = 6


def dof(body, name):
    return body.dof_index(name)


@pytest.fixture(scope="module")
def seq(body):
    """Both arms hang with different twists about the upper arm (left 1.2 rad, right -0.3), then the
    elbows, a little bent at the start, bend further over the frames."""
    t = np.linspace(0.0, 1.0, FRAMES)
    chi = np.zeros((FRAMES, body.num_dofs))
    chi[:, dof(body, "l_shoulder_rot")] = 1.2
    chi[:, dof(body, "r_shoulder_rot")] = -0.3
    for side in "lr":
        chi[:, dof(body, f"{side}_elbow_flex")] = 0.5 + 0.6 * t
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
    """The hybrid started at the truth's frame 0 with the arms exchanged."""
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                     start_frames={"frames": frames, "restarts": 0}, **FAST)
    truth = seq.gt.chi[0]
    perm, sign = mirror_map(body)
    wrong = swapped(truth, dict(chain_pairs(body))["shoulder"], perm, sign, body.limits)
    t.initializer()                         # a self-initialised run (whose start is given here)
    result = run_frames(t, seq, {0: initial_estimate_of(wrong, seq.gt.alpha)})
    return t, np.stack([e.chi for e in result.estimates]), wrong


def test_a_start_with_the_arms_exchanged_is_restarted_from_the_truth(body, seq):
    """The arms exchanged at the start: tracked over the frames, the exchanged hypothesis (the truth)
    has the lowest summed E_S, the tracker starts again from it and the revised frame 0 lies on the
    truth; off, the run keeps the wrong start's frame 0."""
    truth = seq.gt.chi
    t, chis, wrong = run(body, seq, FRAMES - 1)
    choice = t.start_choice
    assert choice["chosen"] == "swap_shoulder", choice
    total = dict(zip(choice["hypotheses"], choice["energy"], strict=True))
    assert total["swap_shoulder"] < 0.8 * total["start"], total
    assert t.revised and sorted(t.revised) == list(range(FRAMES))
    reported = [e.diagnostics.start_choice for e in t.final_tracks({0: t.revised})[0].values()]
    assert reported[-1] == choice and not any(reported[:-1])      # on the frame it was chosen
    from mocap.eval.run_metrics import run_metrics

    metrics = run_metrics(body, seq, list(t.revised.values()), [0.0] * FRAMES, oracle={"enabled": False})
    assert metrics["start_choice"]["chosen"] == "swap_shoulder"
    before, after = (joints_mm(body, seq.gt.alpha, c, truth[0]) for c in (wrong, chis[0]))
    assert before > 15
    assert after < 0.3 * before
    _, off, _ = run(body, seq, 0)
    np.testing.assert_array_equal(off[0], wrong)


def test_a_run_from_a_given_pose_is_not_chosen_over_frames(body, seq):
    """Started from a given pose (ground truth plus noise: the tracker's initializer never asked for),
    the start is the run's, with the setting on, and its frames are recorded as they are tracked."""
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                     start_frames={"frames": 2, "restarts": 0}, **FAST)
    perm, sign = mirror_map(body)
    wrong = swapped(seq.gt.chi[0], dict(chain_pairs(body))["shoulder"], perm, sign, body.limits)
    result = run_frames(t, seq, {0: initial_estimate_of(wrong, seq.gt.alpha)}, frames=3)
    assert t.start_choice is None and not t.revised
    assert not t.revises_tracks                 # recorded as it goes
    t.initializer()                             # asked for its own start: its first frames may change
    assert t.revises_tracks
    np.testing.assert_array_equal(result.estimates[0].chi, wrong)


def test_a_start_one_frame_cannot_tell_is_told_over_frames():
    """A toy pose (root at rest, one angle p) whose every frame's energy (|p| - x_f)^2 cannot tell p
    from -p, observed at x_f = 1 + 0.3 f; its step finds the nearest minimum but p >= -1.2 (a joint
    limit). Started at the wrong sign, one frame is a tie (the start kept); over frames the wrong sign
    cannot follow past the limit and the other sign (the truth) has the lower sum."""
    x = 1.0 + 0.3 * np.arange(6)

    def step(frame, predicted):
        out = np.array(predicted, np.float64)
        out[6] = max(np.sign(out[6]) * x[frame], -1.2)
        return out

    def energy(frame, poses):
        return (np.abs(poses[:, 6]) - x[frame]) ** 2

    starts = np.zeros((2, 7))
    starts[:, 6] = [-1.0, 1.0]
    found = track_hypotheses(starts, list(range(6)), step, energy)
    assert chosen_hypothesis(found.energy[:, :1].sum(axis=1)) == 0        # one frame: a tie, the start
    assert chosen_hypothesis(found.total) == 1                              # over frames: the truth
    np.testing.assert_allclose(found.poses[1, :, 6], x)
    np.testing.assert_allclose(found.total[0], np.sum((np.minimum(x, 1.2) - x) ** 2))   # held at -1.2


def test_restarts_are_other_random_states_cached_and_leave_the_trackers_draws(body, seq, tmp_path,
                                                                             monkeypatch):
    """``restarts`` = 2: two more starts, each from a generator seeded off a copy of the start's (the
    initialiser replaced by a draw from the generator it is given): different from each other, the same
    on a second call (served from the cache folder given to the initializer, not computed again), and
    the tracker's own generator where it was."""
    from mocap.trackers import initialization
    from mocap.trackers.run import frame_of

    calls = []

    def compute(body_, rig, masks, rng, settings, progress=None, library=None):
        calls.append(1)
        return rng.normal(size=body_.num_dofs), np.zeros(body_.num_shape), {}

    monkeypatch.setattr(initialization, "initialize_from_silhouettes", compute)
    t = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(5),
                     start_frames={"frames": 3, "restarts": 2})
    t.initializer(tmp_path)
    state = dict(t.init_rng.bit_generator.state)
    first = t.restarts(frame_of(seq, 0))
    again = t.restarts(frame_of(seq, 0))
    assert len(first) == 2 and len(calls) == 2 and len(list(tmp_path.glob("*.npz"))) == 2
    assert not np.allclose(first[0][0], first[1][0])
    for (a, _), (b, _) in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert t.init_rng.bit_generator.state == state

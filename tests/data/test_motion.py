import numpy as np
import pytest

from mocap.data.motion import ACTIONS, generate_motion, load_motion, save_motion


@pytest.mark.parametrize("action", ACTIONS)
def test_motions_are_smooth_and_within_joint_limits(body, body_full, action):
    for b in (body, body_full):
        chi = generate_motion(b, action, frames=120, fps=25, seed=3).astype(np.float64)
        lo, hi = b.limits[6:, 0], b.limits[6:, 1]
        assert np.all(chi[:, 6:] >= lo) and np.all(chi[:, 6:] <= hi)
        joints = b.shaped().joints(chi)
        vel = np.diff(joints, axis=0) * 25.0                       # m/s
        acc = np.diff(vel, axis=0) * 25.0                          # m/s^2
        assert np.abs(vel).max() < 10.0                            # no jumps
        assert np.abs(acc).max() < 300.0                           # no kinks
        assert joints[..., 2].min() > -0.05                        # nothing far below the floor


def test_walking_moves_through_the_volume_and_boxing_stays(body):
    walk = body.shaped().joints(generate_motion(body, "walk", 100, 25, seed=0))
    box = body.shaped().joints(generate_motion(body, "box", 100, 25, seed=0))
    assert np.ptp(walk[:, 0, :2], axis=0).max() > 1.0
    assert np.ptp(box[:, 0, :2], axis=0).max() < 0.05
    assert np.linalg.norm(walk[:, 0, :2], axis=1).max() < 1.2      # stays within the volume


def test_same_seed_same_motion_and_splits_are_disjoint(body):
    a = generate_motion(body, "walk", 50, seed=4)
    np.testing.assert_array_equal(a, generate_motion(body, "walk", 50, seed=4))
    assert not np.allclose(a, generate_motion(body, "walk", 50, seed=5))
    train = [generate_motion(body, "walk", 50, seed=s, split="train") for s in range(5)]
    test = [generate_motion(body, "walk", 50, seed=s, split="test") for s in range(5)]
    for tr in train:
        for te in test:
            assert not np.allclose(tr, te)


def test_motion_file_round_trip_and_errors(body, body_full, tmp_path):
    chi = generate_motion(body, "jog", 20, seed=1)
    path = save_motion(tmp_path / "m.npz", body, chi, fps=30)
    back, fps = load_motion(path, body)
    np.testing.assert_array_equal(back, chi)
    assert fps == 30
    # a paper22 file drives the fuller body (its extra DOFs stay 0)
    full, _ = load_motion(path, body_full)
    assert np.allclose(full[:, body_full.dof_index("l_knee_flex")], chi[:, body.dof_index("l_knee_flex")])
    csv = tmp_path / "m.csv"
    csv.write_text("# fps: 50\nl_knee_flex,r_knee_flex\n0.1,0.2\n0.3,0.4\n")
    c, fps = load_motion(csv, body)
    assert fps == 50 and c[1, body.dof_index("r_knee_flex")] == pytest.approx(0.4)
    csv.write_text("l_knee_flex,spine_rot\n0.1,0.2\n")
    with pytest.raises(ValueError, match="unknown to body 'paper22': spine_rot"):
        load_motion(csv, body)
    with pytest.raises(FileNotFoundError, match="motion file not found"):
        load_motion(tmp_path / "nope.npz", body)
    with pytest.raises(ValueError, match="unknown action 'dance'"):
        generate_motion(body, "dance", 10)

"""A tracker's own joint limits (``tracker.joint_limits``, :mod:`mocap.trackers.joint_limits`): a
file's limits are the tracker body's (degrees to radians, the DOFs it does not name the body's),
the body itself, its silhouette start and the default ('') untouched; the limits shipped as
``widened`` contain the body's (never narrower) and open the elbows as far as the training motion
goes; bad files are refused with one line naming the file and the entry."""

import json

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.trackers.joint_limits import WIDENED, limits_path, read_limits, tracker_body
from mocap.trackers.presets import make_tracker


def _write(tmp_path, table) -> str:
    path = tmp_path / "limits.json"
    path.write_text(json.dumps(table))
    return str(path)


def test_a_files_limits_are_the_tracker_bodys_and_the_body_is_untouched(body, tmp_path):
    before = body.limits.copy()
    path = _write(tmp_path, {"l_elbow_flex": [-45.0, 150.0], "r_knee_flex": [-12.5, 140.0]})
    own = tracker_body(body, path)
    j, k = body.dof_index("l_elbow_flex"), body.dof_index("r_knee_flex")
    np.testing.assert_allclose(own.limits[j], [-np.pi / 4, np.deg2rad(150.0)], rtol=1e-12)
    np.testing.assert_allclose(own.limits[k], np.deg2rad([-12.5, 140.0]), rtol=1e-12)
    others = np.setdiff1d(np.arange(body.num_dofs), [j, k])
    np.testing.assert_array_equal(own.limits[others], before[others])
    np.testing.assert_array_equal(body.limits, before)
    assert own.faces is body.faces and own.dof_names == body.dof_names
    assert tracker_body(body, "") is body


def test_the_shipped_widened_limits_contain_the_bodys_and_open_the_elbows(body):
    assert limits_path(body.name, WIDENED).is_file()
    wide = read_limits(body, WIDENED)
    assert np.all(wide[:, 0] <= body.limits[:, 0]) and np.all(wide[:, 1] >= body.limits[:, 1])
    for name in ("l_elbow_flex", "r_elbow_flex"):            # the training motion takes them to -43 / -45 deg
        j = body.dof_index(name)
        assert np.rad2deg(wide[j, 0]) < -40.0 < np.rad2deg(body.limits[j, 0])


def test_the_hybrid_tracks_within_its_own_limits_and_starts_on_the_bodys(body, tmp_path):
    rig = ring_rig(4, 3.5, 1.5, 64, 48, fov_deg=45, look_at=(0, 0, 0.9))
    path = _write(tmp_path, {"l_elbow_flex": [-60.0, 150.0]})
    t = make_tracker("hybrid_kp", body=body, rig=rig, rng=np.random.default_rng(0), joint_limits=path)
    j = body.dof_index("l_elbow_flex")
    assert np.rad2deg(t.body.limits[j, 0]) == pytest.approx(-60.0)
    assert t.start_body is body and body.limits[j, 0] > np.deg2rad(-60.0)
    assert t.initializer().start.start.body is body              # the silhouette start: the body's limits
    own = make_tracker("hybrid_kp", body=body, rig=rig, rng=np.random.default_rng(0), joint_limits="")
    assert own.body is body and own.start_body is body
    preset = make_tracker("hybrid_kp", body=body, rig=rig, rng=np.random.default_rng(0))   # chosen on dev
    np.testing.assert_array_equal(preset.body.limits, read_limits(body, WIDENED))
    assert make_tracker("hybrid", body=body, rig=rig, rng=np.random.default_rng(0)).body is body


@pytest.mark.parametrize("table, match", [
    ({"l_elbow": [-10.0, 150.0]}, "'l_elbow' is not a joint DOF"),
    ({"tx": [-1.0, 1.0]}, "'tx' is not a joint DOF"),
    ({"l_elbow_flex": [150.0, -10.0]}, "l_elbow_flex = \\[150.0, -10.0\\]"),
    ({"l_elbow_flex": [-10.0]}, "l_elbow_flex = \\[-10.0\\]"),
    ({"l_elbow_flex": [None, 10.0]}, "expected \\[lower, upper\\] finite degrees"),
    ([1, 2], "holds list"),
])
def test_bad_limits_files_are_refused_naming_file_and_entry(body, tmp_path, table, match):
    path = _write(tmp_path, table)
    with pytest.raises(ValueError, match=match) as e:
        tracker_body(body, path)
    assert path in str(e.value) and "\n" not in str(e.value)


def test_a_missing_limits_file_is_refused_before_the_tracker_is_built(body, tmp_path):
    rig = ring_rig(4, 3.5, 1.5, 64, 48, fov_deg=45, look_at=(0, 0, 0.9))
    with pytest.raises(ValueError, match="joint_limits: no limits file .*nowhere.json"):
        make_tracker("hybrid_kp", body=body, rig=rig, rng=np.random.default_rng(0),
                     joint_limits=str(tmp_path / "nowhere.json"))

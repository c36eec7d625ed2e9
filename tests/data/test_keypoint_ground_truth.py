"""Ground truth for keypoint recordings (issue 26): a gt.npz in a Pose2Sim folder is scored (per
person, with the best assignment), data.gt=PATH names one, a permuted person order scores the
same, metrics.json records the resolved layout and person mode; ``mocap convert`` turns the
folder into a sequence folder keeping the per-view person grouping, and ``mocap
gt-from-joints`` works on the result. Data: two synthetic people 1.5 m apart, 3 frames, 4
views (tests/data/keypoint_folders.py)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from mocap.data.openpose import load_openpose_sequence
from mocap.data.sequence_io import load_sequence
from mocap_cli.main import main
from tests.data.keypoint_folders import known_people, write_gt, write_pose2sim

FRAMES = 3
#: marker_apf with a small start-up (~2 s): the synthetic keypoints are exact
FAST = ["tracker=marker_apf", "data=pose2sim_demo", "data.fps=25", "data.person=all", "init.mode=tracker",
        "recording.enabled=false", "tracker.init.particles=40", "tracker.init.passes=1",
        "tracker.init.layers=4", "tracker.particles=20", "tracker.layers=2"]


@pytest.fixture(scope="module")
def two_people(tmp_path_factory, body):
    """(Pose2Sim folder with gt.npz of alice and bob, joints (F, 2, J, 3), single-person gt)."""
    rig, joints, keypoints, gt = known_people(body, FRAMES)
    root = tmp_path_factory.mktemp("rec") / "rec"
    # the detector lists the people in another order in some files: identities are per file
    write_pose2sim(root, rig, keypoints, order=lambda f, c: [1, 0] if (f + c) % 2 else [0, 1])
    write_gt(root / "gt.npz", gt, joints, ["alice", "bob"])
    return root, joints, gt


@pytest.fixture(scope="module")
def tracked(two_people, tmp_path_factory):
    root, _, _ = two_people
    run = tmp_path_factory.mktemp("run")
    assert main(["track", *FAST, f"data.path={root}", f"hydra.run.dir={run}"]) == 0
    return run, json.loads((run / "metrics.json").read_text())


def test_a_gt_npz_in_a_pose2sim_folder_is_scored_per_person(tracked, two_people):
    _, m = tracked
    assert m["ground_truth"] == {"file": str(two_people[0] / "gt.npz"), "people": ["alice", "bob"],
                                 "skeleton": "mocap"}
    assert m["people_in_ground_truth"] == 2 and m["people_tracked"] == 1     # one track: one person
    (name,) = [n for n, p in m["people"].items() if p["track"] == 0]
    person = m["people"][name]
    assert person["mpjpe_mm"] < 30 and person["pcp"] == 1.0 and person["coverage"] == 1.0
    assert person["identity_switches"] == 0 and m["tracks"]["0"]["track_jumps"] == 0
    assert m["mpjpe_mm"] == person["mpjpe_mm"]
    other = m["people"][{"alice": "bob", "bob": "alice"}[name]]
    assert other["track"] is None and other["coverage"] == 0.0
    # the keypoint metrics are there too, and the resolved layout and person mode
    assert m["keypoints"] == {"layout": "BODY_25B", "layout_setting": "auto", "person": "all"}
    assert m["config"]["data"]["layout"] == "auto" and m["reprojection_median_px"] < 5


def test_a_permuted_person_order_scores_the_same(tracked, two_people, body, tmp_path):
    from mocap.eval.run_metrics import accuracy_metrics
    from mocap.export.motion import load_motion

    run, m = tracked
    root, joints, gt = two_people
    write_gt(tmp_path / "swapped.npz", gt, joints[:, ::-1], ["bob", "alice"])
    seq = load_openpose_sequence(root, layout="auto", person="all", gt=tmp_path / "swapped.npz")
    assert seq.gt.person_names == ("bob", "alice")
    motion = load_motion(run)
    got = accuracy_metrics(body, seq, motion.chi, motion.alpha)
    assert got["people"] == m["people"]
    assert got["mpjpe_mm"] == m["mpjpe_mm"] and got["pcp"] == m["pcp"]


def test_data_gt_names_a_ground_truth_file(two_people, tmp_path, body):
    root, joints, gt = two_people
    bare = tmp_path / "bare"
    shutil.copytree(root, bare)
    (bare / "gt.npz").unlink()
    assert load_openpose_sequence(bare, layout="auto").gt is None
    write_gt(tmp_path / "alice.npz", gt, joints[:, :1])               # one person, no person axis
    seq = load_openpose_sequence(bare, layout="auto", gt=tmp_path / "alice.npz")
    assert seq.gt.person_names == () and seq.gt.joints.shape == (FRAMES, len(gt.joint_names), 3)
    np.testing.assert_allclose(seq.gt.joints, joints[:, 0])
    assert seq.meta["gt"] == str(tmp_path / "alice.npz")
    # frames=N keeps the first N ground-truth frames
    assert load_openpose_sequence(root, layout="auto", frames=2).gt.joints.shape[0] == 2


def test_convert_keeps_the_person_grouping_and_gt_from_joints_works_on_it(two_people, tmp_path, capsys):
    root, joints, gt = two_people
    out = tmp_path / "seq"
    assert main(["convert", str(root), str(out), "--fps", "25"]) == 0
    assert "wrote" in capsys.readouterr().out
    seq = load_sequence(out)
    src = load_openpose_sequence(root, layout="auto", person="all")
    for key in ("frame", "view", "label", "person"):
        np.testing.assert_array_equal(getattr(seq.detections, key), getattr(src.detections, key))
    np.testing.assert_allclose(seq.detections.xy, src.detections.xy)
    assert set(seq.detections.person) == {0, 1}
    assert seq.meta["layout"] == "BODY_25B" and seq.meta["person"] == "all" and seq.fps == 25
    assert seq.gt.person_names == ("alice", "bob")
    np.testing.assert_allclose(seq.gt.joints, joints)
    # gt-from-joints on the converted folder (one person's joints, by name)
    jdir = tmp_path / "joints"
    jdir.mkdir()
    np.savez(jdir / "joints.npz", joint_names=np.array(gt.joint_names), joints=joints[:, 1])
    assert main(["gt-from-joints", str(jdir), str(out), "--skeleton", "none", "--overwrite"]) == 0
    again = load_sequence(out)
    assert again.gt.person_names == () and np.allclose(again.gt.joints, joints[:, 1])
    # data=folder with data.gt=PATH uses that file instead of the folder's
    write_gt(tmp_path / "both.npz", gt, joints, ["alice", "bob"])
    assert load_sequence(out, gt=tmp_path / "both.npz").gt.person_names == ("alice", "bob")


def test_a_gt_npz_not_listed_in_sequence_json_is_used(two_people, tmp_path):
    root, joints, gt = two_people
    out = tmp_path / "seq"
    assert main(["convert", "--fps", "30", str(root), str(out), "--gt", str(root / "gt.npz")]) == 0
    info = json.loads((out / "sequence.json").read_text())
    info["content"]["gt"] = False
    (out / "sequence.json").write_text(json.dumps(info))
    seq = load_sequence(out)
    assert seq.gt is not None and seq.gt.person_names == ("alice", "bob")
    assert seq.meta["gt"] == str(out / "gt.npz")


def test_convert_subject_mode_keeps_one_person_per_view(two_people, tmp_path):
    root, _, _ = two_people
    out = tmp_path / "subject"
    assert main(["convert", "--fps", "30", str(root), str(out), "--person", "subject", "--frames", "2"]) == 0
    seq = load_sequence(out)
    det = seq.detections
    assert seq.meta["person"] == "subject" and seq.num_frames == 2
    for f in range(2):
        for c in range(seq.num_views):
            assert len(set(det.person[(det.frame == f) & (det.view == c)])) == 1


def test_write_and_load_keep_the_person_column(two_people, tmp_path):
    from mocap.data.sequence_io import write_sequence

    root, _, _ = two_people
    src = load_openpose_sequence(root, layout="auto", person="all")
    out = write_sequence(src, tmp_path / "s")
    assert json.loads((out / "detections.json").read_text())["columns"][-1] == "person"
    np.testing.assert_array_equal(load_sequence(out).detections.person, src.detections.person)


def test_old_detections_without_person_still_load(two_people, tmp_path):
    root, _, _ = two_people
    out = tmp_path / "seq"
    assert main(["convert", "--fps", "30", str(root), str(out)]) == 0
    d = json.loads((out / "detections.json").read_text())
    d["columns"] = d["columns"][:6]
    d["rows"] = [r[:6] for r in d["rows"]]
    (out / "detections.json").write_text(json.dumps(d))
    assert load_sequence(out).detections.person is None


def test_the_video_recording_takes_its_tracked_frames_of_the_ground_truth(tmp_path):
    """data=pose2sim_demo_video with a gt.npz (the demo's keypoints, 100 frames; a ground truth
    whose joint values are their frame numbers): frames start:stop:step are the ones kept."""
    from mocap.body.skeletons import SKELETONS
    from mocap.video.sequence import load_video_sequence
    from tests.conftest import SHARED

    demo = SHARED / "data" / "pose2sim-demo"
    if not (demo / "videos").is_dir():
        pytest.skip("the Pose2Sim demo is not in ../shared/data")
    rec = tmp_path / "rec"
    rec.mkdir()
    shutil.copy(demo / "Calib.toml", rec)
    for sub in ("pose", "videos"):
        (rec / sub).symlink_to(demo / sub)
    names = list(SKELETONS["humaneva15"])
    joints = np.arange(100.0)[:, None, None] * np.ones((1, len(names), 3))
    np.savez(rec / "gt.npz", joints=joints, joint_names=np.array(names), skeleton=np.array("humaneva15"))
    seq = load_video_sequence(rec, stop=10, step=2, scale=0.25, layout="auto")
    assert seq.num_frames == 5 and list(seq.gt.joints[:, 0, 0]) == [0, 2, 4, 6, 8]
    assert seq.meta["layout"] == "BODY_25B" and seq.meta["gt"] == str(rec / "gt.npz")
    np.savez(rec / "gt.npz", joints=joints[:5], joint_names=np.array(names), skeleton=np.array("humaneva15"))
    with pytest.raises(ValueError, match="field 'joints' has 5 frames, the recording 100"):
        load_video_sequence(rec, stop=10, step=2, scale=0.25, layout="auto")


def test_trailing_frames_without_anyone_are_kept(two_people, tmp_path):
    """A recording whose last frame has nobody detected in any view still has that frame: the
    loader and ``mocap convert`` count the keypoint files, not the last detection."""
    root, _, _ = two_people
    src = tmp_path / "rec"
    shutil.copytree(root, src)
    src_gt = src / "gt.npz"
    src_gt.unlink()                       # ground truth would also carry the count
    last = sorted(src.glob("pose/*/*.json"))
    views = sorted({p.parent for p in last})
    for view in views:
        final = sorted(view.glob("*.json"))[-1]
        doc = json.loads(final.read_text())
        doc["people"] = []
        final.write_text(json.dumps(doc))
    seq = load_openpose_sequence(src, layout="auto", person="all")
    assert seq.num_frames == FRAMES and int(seq.detections.frame.max()) == FRAMES - 2
    out = tmp_path / "seq"
    assert main(["convert", "--fps", "30", str(src), str(out)]) == 0
    assert load_sequence(out).num_frames == FRAMES
    run = tmp_path / "run"
    assert main(["track", *FAST, f"data.path={src}", f"hydra.run.dir={run}"]) == 0
    assert json.loads((run / "metrics.json").read_text())["frames"] == FRAMES     # the empty frame tracked


def test_a_frame_count_below_the_detections_is_refused(two_people):
    from dataclasses import replace

    seq = load_openpose_sequence(two_people[0], layout="auto", person="all")
    with pytest.raises(ValueError, match="detections reach frame 2, beyond its 2 frames"):
        replace(seq, frames=2, gt=None)

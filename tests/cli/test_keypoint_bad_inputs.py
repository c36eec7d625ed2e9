"""The catalogue of bad inputs for keypoint recordings, their ground truth and ``mocap convert``
(issue 26): each is refused before any work with exit status 2 and one line
``mocap <command>: error: ...`` naming the file / setting and what is wrong, never a traceback;
``--debug`` shows the traceback; an error raised while tracking (after the checks: a bug) keeps
its traceback. Commands run in-process (``mocap_cli.main.main``) on a 3-frame synthetic
Pose2Sim folder of two people with known joints (tests/data/keypoint_folders.py)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocap_cli.main import main
from tests.data.keypoint_folders import known_people, write_gt, write_pose2sim

CONVERT = ("convert", "--fps", "30")
TRACK = ["track", "tracker=marker_apf", "data=pose2sim_demo", "data.fps=25", "init.mode=tracker", "frames=2",
         "recording.enabled=false", "tracker.init.particles=20", "tracker.init.passes=1"]
BASE: list[Path] = []          # the module's Pose2Sim folder (set by the autouse fixture)


@pytest.fixture(scope="module")
def base(tmp_path_factory, body) -> Path:
    rig, joints, keypoints, gt = known_people(body, 3)
    root = write_pose2sim(tmp_path_factory.mktemp("rec") / "rec", rig, keypoints)
    write_gt(root / "gt.npz", gt, joints, ["alice", "bob"])
    return root


@pytest.fixture(autouse=True)
def _base(base):
    BASE[:] = [base]


def copy(tmp: Path) -> Path:
    d = tmp / "rec"
    shutil.copytree(BASE[0], d)
    return d


def json_file(d: Path, view: int = 1, frame: int = 1) -> Path:
    return sorted(sorted((d / "pose").iterdir())[view].glob("*.json"))[frame]


def edit_json(tmp: Path, fn) -> Path:
    d = copy(tmp)
    f = json_file(d)
    data = json.loads(f.read_text())
    fn(data)
    f.write_text(json.dumps(data))
    return d


def edit_gt(tmp: Path, fn) -> Path:
    d = copy(tmp)
    with np.load(d / "gt.npz") as z:
        arrays = dict(z)
    fn(arrays)
    np.savez(d / "gt.npz", **arrays)
    return d


def nan_keypoint(data):
    data["people"][0]["pose_keypoints_2d"][3] = float("nan")


def short_person(data):
    data["people"][0]["pose_keypoints_2d"] = data["people"][0]["pose_keypoints_2d"][:-3]


def missing_view(tmp):
    d = copy(tmp)
    shutil.rmtree(sorted((d / "pose").iterdir())[2])
    return d


def missing_frame(tmp):
    d = copy(tmp)
    json_file(d, view=1, frame=2).unlink()
    return d


def nobody(tmp):
    d = copy(tmp)
    for f in (d / "pose").rglob("*.json"):
        f.write_text(json.dumps({"version": 1.3, "people": []}))
    return d


def rewrite(tmp, name, text):
    d = copy(tmp)
    (d / name).write_text(text)
    return d


def without(tmp, name):
    d = copy(tmp)
    (d / name).unlink()
    return d


def gt_set(key, value):
    return lambda a: a.__setitem__(key, value)


def gt_del(key):
    return lambda a: a.pop(key)


def track(tmp_data, *extra):
    return lambda t: [*TRACK, f"data.path={tmp_data(t) if callable(tmp_data) else tmp_data}", *extra]


def base_folder(t):
    return BASE[0]


# (case, argv(tmp), words the one line must hold)
CASES = [
    ("NaN keypoint", track(lambda t: edit_json(t, nan_keypoint)),
     ["cam_01.0001.json", "frame 1", "person 0", "NaN"]),
    ("keypoint list too short", track(lambda t: edit_json(t, short_person)),
     ["cam_01.0001.json", "72 values", "expected 75"]),
    ("invalid JSON", track(lambda t: rewrite(t, "pose/cam_01_json/cam_01.0001.json", "{oops")),
     ["cam_01.0001.json", "not valid JSON"]),
    ("missing view", track(missing_view), ["no folder for ['cam_02']", "cam_00_json"]),
    ("missing frame in one view", track(missing_frame), ["cam_01_json", "missing here: 2"]),
    ("nobody in any file", track(nobody), ["no person with 'pose_keypoints_2d'"]),
    ("no calibration", track(lambda t: without(t, "Calib.toml")), ["no calibration (*.toml)"]),
    ("broken calibration", track(lambda t: rewrite(t, "Calib.toml", "[cam_00]\nname = \n")),
     ["Calib.toml", "cannot parse TOML"]),
    ("wrong layout", track(base_folder, "data.layout=BODY_25"),
     ["do not look like BODY_25", "layout=BODY_25B"]),
    ("layout of another size", track(base_folder, "data.layout=COCO"),
     ["layout COCO has 18 keypoints", "the files have 25"]),
    ("unknown layout", track(base_folder, "data.layout=XYZ"), ["layout = 'XYZ'", "BODY_25B", "auto"]),
    ("data.person=bogus", track(base_folder, "data.person=bogus"), ["person = 'bogus'", "subject", "all"]),
    ("data.fps=0", track(base_folder, "data.fps=0"), ["fps = 0", "> 0"]),
    ("data.min_confidence=2", track(base_folder, "data.min_confidence=2"), ["min_confidence = 2", "[0, 1)"]),
    ("data.frames=0", track(base_folder, "data.frames=0"), ["frames = 0", ">= 1"]),
    ("unknown data setting", track(base_folder, "+data.bogus=1"),
     ["unknown data setting", "bogus", "layout"]),
    ("missing data folder", track(lambda t: t / "nope"), ["recording folder not found", "nope"]),
    ("data.gt: no such file", track(base_folder, "data.gt=/no/gt.npz"),
     ["gt = '/no/gt.npz'", "not found"]),
    ("gt.npz without joints", track(lambda t: edit_gt(t, gt_del("joints"))),
     ["gt.npz", "missing field 'joints'"]),
    ("gt.npz joints of the wrong shape", track(lambda t: edit_gt(t, lambda a: a.__setitem__(
        "joints", a["joints"][..., :2]))), ["gt.npz", "field 'joints'", "(3, 2, 19, 2)"]),
    ("gt.npz of another length", track(lambda t: edit_gt(t, lambda a: a.__setitem__(
        "joints", a["joints"][:2]))), ["gt.npz", "2 frames", "the recording 3"]),
    ("gt.npz joint_valid shape", track(lambda t: edit_gt(t, gt_set("joint_valid", np.ones((3, 19), bool)))),
     ["gt.npz", "field 'joint_valid'", "(3, 2, 19)"]),
    ("gt.npz person_names count", track(lambda t: edit_gt(t, gt_set("person_names", np.array(["a"])))),
     ["gt.npz", "field 'person_names'", "1 names", "2 people"]),
    ("gt.npz unknown skeleton", track(lambda t: edit_gt(t, gt_set("skeleton", np.array("h36m")))),
     ["gt.npz", "field 'skeleton'", "'h36m'", "shelf14"]),
    ("gt.npz names not of its skeleton", track(lambda t: edit_gt(t, gt_set("skeleton", np.array("coco17")))),
     ["gt.npz", "field 'joint_names'", "not the coco17 skeleton"]),
    ("gt.npz names the body does not know", track(lambda t: edit_gt(t, lambda a: a.__setitem__(
        "joint_names", np.array(["Nose", *a["joint_names"][1:]])))), ["unknown joints Nose"]),
    ("gt.npz NaN joint", track(lambda t: edit_gt(t, lambda a: a["joints"].__setitem__((1, 1, 4, 2), np.nan))),
     ["gt.npz", "NaN/Inf at frame 1", "person 'bob'", "nonfinite=drop"]),
    ("gt.npz with a pose chi and people", track(lambda t: edit_gt(t, gt_set("chi", np.zeros((3, 22))))),
     ["gt.npz", "field 'chi' is not allowed with several people"]),
    ("gt.npz not an archive", track(lambda t: rewrite(t, "gt.npz", "not a zip")),
     ["gt.npz", "not a readable .npz"]),
    ("gt_noise without a pose", track(base_folder, "init.mode=gt_noise"), ["no ground-truth pose chi",
                                                                           "init.mode=tracker"]),
    ("a Pose2Sim folder as data=folder", lambda t: ["track", "tracker=marker_apf", "data=folder",
                                                    f"data.path={BASE[0]}", "init.mode=tracker"],
     ["Pose2Sim folder", "mocap convert"]),
    ("convert: layout of another size", lambda t: [*CONVERT, str(BASE[0]), str(t / "o"), "--layout", "COCO"],
     ["layout COCO has 18 keypoints", "layouts with 25: ['BODY_25B', 'BODY_25']"]),
    ("convert: output exists", lambda t: [*CONVERT, str(BASE[0]), str(t)], ["exists", "--overwrite"]),
    ("convert: bad --person", lambda t: [*CONVERT, str(BASE[0]), str(t / "o"), "--person", "x"],
     ["--person", "invalid choice: 'x'", "mocap convert --help"]),
    ("convert: unknown option", lambda t: [*CONVERT, str(BASE[0]), str(t / "o"), "--fsp", "3"],
     ["unrecognized arguments: --fsp"]),
    ("convert: no calibration", lambda t: [*CONVERT, str(without(t, "Calib.toml")), str(t / "o")],
     ["no calibration (*.toml)"]),
    ("convert: a bad gt.npz", lambda t: [*CONVERT, str(edit_gt(t, gt_del("joint_names"))), str(t / "o")],
     ["gt.npz", "missing field 'joint_names'"]),
    ("gt-from-joints on a Pose2Sim folder",
     lambda t: ["gt-from-joints", str(t), str(BASE[0]), "--skeleton", "none"],
     ["has no sequence.json", "Pose2Sim folder", "mocap convert"]),
]


def test_the_catalogue_has_at_least_fifteen_cases():
    assert len(CASES) >= 15


@pytest.mark.parametrize("case, argv, words", CASES, ids=[c[0] for c in CASES])
def test_bad_keypoint_input_gives_one_line(case, argv, words, tmp_path, capsys):
    args = argv(tmp_path)
    run_dir = tmp_path / "run"
    if args[0] == "track":
        args.append(f"hydra.run.dir={run_dir}")
    got = main(args)
    out = capsys.readouterr()
    assert got == 2, out.err
    assert "Traceback" not in out.err
    (line,) = [ln for ln in out.err.splitlines() if "error:" in ln]
    assert line.startswith(f"mocap {args[0]}: error:"), line
    for word in words:
        assert word in line, (word, line)
    if args[0] == "track":                           # refused before any work: no results
        assert not (run_dir / "metrics.json").exists() and not (run_dir / "motion.npz").exists()
    if args[0] == "convert":
        assert not (tmp_path / "o").exists()


def test_debug_shows_the_traceback(tmp_path):
    """--debug, in a subprocess: the traceback as a user sees it (without --debug the same
    input is the one line of the catalogue's "layout of another size")."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"} | {"OPENBLAS_NUM_THREADS": "1"}
    args = ["--debug", *CONVERT, str(BASE[0]), str(tmp_path / "o"), "--layout", "COCO"]
    loud = subprocess.run([sys.executable, "-m", "mocap_cli", *args], capture_output=True, text=True,
                          env=env, timeout=300)
    assert loud.returncode != 0 and "Traceback" in loud.stderr and "OpenPoseFormatError" in loud.stderr
    assert "layout COCO has 18 keypoints" in loud.stderr


def test_hydra_full_error_raises_in_process(tmp_path, monkeypatch):
    from mocap.data.openpose import OpenPoseFormatError

    monkeypatch.setenv("HYDRA_FULL_ERROR", "1")
    with pytest.raises(OpenPoseFormatError, match="do not look like BODY_25"):
        main([*TRACK, f"data.path={BASE[0]}", "data.layout=BODY_25", f"hydra.run.dir={tmp_path}"])


def test_an_error_while_tracking_keeps_its_traceback(tmp_path, monkeypatch, capsys):
    """A KeyError raised after every check (here: by the frame loop) is a bug, not a user's
    mistake: mocap re-raises it (the traceback) instead of printing one line."""
    import mocap.run_folder.tracking as tracking

    def broken(*args, **kwargs):
        raise KeyError("mpjpe_std_mm")

    monkeypatch.setattr(tracking, "run_frames", broken)
    with pytest.raises(KeyError) as info:
        main(["track", "tracker=apf", "data=walk_small", "data.frames=2", "tracker.particles=4",
              "tracker.layers=2", "recording.enabled=false", f"hydra.run.dir={tmp_path}"])
    from mocap.run_folder.attempt import DURING_WORK_NOTE

    assert DURING_WORK_NOTE in info.value.__notes__
    assert "error:" not in capsys.readouterr().err

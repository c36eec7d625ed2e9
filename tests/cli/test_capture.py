"""``mocap capture``: every bad input refused in one line before any folder is written; the stage
plan (a changed stage reruns the later ones); end to end on the Pose2Sim demo's first frames
(exports read back by independent readers), resumed stage by stage (files untouched), a changed
setting rerunning the later stages only, an interrupted stage leaving no record."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from mocap.run_folder import capture as plan
from mocap_cli.main import main as mocap

REPO = Path(__file__).resolve().parents[2]
CANDIDATES = [Path(os.environ.get("MOCAP_SHARED_DATA", REPO.parent / "shared" / "data")) / "pose2sim-demo",
              REPO / "../shared/data/pose2sim-demo"]
DEMO = next((p.resolve() for p in CANDIDATES if (p / "videos").is_dir()), None)
MULTI = next((p.parent.resolve() / "pose2sim-demo-multi" for p in CANDIDATES
              if (p.parent / "pose2sim-demo-multi" / "videos").is_dir()), None)
CAMERAS = ("cam_01", "cam_02", "cam_03", "cam_04")


def _calib_toml(path: Path, size=(64, 48)) -> None:
    w, h = size
    lines = []
    for i, name in enumerate(CAMERAS):
        lines += [f"[{name}]", f'name = "{name}"', f"size = [ {w}.0, {h}.0]",
                  f"matrix = [ [ 60.0, 0.0, {w / 2}], [ 0.0, 60.0, {h / 2}], [ 0.0, 0.0, 1.0]]",
                  "distortions = [ 0.0, 0.0, 0.0, 0.0]", f"rotation = [ 0.0, {0.5 * i}, 0.0]",
                  "translation = [ 0.0, 0.0, 3.0]", "fisheye = false", ""]
    path.write_text("\n".join(lines + ["[metadata]", "adjusted = false", "error = 0.0", ""]))


def _video(path: Path, frames: int, size=(64, 48)) -> None:
    w, h = size
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for f in range(frames):
        out.write(np.full((h, w, 3), 10 * f, np.uint8))
    out.release()


def _recording(root: Path, lengths=(3, 3, 3, 3), names=("cam01", "cam02", "cam03", "cam04"),
               video_size=(64, 48)) -> Path:
    (root / "videos").mkdir(parents=True)
    _calib_toml(root / "Calib.toml")
    for n, name in zip(lengths, names, strict=True):
        _video(root / "videos" / f"{name}.mp4", n, video_size)
    return root


def _bad(tmp_path, case):
    """(argv, expected words of the line) of one bad input; the recording made as needed."""
    rec = tmp_path / "rec"
    if case == "no folder":
        return [str(tmp_path / "nothing")], "recording folder not found"
    if case == "no calibration":
        _recording(rec)
        (rec / "Calib.toml").unlink()
        return [str(rec)], "no calibration"
    if case == "calibration and calibrate":
        _recording(rec)
        return [str(rec), "--calibration", str(rec / "Calib.toml"), "--calibrate", "people"], "not both"
    if case == "video does not open":
        _recording(rec)
        (rec / "videos" / "cam02.mp4").write_bytes(b"not a video" * 100)
        return [str(rec)], "cam02.mp4"
    if case == "different lengths":
        _recording(rec, lengths=(3, 3, 2, 3))
        return [str(rec)], "camera 'cam_03' has 2 frames"
    if case == "camera names":
        _recording(rec, names=("cam01", "cam02", "cam03", "camX"))
        return [str(rec)], "no video for cameras ['cam_04']"
    if case == "video size":
        _recording(rec, video_size=(32, 24))
        return [str(rec)], "video is 32x24 but the calibration"
    if case == "unknown tracker":
        _recording(rec)
        return ([str(rec), "--tracker", "marker_apff"],
                "unknown tracker 'marker_apff' (did you mean marker_apf?)")
    if case == "unknown format":
        _recording(rec)
        return [str(rec), "--formats", "bvh,fbx"], "unknown format 'fbx'"
    if case == "people calibration from boards":
        _recording(rec)
        return [str(rec), "--calibrate", "people", "--intrinsics", str(rec)], "--intrinsics-from FILE"
    raise AssertionError(case)


BAD = ["no folder", "no calibration", "calibration and calibrate", "video does not open", "different lengths",
       "camera names", "video size", "unknown tracker", "unknown format",
       "people calibration from boards"]


@pytest.mark.parametrize("case", BAD)
def test_each_bad_input_is_one_line_before_any_folder_is_written(tmp_path, capsys, case):
    argv, words = _bad(tmp_path, case)
    out = tmp_path / "out"
    code = mocap(["capture", *argv, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and err.startswith("mocap capture: error:"), err
    assert words in err, err
    assert not out.exists()


def test_a_changed_stage_reruns_every_later_one(tmp_path):
    stages = [plan.Stage("detect", {"stop": 6}, ("detect/d",)),
              plan.Stage("track", {"seed": 0}, ("track/t",)), plan.Stage("export", {"formats": ["bvh"]})]
    assert plan.stages_to_run(tmp_path, {}, stages) == [True, True, True]
    record = {}
    for s in stages:
        for o in s.outputs:
            (tmp_path / o).parent.mkdir(exist_ok=True)
            (tmp_path / o).write_text("x")
        record = plan.finish_stage(tmp_path, record, s, 1.0)
    record = plan.check_capture_folder(tmp_path)            # as read back from capture.json
    assert plan.stages_to_run(tmp_path, record, stages) == [False, False, False]
    seed1 = [stages[0], plan.Stage("track", {"seed": 1}, ("track/t",)), stages[2]]
    assert plan.stages_to_run(tmp_path, record, seed1) == [False, True, True]
    assert plan.changed_settings(record, seed1[1]) == ["seed"]
    assert plan.stages_to_run(tmp_path, record, stages, {"track": True}) == [False, True, True]
    (tmp_path / "detect" / "d").unlink()                     # an output gone: from there on
    assert plan.stages_to_run(tmp_path, record, stages) == [True, True, True]
    # a stage that starts drops its own record and the later ones' in the file first
    plan.start_stage(tmp_path, record, stages, 1)
    assert sorted(json.loads((tmp_path / plan.RECORD).read_text())["stages"]) == ["detect"]


def test_a_foreign_folder_is_refused(tmp_path):
    (tmp_path / "something.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="not written by mocap capture"):
        plan.check_capture_folder(tmp_path)


def _mtimes(out: Path, names) -> dict:
    return {n: (out / n).stat().st_mtime_ns for n in names}


@pytest.mark.skipif(DEMO is None, reason="Pose2Sim demo not present")
def test_capture_end_to_end_resumes_and_reruns_only_what_changed(tmp_path, capsys, monkeypatch):
    from mocap.video.detector import detector_available

    if not detector_available():
        pytest.skip("mediapipe (the detector) not installed")
    import bvhio
    import ezc3d

    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    out = tmp_path / "cap"
    base = ["capture", str(DEMO), "--out", str(out), "--stop", "6", "--scale", "0.25", "--no-progress"]
    assert mocap([*base, "--formats", "bvh,c3d"]) == 0
    text = capsys.readouterr().out
    record = json.loads((out / "capture.json").read_text())
    assert list(record["stages"]) == ["detect", "track", "export"]
    assert record["summary"]["frames"] == 6 and record["summary"]["people"] == 1
    assert set(record["summary"]["reprojection_median_px_per_view"]) == set(CAMERAS)
    assert "frames: 6, people: 1" in text and "[track] done in" in text and "initialises itself" in text
    bvh = bvhio.readAsBvh(str(out / "export" / "motion.bvh"))          # independent readers
    assert bvh.FrameCount == 6
    c3d = ezc3d.c3d(str(out / "export" / "motion.c3d"))
    assert c3d["data"]["points"].shape[2] == 6 and np.isfinite(c3d["data"]["points"]).all()

    files = ["detect/detect.json", "track/motion.npz", "export/motion.bvh", "export/motion.c3d"]
    before = _mtimes(out, files)
    assert mocap([*base, "--formats", "bvh,c3d"]) == 0                  # resumed: nothing redone
    assert capsys.readouterr().out.count("skipped") == 3
    assert _mtimes(out, files) == before

    # an interrupted export leaves no export record; the next run redoes only the export
    from mocap_cli.commands import capture

    def interrupted(*args):
        raise KeyboardInterrupt("interrupted")
    monkeypatch.setattr(capture, "run_export", interrupted)
    assert mocap([*base, "--formats", "bvh"]) == 130
    assert list(json.loads((out / "capture.json").read_text())["stages"]) == ["detect", "track"]
    monkeypatch.undo()
    assert mocap([*base, "--formats", "bvh"]) == 0
    after = _mtimes(out, files[:3])
    assert after[files[0]] == before[files[0]] and after[files[1]] == before[files[1]]
    assert after[files[2]] != before[files[2]] and not (out / files[3]).exists()   # the c3d: not asked now

    # a changed tracker setting reruns the track and the export, not the detection
    assert mocap([*base, "--formats", "bvh", "--seed", "1"]) == 0
    assert "[track] start (changed: overrides)" in capsys.readouterr().out
    again = _mtimes(out, files[:3])
    assert again[files[0]] == before[files[0]]
    assert again[files[1]] != after[files[1]] and again[files[2]] != after[files[2]]
    track = json.loads((out / "capture.json").read_text())["stages"]["track"]
    assert "seed=1" in track["settings"]["overrides"]


@pytest.mark.parametrize("tracker, people", [("marker_apf", 1), ("hybrid", 1), ("marker_people", "auto")])
def test_the_track_stage_overrides_compose_as_mocap_track_takes_them(tmp_path, tracker, people):
    from mocap_cli.commands import capture
    from mocap_cli.hydra_edge import compose

    rec = _recording(tmp_path / "rec")
    a = capture._parser().parse_args([str(rec), "--out", str(tmp_path / "out"), "--stop", "2",
                                      "--track-set", "frames=2"])
    inputs = capture.Inputs(rec, rec / "videos", rec / "Calib.toml", CAMERAS, 3, 30.0)
    overrides = capture.track_overrides(a, inputs, tmp_path / "out", people, tracker, rec / "Calib.toml")
    cfg = compose("track", [o for o in overrides if not o.startswith("hydra.")])
    assert cfg.tracker.name == tracker and cfg.init.mode == "tracker" and cfg.frames == 2
    assert Path(cfg.data.path) == (tmp_path / "out" / "detect").resolve()
    assert Path(cfg.data.calibration) == (rec / "Calib.toml").resolve()
    if tracker == "hybrid":     # the silhouettes: the detected masks, the detected frames
        assert cfg.data._target_.endswith("video_sequence") and cfg.data.stop == 2
        assert Path(cfg.data.masks) == (tmp_path / "out" / "detect" / "masks").resolve()
    else:
        assert cfg.data.person == ("subject" if people == 1 else "all") and cfg.data.fps == 30


def test_help_and_a_bad_flag_import_no_numeric_stack():
    from tests.cli.test_startup import imported_by

    assert imported_by(["capture", "--help"]) == (0, [])
    assert imported_by(["capture", "--no-such-flag"]) == (2, [])


@pytest.mark.skipif(DEMO is None, reason="Pose2Sim demo not present")
def test_ctrl_c_during_detection_leaves_no_stage_record(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    from mocap.video.detector import detector_available

    if not detector_available():
        pytest.skip("mediapipe (the detector) not installed")
    out = tmp_path / "cap"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    p = subprocess.Popen([sys.executable, "-m", "mocap_cli", "capture", str(DEMO), "--out", str(out),
                          "--stop", "30", "--scale", "0.25", "--no-progress"], cwd=REPO, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "[detect] start"
        time.sleep(2.0)                                         # inside the detection
        p.send_signal(signal.SIGINT)
        stdout, stderr = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 130, stderr
    assert stderr.strip().splitlines()[-1].startswith("mocap capture: interrupted"), stderr
    assert "[detect] done" not in stdout
    assert json.loads((out / "capture.json").read_text())["stages"] == {}      # nothing to trust
    assert not (out / "track").exists() and not (out / "export").exists()
    assert not (out / ".mocap.lock").exists()       # removed, by the watchdog too if it ended the process
    from mocap.run_folder.lock import run_lock

    with run_lock(out):             # and not held any more
        pass


@pytest.mark.skipif(MULTI is None, reason="Pose2Sim two-person demo not present")
def test_capture_of_two_people_exports_each_person(tmp_path, capsys, monkeypatch):
    """The real two-person video through every stage: two tracks, a BVH per person read back by
    bvhio, one C3D holding both people's markers (ezc3d), the summary's per-person reprojection."""
    from mocap.video.detector import detector_available

    if not detector_available():
        pytest.skip("mediapipe (the detector) not installed")
    import bvhio
    import ezc3d

    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    out = tmp_path / "cap"
    assert mocap(["capture", str(MULTI), "--out", str(out), "--people", "2", "--stop", "5", "--scale", "0.5",
                  "--formats", "bvh,c3d", "--no-progress"]) == 0
    text = capsys.readouterr().out
    record = json.loads((out / "capture.json").read_text())
    assert record["summary"]["frames"] == 5 and record["summary"]["people"] == 2
    assert "people: 2" in text and "person 0" in text and "person 1" in text
    for person in (0, 1):
        assert bvhio.readAsBvh(str(out / "export" / f"motion_p{person}.bvh")).FrameCount == 5
    c3d = ezc3d.c3d(str(out / "export" / "motion.c3d"))
    labels = c3d["parameters"]["POINT"]["LABELS"]["value"]
    assert {lab.split("_")[0] for lab in labels} == {"p0", "p1"}
    assert c3d["data"]["points"].shape[2] == 5

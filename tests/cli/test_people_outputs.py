"""Several people through the command line: a several-people run given a ground-truth file
scores every true person (the best assignment of tracks to people, checked against the
nearest track computed here), rescore recomputes the same figures, replay summarises every
person; a several-people recording tracked as one person is flagged on the terminal and in
metrics.json."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocap.export.people_motion import load_people_motion
from mocap.run_folder.manifest import manifest_problem
from mocap.run_folder.people import several_people_evidence
from tests.cli.in_process import mocap as in_process
from tests.cli.people_data import crowd_gt_folder
from tests.conftest import PEOPLE_RUN

REPO = Path(__file__).resolve().parents[2]
FAST = [o for o in PEOPLE_RUN if o.startswith("tracker.")]


def mocap(*args: str) -> subprocess.CompletedProcess:
    """``mocap *args`` as a process: the tracks, whose warnings on stderr are asserted (in the
    test's process pytest would catch them)."""
    return subprocess.run([sys.executable, "-m", "mocap_cli", *args], capture_output=True, text=True,
                          cwd=REPO, timeout=600)


def nearest_tracks(joints: np.ndarray, truth: np.ndarray, gate_m: float = 0.5) -> list[int]:
    """For each true person (F, P, J, 3), the track (column of joints (F, T, J, 3)) nearest on
    average over the frames both exist (-1: none within the gate): the assignment to expect
    when people are far apart."""
    out = []
    for p in range(truth.shape[1]):
        best, best_err = -1, gate_m
        for t in range(joints.shape[1]):
            err = np.linalg.norm(joints[:, t] - truth[:, p], axis=-1).mean(axis=-1)   # (F,) NaN: absent
            if np.isfinite(err).any() and np.nanmean(err) < best_err:
                best, best_err = t, np.nanmean(err)
        out.append(best)
    return out


@pytest.mark.slow
def test_a_people_run_with_a_ground_truth_file_is_scored_per_person(body, tmp_path):
    data = crowd_gt_folder(body, tmp_path / "crowd_gt", frames=6)
    run = tmp_path / "run"
    r = mocap("track", f"hydra.run.dir={run}", "tracker=marker_people", "data=folder", f"data.path={data}",
              "init.mode=tracker", *FAST)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((run / "metrics.json").read_text())
    a = load_people_motion(run)
    from mocap.data.sequence_io import load_ground_truth

    gt = load_ground_truth(data / "gt.npz")
    truth = np.where(gt.joint_valid[..., None], gt.joints, np.nan)
    ids = [int(i) for i in a["person_ids"]]
    nearest = nearest_tracks(a["joints"].astype(np.float64), truth)
    want = {name: (ids[t] if t >= 0 else -1) for name, t in zip(gt.person_names, nearest, strict=True)}
    assert [p["person"] for p in m["per_person"]] == list(gt.person_names)       # the file's order
    assert m["assignment"] == want and want["actor4"] == -1                    # actor4 enters at frame 10
    assert len({t for t in want.values() if t >= 0}) == 4
    tracked = [p for p in m["per_person"] if p["track"] >= 0]
    assert all(p["mpjpe_mm"] < 60 and p["pcp"] >= 0.9 for p in tracked)
    assert m["identity_switches"] == 0 and m["people_in_ground_truth"] == 5 and m["people_tracked"] == 4
    assert "4 of 5 people tracked, 0 identity switches, MPJPE" in r.stdout
    assert "several people in the data" not in r.stderr           # tracked as several: no flag
    # rescore: the same figures from the motion file, the folder still a complete run
    r = in_process("rescore", str(run))
    assert r.returncode == 0 and "identity switches 0 -> 0" in r.stdout, r.stderr[-2000:]
    again = json.loads((run / "metrics.json").read_text())
    assert again["per_person"] == m["per_person"]
    assert again["rescored"]["previous"]["mpjpe_mm"] == m["mpjpe_mm"]
    assert manifest_problem(run) is None
    # replay: the recording's summary, then every person of the motion
    r = in_process("replay", str(run), "--summary")
    assert r.returncode == 0 and "people motion: 6 frames" in r.stdout
    assert all(f"  person {i}: " in r.stdout for i in ids)
    # export: every person of the file
    r = in_process("export", str(run), "--format", "bvh")
    assert r.returncode == 0 and all((run / f"motion_p{i}.bvh").is_file() for i in ids), r.stderr


@pytest.mark.slow
def test_the_crowds_own_truth_is_rescored_per_person(people_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(people_run, run)
    before = json.loads((run / "metrics.json").read_text())
    r = in_process("rescore", str(run))
    assert r.returncode == 0, r.stderr[-2000:]
    after = json.loads((run / "metrics.json").read_text())
    assert after["per_person"] == before["per_person"] and after["assignment"] == before["assignment"]
    assert manifest_problem(run) is None


@pytest.mark.slow
def test_several_people_tracked_as_one_person_are_flagged(body, tmp_path):
    data = crowd_gt_folder(body, tmp_path / "crowd_gt", frames=3)
    run = tmp_path / "run"
    r = mocap("track", f"hydra.run.dir={run}", "tracker=marker_apf", "data=folder", f"data.path={data}",
              "init.mode=tracker", "frames=2", "tracker.particles=20", "tracker.layers=3")
    assert r.returncode == 0, r.stderr[-3000:]
    line = "several people in the data, tracked as one person: the ground truth"
    warnings = [w for w in r.stderr.splitlines() if line in w]
    assert len(warnings) == 2 and warnings[0].startswith("WARNING: ")      # before the work, and at the end
    assert "tracker=marker_people" in warnings[0]
    m = json.loads((run / "metrics.json").read_text())
    assert m["several_people_data"]["people"] == 5 and any(line in f for f in m["quality"]["flags"])


def test_what_says_a_recording_holds_several_people(body, tmp_path):
    from dataclasses import replace

    from mocap.data.crowd import crowd_sequence

    crowd = crowd_sequence(body=body, frames=20)
    assert several_people_evidence(crowd) == {"people": 4, "why": "the data holds 5 people"}
    detections_only = replace(crowd, meta={})
    assert several_people_evidence(detections_only)["why"] == "the detections hold up to 4 people in one view"
    d = crowd.detections
    one = d.person == d.person.min()
    from mocap.data.sequence import Detections

    single = Detections(d.labels, d.frame[one], d.view[one], d.label[one], d.xy[one], d.confidence[one],
                        np.zeros(int(one.sum()), np.int64))
    assert several_people_evidence(replace(crowd, detections=single, meta={})) is None
    subject = replace(crowd, detections=single, meta={"people_in_view": 2, "person": "subject"})
    assert several_people_evidence(subject)["why"] == ("the keypoint files hold up to 2 people in one view "
                                                       "(data.person=subject kept one per view)")


DEMO = REPO.parent / "shared" / "data" / "pose2sim-demo"


@pytest.mark.skipif(not (DEMO / "Calib.toml").is_file(), reason="Pose2Sim demo data not present")
def test_the_pose2sim_demos_bystanders_are_seen_though_one_subject_is_kept():
    import warnings

    from mocap.data.openpose import load_openpose_sequence

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")             # frames without the subject in a view
        seq = load_openpose_sequence(DEMO, fps=60, layout="auto", frames=10)
    assert len(np.unique(seq.detections.person[seq.detections.frame == 0])) >= 1
    evidence = several_people_evidence(seq)
    assert evidence["people"] >= 2 and evidence["why"].endswith("(data.person=subject kept one per view)")


@pytest.mark.slow
@pytest.mark.skipif(not (DEMO / "Calib.toml").is_file(), reason="Pose2Sim demo data not present")
def test_a_several_people_tracker_on_one_kept_person_is_refused_before_any_work(tmp_path):
    r = mocap("track", f"hydra.run.dir={tmp_path}", "tracker=marker_people", "data=pose2sim_demo",
              f"data.path={DEMO}", "init.mode=tracker")
    assert r.returncode != 0 and "Traceback" not in r.stderr
    said = "tracks several people, but data.person=subject keeps one per view (the keypoint files hold up to"
    assert said in r.stderr and r.stderr.strip().endswith("use data.person=all")
    assert not (tmp_path / "metrics.json").exists() and not (tmp_path / "motion.npz").exists()

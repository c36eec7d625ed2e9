"""Ablation tables for real use: sweeps make one row per value, single seeds show no ± 0.0,
NaN runs are named, runs without ground truth keep their own columns."""

import json

import numpy as np
import pytest
import yaml

from mocap.export.motion import motion_arrays, write_motion
from mocap.run_folder.sweep import collect, markdown, table_rows
from mocap.trackers.base import Estimate


def seal(root):
    """Mark each fake run complete as a finished run is: manifest.json with its files' checksums."""
    from mocap.run_folder.manifest import write_manifest

    for m in root.rglob("metrics.json"):
        write_manifest(m.parent, [n for n in ("motion.npz", "metrics.json") if (m.parent / n).is_file()])
    return root


def fake_run(root, name, overrides, **metrics):
    d = root / name
    (d / ".hydra").mkdir(parents=True)
    (d / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
    base = {"tracker": "marker_apf", "data": "walk_markers", "sec_per_frame": 0.5, "particles": 100,
            "layers": 10, "energy_terms": ["markers"]}
    (d / "metrics.json").write_text(json.dumps({**base, **metrics}))
    return d


def test_sweep_rows_seeds_nan_and_no_ground_truth(tmp_path, body):
    for fp, errs in (("0.1", (10.0, 14.0)), ("0.3", (20.0, float("nan")))):
        for seed, e in enumerate(errs):
            over = ["tracker=marker_apf", f"data.detections.false_positive_rate={fp}", f"seed={seed}"]
            fake_run(tmp_path, f"fp{fp}_s{seed}", over, mpjpe_mm=e)
    fake_run(tmp_path, "real_kp", ["tracker=marker_apf", "data=pose2sim_demo"], data="pose2sim_demo",
             reprojection_median_px=3.5, bone_length_std_mm=2.0, jitter_mm=4.0)
    # a run with neither ground truth nor detections: its motion.npz gives bone std and jitter
    d = fake_run(tmp_path, "real_sil", ["tracker=local", "data=video"], tracker="local", data="video")
    chis = np.zeros((3, body.num_dofs))
    chis[:, 0] = [0.0, 0.01, 0.03]                      # x: 0, 10, 30 mm -> 2nd difference 10 mm
    ests = [Estimate(c, np.zeros(body.num_shape)) for c in chis]
    write_motion(d / "motion.npz", motion_arrays(body, ests, [0, 0, 0], 25.0))
    seal(tmp_path)
    got = collect(tmp_path)
    assert [p for p in got.problems if "fp0.3_s1" in p[0]] and "nan" in got.problems[0][1]
    rows = {(r["data"], r["overrides"]): r for r in table_rows(got.runs)}
    a = rows[("walk_markers", "data.detections.false_positive_rate=0.1")]
    b = rows[("walk_markers", "data.detections.false_positive_rate=0.3")]
    assert a["seeds"] == 2 and a["mpjpe_mean_mm"] == 12.0 and a["mpjpe_std_mm"] == pytest.approx(2 ** 0.5 * 2)
    assert b["seeds"] == 1 and b["mpjpe_mean_mm"] == 20.0 and b["mpjpe_std_mm"] is None
    kp = next(r for r in rows.values() if r["data"] == "pose2sim_demo")
    assert "mpjpe_mean_mm" not in kp and kp["reprojection_median_px"] == 3.5
    sil = next(r for r in rows.values() if r["data"] == "video")
    assert sil["jitter_mm"] == pytest.approx(10.0, abs=1e-3) and sil["bone_length_std_mm"] < 1e-3
    md = markdown(table_rows(got.runs), got.problems, "t")
    assert "| 12.0 ± 2.8 |" in md and "| 20.0 |" in md and "± 0.0" not in md
    assert "fp0.3_s1" in md and "reprojection (px)" in md and "jitter (mm)" in md


def test_expected_jobs_counts_the_sweep_config_and_the_command_line(tmp_path):
    """A sweep config's params (conf/sweep/*) overridden by the command line's; commas inside a
    list value do not count as sweep values."""
    import yaml

    from mocap.run_folder.sweep import expected_jobs

    (tmp_path / "multirun.yaml").write_text(yaml.safe_dump({"hydra": {
        "sweeper": {"params": {"data": "a,b,c", "tracker": "x,y,z,w", "seed": "0,1,2"}},
        "overrides": {"task": ["+sweep=mismatch", "tracker=x,y", "seed=0", "data.views=[0,2,4,6]",
                               "'data.noise={holes:2,dilate_px:3}'"]}}}))
    assert expected_jobs(tmp_path) == 3 * 2 * 1
    assert expected_jobs(tmp_path / "nothing") is None


def test_runs_are_labelled_and_counted_from_the_config_that_ran(tmp_path):
    """overrides.yaml of a refused re-run says particles=20; the run's config says 25: the
    label is 25. Seeds are counted as distinct seeds; a seed twice in a row is reported."""
    for name, over, particles, seed in (("a", "20", 25, 0), ("b", "25", 25, 1), ("c", "20", 20, 0),
                                        ("d", "20", 20, 0)):
        fake_run(tmp_path, name, ["tracker=apf", f"tracker.particles={over}", f"seed={seed}"],
                 tracker="apf", seed=seed, mpjpe_mm=10.0,
                 config={"seed": seed, "tracker": {"particles": particles}})
    seal(tmp_path)
    got = collect(tmp_path)
    rows = {r["overrides"]: r for r in table_rows(got.runs)}
    assert rows["tracker.particles=25"]["seeds"] == 2 and rows["tracker.particles=20"]["seeds"] == 1
    (problem,) = got.problems
    assert "tracker.particles=20" in problem[0] and "seed(s) 0 more than once" in problem[1]

"""mocap rescore: a finished run re-scored from its motion.npz and stored config."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import mocap
from mocap.data.sources import folder_sequence
from mocap.eval import run_metrics
from mocap.eval.mismatch import fit_oracle
from mocap.export.motion import motion_arrays, write_motion
from mocap.run_folder.manifest import manifest_problem, write_manifest
from mocap.trackers.base import Estimate
from tests.cli import in_process

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "data" / "mismatch" / "walk"


def rescore(*args) -> subprocess.CompletedProcess:
    """``mocap rescore *args`` in this process (:mod:`tests.cli.in_process`: what it writes is the
    point, not the process), as a fresh process would: with no oracle fit kept in memory by an
    earlier call (:mod:`mocap.eval.run_metrics` keeps them per process), so a cached fit is read
    from its cache folder or fitted and written there."""
    with pytest.MonkeyPatch.context() as mp:
        for memo in ("_ORACLES", "_FITS", "_SURFACE_ORACLES"):
            mp.setattr(run_metrics, memo, {})
        return in_process.mocap("rescore", *args)


def test_rescoring_an_unchanged_evaluation_gives_the_runs_own_figures(short_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(short_run, run)
    before = json.loads((run / "metrics.json").read_text())
    r = rescore(run)
    assert r.returncode == 0, r.stderr
    after = json.loads((run / "metrics.json").read_text())
    assert after["mpjpe_mm"] == pytest.approx(before["mpjpe_mm"], abs=1e-9)
    assert after["per_frame_mm"] == pytest.approx(before["per_frame_mm"], abs=1e-9)
    assert after["rescored"]["previous"]["mpjpe_mm"] == before["mpjpe_mm"]
    assert after["sec_per_frame"] == before["sec_per_frame"]          # speed figures kept
    assert manifest_problem(run) is None                  # the manifest follows the new metrics.json
    assert rescore(tmp_path / "nothing").returncode == 2


@pytest.mark.slow
@pytest.mark.skipif(not WALK.is_dir(), reason="data/mismatch not in this checkout")
def test_rescoring_a_mismatch_run_scores_the_oracles_poses_as_the_oracle(tmp_path):
    """A run whose motion is the oracle's own fit (5 frames) is re-scored at the oracle's raw
    error, through the HumanEva mapping (pelvis, thorax, head on landmarks of ours)."""
    body = mocap.load_body("paper22")
    seq = folder_sequence(body=body, path=str(WALK), images=False)
    F = 5
    fit = fit_oracle(body, seq.gt.joint_names, seq.gt.joints[:F], None, seq.gt.skeleton)
    run = tmp_path / "run"
    run.mkdir()
    ests = [Estimate(c, fit.alpha.astype(np.float32), {}) for c in fit.chi]
    write_motion(run / "motion.npz", motion_arrays(body, ests, [0.0] * F, 25.0))
    config = {"body": {"_target_": "mocap.body.load_body", "name": "paper22"},
              "data": {"_target_": "mocap.data.sources.folder_sequence", "path": str(WALK),
                       "images": False, "name": "mismatch_walk"}}
    (run / "metrics.json").write_text(json.dumps({"config": config, "mpjpe_mm": 999.0}))
    write_manifest(run, ["motion.npz", "metrics.json"])        # a complete run, as mocap track leaves it
    twin = tmp_path / "twin"
    shutil.copytree(run, twin)
    r = rescore(run, "--oracle-cache", tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    m = json.loads((run / "metrics.json").read_text())
    assert m["mpjpe_mm"] == pytest.approx(fit.metrics["raw_mm"], abs=0.05)
    assert m["mismatch"]["raw_mm"] == pytest.approx(fit.metrics["raw_mm"], abs=0.05)
    assert m["oracle"]["raw_mm"] == pytest.approx(fit.metrics["raw_mm"], abs=0.05)
    assert m["rescored"]["previous"] == {"mpjpe_mm": 999.0}
    # the oracle fits were kept by content: a second run of the same sequence reads them back
    kept = sorted(p.name for p in (tmp_path / "cache").rglob("*") if p.is_file())
    assert kept
    r = rescore(twin, "--oracle-cache", tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "cache").rglob("*") if p.is_file()) == kept
    t = json.loads((twin / "metrics.json").read_text())
    assert t["oracle"] == m["oracle"]
    assert t.get("surface_oracle_mm") == m.get("surface_oracle_mm")

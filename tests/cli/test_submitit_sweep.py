"""A sweep through a real cluster launcher (issue 28): Hydra's submitit launcher in local mode
(``hydra/launcher=submitit_local``) pickles every job, starts it in its own process through
submitit and gathers its result from submitit's folder, as the SLURM launcher
(conf/hydra/launcher/slurm.yaml) does on a cluster; ``mocap ablate`` reads the jobs'
run directories."""

from __future__ import annotations

import csv
import json
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocap.export.motion import load_motion

REPO = Path(__file__).resolve().parents[2]


def mocap(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocap_cli", *args], capture_output=True, text=True,
                          cwd=REPO, timeout=600)


@pytest.mark.slow        # two tracker processes started by submitit (~15 s with a warm numba cache)
def test_submitit_local_sweep_runs_pickled_jobs_and_ablate_reads_them(tmp_path):
    sweep = tmp_path / "sweep"
    r = mocap("track", "--multirun", "hydra/launcher=submitit_local", f"hydra.sweep.dir={sweep}",
              "hydra.launcher.cpus_per_task=1", "tracker=apf_prior", "data=walk_small",
              "tracker.particles=6", "tracker.layers=2", "frames=2", "seed=0,1", "recording.enabled=false")
    assert r.returncode == 0, r.stderr[-3000:]
    runs = {json.loads((d / "metrics.json").read_text())["seed"]: d             # content-named folders
            for d in sweep.iterdir() if (d / "metrics.json").is_file()}
    assert sorted(runs) == [0, 1]
    returned = {}
    for result in (sweep / ".submitit").glob("*/*_result.pkl"):     # what the launcher gathered
        status, job = pickle.loads(result.read_bytes())
        assert status == "success"
        returned[job.return_value["seed"]] = job.return_value
    assert sorted(returned) == [0, 1]
    for num, run in runs.items():
        m = json.loads((run / "metrics.json").read_text())
        assert run.name.startswith(f"apf_prior_walk_small_s{num}_") and (run / "manifest.json").is_file()
        assert (m["tracker"], m["data"], m["seed"], m["frames"]) == ("apf_prior", "walk_small", num, 2)
        assert m["threads"] == 1                     # threads=auto: cpus_per_task
        assert np.isfinite(m["mpjpe_mm"]) and m["mpjpe_mm"] < 200
        assert returned[num]["mpjpe_mm"] == m["mpjpe_mm"]      # the job's own metrics came back
        motion = load_motion(run / "motion.npz")
        assert motion.chi.shape[0] == 2 and np.isfinite(motion.chi).all()
        assert motion.info["seed"] == num and motion.info["tracker"] == "apf_prior"
        assert not list(run.glob("*.rrd*"))
    per_seed = [json.loads((runs[n] / "metrics.json").read_text())["mpjpe_mm"] for n in (0, 1)]
    assert per_seed[0] != per_seed[1]                # two seeds, two runs (not one run twice)
    out = mocap("ablate", str(sweep))
    assert out.returncode == 0, out.stderr
    (row,) = list(csv.DictReader((sweep / "ablation.csv").open()))
    assert (row["tracker"], row["data"], row["seeds"]) == ("apf_prior", "walk_small", "2")
    assert float(row["mpjpe_mean_mm"]) == pytest.approx(np.mean(per_seed))
    assert "| apf_prior | walk_small |" in (sweep / "ablation.md").read_text()

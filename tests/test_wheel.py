"""The library without the repository: the wheel built from the sources holds every module
and every data file of the checkout's packages and the Hydra configs of conf/; installed into
a fresh virtual environment outside the checkout (the wheel alone, without its dependencies:
those are read from the test's own environment, whose editable install of the checkout is
not), from a working directory outside the checkout, it reads the prior's motion-type split
and tracks a short synthetic sequence with its body model, pose prior and presets read from
the installed package data; every ``mocap`` command answers ``--help`` (the Hydra ones with
their configs read from the wheel), and the console script tracks, sweeps, exports and
tabulates there."""

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
UV = shutil.which("uv", path=str(Path(sys.executable).parent)) or shutil.which("uv")

SCRIPT = r"""
import json, sys
import numpy as np
import mocap
body = mocap.load_body("paper22")
seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=4, seed=0)
r = mocap.track(seq, tracker="apf_prior", body=body, seed=0, particles=8, layers=2)
shaped = body.shaped(r.estimates[0].alpha)
joints = np.stack([shaped.pose(e.chi[None]).joints[0] for e in r.estimates])
err = 1e3 * np.linalg.norm(joints - seq.gt.joints[: len(joints)], axis=-1).mean()
from mocap.clips.split import read_split
split = read_split()
print(json.dumps({"file": mocap.__file__, "frames": len(r.estimates), "dofs": int(r.estimates[-1].chi.size),
                  "mean_joint_error_mm": float(err), "hydra_imported": "hydra" in sys.modules,
                  "split": [list(split.train), list(split.held_out)]}))
"""


def run(cmd, **kw):
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=600, **kw)
    assert r.returncode == 0, f"{cmd}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.mark.slow
@pytest.mark.skipif(UV is None, reason="needs uv (installed by scripts/setup_env.sh)")
def test_the_wheel_installed_outside_the_checkout_tracks(tmp_path):
    src = tmp_path / "src"                      # build from a copy: no build/ in the checkout
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, src / name)
    for package in ("mocap", "mocap_cli", "mocap_build", "conf"):
        shutil.copytree(REPO / package, src / package,
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "*.nbi", "*.nbc"))
    run([UV, "build", "--wheel", "--offline", "--out-dir", tmp_path / "dist", src])
    (wheel,) = (tmp_path / "dist").glob("mocap-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    conf = {"mocap_cli/" + p.relative_to(REPO).as_posix() for p in (REPO / "conf").rglob("*.yaml")}
    assert conf and conf <= names, sorted(conf - names)           # every Hydra config ships
    tracked = subprocess.run(["git", "ls-files", "mocap", "mocap_cli"], cwd=REPO, capture_output=True,
                             text=True).stdout.split()
    if tracked:                                   # every module and data file of the packages
        assert set(tracked) <= names, sorted(set(tracked) - names)
    assert "mocap/clips/split.yaml" in names and "mocap_cli/main.py" in names
    python = getattr(sys, "_base_executable", sys.executable)
    run([UV, "venv", "--offline", "--python", python, tmp_path / "venv"])
    py = tmp_path / "venv" / "bin" / "python"
    # the dependencies: this environment's packages as a plain path (its own .pth files, the
    # editable install of the checkout among them, are not read from there)
    purelib = run([py, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"]).stdout.strip()
    Path(purelib, "_test_dependencies.pth").write_text(sysconfig.get_path("purelib") + "\n")
    run([UV, "pip", "install", "--offline", "--no-deps", "--link-mode", "copy", "--python", py, wheel])
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["OPENBLAS_NUM_THREADS"] = "1"
    out = json.loads(run([py, "-c", SCRIPT], cwd=work, env=env).stdout.strip().splitlines()[-1])
    installed = Path(out["file"]).resolve()
    assert installed.is_relative_to((tmp_path / "venv").resolve()), installed
    assert not installed.is_relative_to(REPO)
    assert out["frames"] == 4 and out["dofs"] == 22
    assert out["mean_joint_error_mm"] < 60.0, out      # started at ground truth + 3 deg noise
    assert out["hydra_imported"] is False              # no Hydra below the entry points
    assert out["split"][0] and out["split"][1] and not set(out["split"][0]) & set(out["split"][1])

    # the console script, from the same folder outside the checkout
    mocap = tmp_path / "venv" / "bin" / "mocap"
    assert "track" in run([mocap, "--help"], cwd=work, env=env).stdout
    listed = run([py, "-c", "from mocap_cli.main import COMMANDS; print(' '.join(COMMANDS))"], cwd=work,
                 env=env).stdout.split()
    assert len(listed) >= 10, listed
    for command in listed:                                  # every command answers --help
        shown = run([mocap, command, "--help"], cwd=work, env=env).stdout
        assert shown.strip(), command
        if "Hydra" in shown:                                # its config groups, read from the wheel
            assert "tracker" in shown or "data" in shown, (command, shown[:500])
    tiny = ["data=walk_small", "data.frames=3", "frames=3", "tracker=apf_prior", "tracker.particles=6",
            "tracker.layers=2", "recording.every=2"]
    run([mocap, "track", *tiny, "hydra.run.dir=runs/one"], cwd=work, env={**env, "TQDM_DISABLE": "1"})
    metrics = json.loads((work / "runs" / "one" / "metrics.json").read_text())
    assert metrics["frames"] == 3 and metrics["tracker"] == "apf_prior" and metrics["mpjpe_mm"] < 80
    assert metrics["config"]["data"]["cameras"] == "ring4_small"
    assert (work / "runs" / "one" / "recording.rrd").is_file()
    exported = run([mocap, "export", "runs/one", "--format", "bvh"], cwd=work, env=env)
    bvh = (work / "runs" / "one" / "motion.bvh").read_text()
    assert "wrote" in exported.stdout and bvh.startswith("HIERARCHY") and "Frames: 3" in bvh
    run([mocap, "track", "--multirun", *tiny, "seed=0,1", "hydra.sweep.dir=sweep"], cwd=work,
        env={**env, "TQDM_DISABLE": "1"})
    table = run([mocap, "ablate", "sweep", "--strict"], cwd=work, env=env).stdout
    assert "apf_prior" in table and (work / "sweep" / "ablation.csv").is_file()
    rows = (work / "sweep" / "ablation.csv").read_text().splitlines()
    assert len(rows) == 2 and "apf_prior" in rows[1]                  # two seeds, one row

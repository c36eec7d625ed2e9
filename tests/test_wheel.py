"""The library without the repository (issue 10): the wheel built from the sources, installed
into a fresh virtual environment outside the checkout (its dependencies from uv's cache,
offline), tracks a short synthetic sequence from a working directory outside the checkout,
with its body model, pose prior and presets read from the installed package data."""

import json
import os
import shutil
import subprocess
import sys
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
r = mocap.track(seq, tracker="hybrid", body=body, seed=0,
                local={"iterations": 3}, apf={"particles": 8, "layers": 2})
shaped = body.shaped(r.estimates[0].alpha)
joints = np.stack([shaped.pose(e.chi[None]).joints[0] for e in r.estimates])
err = 1e3 * np.linalg.norm(joints - seq.gt.joints[: len(joints)], axis=-1).mean()
print(json.dumps({"file": mocap.__file__, "frames": len(r.estimates), "dofs": int(r.estimates[-1].chi.size),
                  "mean_joint_error_mm": float(err), "hydra_imported": "hydra" in sys.modules}))
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
    shutil.copytree(REPO / "mocap", src / "mocap",
                    ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "*.nbi", "*.nbc"))
    run([UV, "build", "--wheel", "--offline", "--out-dir", tmp_path / "dist", src])
    (wheel,) = (tmp_path / "dist").glob("mocap-*.whl")
    python = getattr(sys, "_base_executable", sys.executable)
    run([UV, "venv", "--offline", "--python", python, tmp_path / "venv"])
    py = tmp_path / "venv" / "bin" / "python"
    run([UV, "pip", "install", "--offline", "--link-mode", "hardlink", "--python", py, wheel])
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

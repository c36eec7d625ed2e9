"""Safe defaults (issue 37): a command run with no output argument writes nothing inside the
package or the repository's tracked files. ``mocap train-prior`` goes to
outputs/priors/ of the current directory (not the prior shipped in mocap/energy/assets), ``mocap
make-dataset`` to outputs/datasets/ (not data/); each is run from a scratch directory with tiny
settings, and the checkout's ``git status`` and the shipped prior's bytes are the same after."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mocap.energy.prior import ParzenPrior, default_prior_path

REPO = Path(__file__).resolve().parents[2]


def git_status() -> str:
    if shutil.which("git") is None or not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    return subprocess.run(["git", "status", "--porcelain", "--untracked-files=all"], cwd=REPO,
                          capture_output=True, text=True, check=True).stdout


def mocap(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
           "TQDM_DISABLE": "1"}
    return subprocess.run([sys.executable, "-m", "mocap_cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_train_prior_without_out_leaves_the_shipped_prior_and_the_checkout_alone(tmp_path):
    shipped = default_prior_path("paper22")
    before, shipped_bytes = git_status(), shipped.read_bytes()
    r = mocap(tmp_path, "train-prior", "--body", "paper22", "--samples", "3")
    assert r.returncode == 0, r.stderr[-3000:]
    out = tmp_path / "outputs" / "priors" / "pose_prior_paper22.npz"
    assert len(ParzenPrior.load(out).samples) > 0
    assert f"tracker.prior.prior_file={Path('outputs') / 'priors' / out.name}" in r.stdout
    assert shipped.read_bytes() == shipped_bytes
    assert git_status() == before


@pytest.mark.slow
def test_make_dataset_without_out_writes_under_outputs_not_data(tmp_path):
    before = git_status()
    r = mocap(tmp_path, "make-dataset", "cameras=ring4_small", "frames=2", "name=tiny")
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "outputs" / "datasets" / "tiny" / "contact_sheet.png").is_file()
    assert not (tmp_path / "data").exists()
    assert git_status() == before

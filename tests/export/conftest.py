"""One short tracked run shared by the motion and export tests."""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def track(out: Path, *args: str) -> Path:
    r = subprocess.run([sys.executable, str(REPO / "experiments" / "track.py"), f"hydra.run.dir={out}",
                        *args], capture_output=True, text=True, cwd=REPO, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="session")
def short_run(tmp_path_factory) -> Path:
    """apf_prior on walk_small, 4 frames, tiny budget; recording on."""
    return track(tmp_path_factory.mktemp("export_run"), "tracker=apf_prior", "frames=4",
                 "data=walk_small", "tracker.particles=6", "tracker.layers=2")

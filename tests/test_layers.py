"""The import-layer contract of pyproject.toml ([tool.importlinter]) holds for this checkout:
no package imports a package of a higher layer or a sibling of its own layer, no module
circles in any package of mocap, and the trackers' settings import none of the parts they
configure. Every package and top-level module of mocap has its layer, so a new one cannot
stand outside the contract."""

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIG = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]

LINT = ("import sys\nfrom importlinter.cli import lint_imports\n"
        "sys.exit(lint_imports(config_filename='pyproject.toml', no_cache=True, no_logo=True))")


def test_the_import_contracts_are_kept():
    env = {**os.environ, "PYTHONPATH": str(REPO)}   # this checkout's mocap, not an installed one
    r = subprocess.run([sys.executable, "-c", LINT], cwd=REPO, env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-2000:]
    assert re.search(r"Contracts: (\d+) kept, 0 broken", r.stdout), r.stdout[-2000:]


def test_every_package_of_mocap_has_a_layer():
    (layers,) = [c["layers"] for c in CONFIG["contracts"] if c["type"] == "layers"]
    named = {m.strip() for layer in layers for m in layer.split("|")}
    top = {f"mocap.{p.stem}" for p in (REPO / "mocap").glob("*.py") if p.stem != "__init__"}
    top |= {f"mocap.{p.parent.name}" for p in (REPO / "mocap").glob("*/__init__.py")}
    assert top - named == set(), f"packages with no layer in pyproject.toml: {sorted(top - named)}"
    assert named - top == set(), f"layers naming no package: {sorted(named - top)}"

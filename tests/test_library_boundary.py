"""The library stays a library (issue 23): nothing under mocap/ imports Hydra or OmegaConf (only
the command line, mocap_cli/, does), and no path under mocap/ climbs out of the package to the
repository (data is passed in by the caller; package data sits inside mocap/)."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LIBRARY = REPO / "mocap"

HYDRA = re.compile(r"^\s*(import\s+(hydra|omegaconf)\b|from\s+(hydra|omegaconf)[\s.])", re.M)
# Path(__file__)[.resolve()].parents[k] and Path(__file__)[.resolve()].parent.parent...
PARENTS = re.compile(r"__file__\)(?:\.resolve\(\)|\.absolute\(\))?\.parents\[(\d+)\]")
PARENT_CHAIN = re.compile(r"__file__\)(?:\.resolve\(\)|\.absolute\(\))?((?:\.parent\b)+)")


def hydra_imports(text: str) -> list[str]:
    return [m.group(0).strip() for m in HYDRA.finditer(text)]


def climbs_out(text: str, depth: int) -> list[str]:
    """Paths built from __file__ that reach the package's parent folder or above; depth: the
    folders between the package root and the file (mocap/x.py: 1, mocap/a/x.py: 2)."""
    bad = [m.group(0) for m in PARENTS.finditer(text) if int(m.group(1)) >= depth]
    bad += [m.group(0) for m in PARENT_CHAIN.finditer(text) if m.group(1).count(".parent") > depth]
    return bad


def library_files() -> list[Path]:
    return sorted(p for p in LIBRARY.rglob("*.py") if "__pycache__" not in p.parts)


def test_the_checks_find_what_they_look_for():
    text = "import hydra\nfrom omegaconf import OmegaConf\n    from hydra.utils import x\n"
    assert hydra_imports(text) == ["import hydra", "from omegaconf", "from hydra."]
    assert hydra_imports("# hydra.searchpath: [pkg://mocap.presets]\nx = hydra_dir\n") == []
    # mocap/a/x.py: parents[1] is mocap/ (package data), parents[2] the repository
    assert climbs_out("Path(__file__).resolve().parents[1] / 'clips'", depth=2) == []
    assert climbs_out("REPO = Path(__file__).resolve().parents[2]", depth=2)
    assert climbs_out("Path(__file__).parent.parent / 'assets'", depth=2) == []
    assert climbs_out("Path(__file__).resolve().parent.parent.parent", depth=2)
    assert climbs_out("body.parents[j]", depth=1) == []


def test_no_hydra_or_omegaconf_import_in_the_library():
    found = {str(p.relative_to(REPO)): hydra_imports(p.read_text()) for p in library_files()}
    assert {k: v for k, v in found.items() if v} == {}


def test_no_path_in_the_library_leaves_the_package():
    found = {}
    for p in library_files():
        depth = len(p.relative_to(LIBRARY).parts)
        found[str(p.relative_to(REPO))] = climbs_out(p.read_text(), depth)
    assert {k: v for k, v in found.items() if v} == {}

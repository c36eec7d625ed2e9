"""Metadata that makes a run traceable: git revision, config hash, host."""

from __future__ import annotations

import hashlib
import platform
import subprocess
import uuid
from pathlib import Path


def git_revision(repo: Path | None) -> str:
    """The git revision of the checkout ``repo`` (``+dirty`` with uncommitted changes);
    "unknown" when ``repo`` is None or not a checkout."""
    if repo is None:
        return "unknown"
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True,
                             text=True, timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=repo,
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return (rev + ("+dirty" if dirty else "")) if rev else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def run_metadata(config_yaml: str, repo: Path | None, seed: int, **extra) -> dict:
    return {"run_id": uuid.uuid4().hex, "git_revision": git_revision(repo), "seed": seed,
            "config_hash": hashlib.sha1(config_yaml.encode()).hexdigest()[:12],
            "host": platform.node(), **extra}

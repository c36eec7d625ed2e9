"""What the safety tests compare: a folder tree listed with every entry's kind, size and checksum."""

from __future__ import annotations

import hashlib
from pathlib import Path


def tree(root: Path) -> dict[str, tuple]:
    """Every entry below ``root`` (relative path -> ("dir",) / ("link", target) /
    ("file", bytes, sha256)); symbolic links are listed, never followed."""
    out: dict[str, tuple] = {}
    for p in sorted(Path(root).rglob("*")):
        rel = str(p.relative_to(root))
        if p.is_symlink():
            out[rel] = ("link", str(p.readlink()))
        elif p.is_dir():
            out[rel] = ("dir",)
        else:
            data = p.read_bytes()
            out[rel] = ("file", len(data), hashlib.sha256(data).hexdigest())
    return out

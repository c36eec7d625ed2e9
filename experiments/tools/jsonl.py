"""One measured row reported the way the diagnosis scripts do: its summary line printed, the row
appended to a JSON-lines file when one is given."""

from __future__ import annotations

import json
from pathlib import Path


def report(row: dict, line: str, out: Path | None) -> None:
    """Print ``line``; with ``out``, append ``row`` to it as one JSON line."""
    print(line, flush=True)
    if out:
        with open(out, "a") as fh:
            fh.write(json.dumps(row) + "\n")

"""The export tests use the session's ``short_run`` (tests/conftest.py)."""

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

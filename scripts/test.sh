#!/usr/bin/env bash
# The test command: installs what it needs (first run), then runs the test suite.
# Extra arguments go to pytest (e.g. `bash scripts/test.sh tests/body -x`). The suite runs on every
# core (pytest-xdist: one worker per core, each test file kept on one worker so its module-scoped
# fixtures are built once, the longest files first: tests/file_durations.json, refreshed by
# `--store-durations`); `-n 0` runs it in one process, `-m "not slow"` skips the slow tests.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
.venv/bin/ruff check mocap mocap_cli experiments tests benchmarks
exec .venv/bin/pytest -n auto --dist loadfile --no-loadscope-reorder "$@"

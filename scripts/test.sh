#!/usr/bin/env bash
# The test command: installs what it needs (first run), then runs the test suite.
# Extra arguments go to pytest (e.g. `bash scripts/test.sh tests/body -x`).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
.venv/bin/ruff check mocap mocap_cli experiments tests benchmarks
exec .venv/bin/pytest "$@"

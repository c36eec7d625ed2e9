#!/usr/bin/env bash
# The main job: installs what it needs (first run), then runs the default experiment on the
# built-in synthetic data and writes its .rrd recording(s) and metrics under outputs/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
exec .venv/bin/python experiments/show_body.py "$@"

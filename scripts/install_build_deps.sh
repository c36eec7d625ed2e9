#!/usr/bin/env bash
# Installs the optional model-building dependencies (the `build` extra: torch 2.13.0 CPU,
# anny and its needs) into .venv-build, a separate environment so the runtime .venv stays
# light. anny is installed without its hard dependency on warp-lang (NVIDIA Warp), which
# the build does not use (it skins with plain LBS).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export UV_PYTHON_DOWNLOADS=never
uv() { .venv/bin/uv "$@"; }
PY="${PYTHON:-python3.11}"; command -v "$PY" >/dev/null || PY=python3
[ -x .venv-build/bin/python ] || uv venv -q --python "$PY" .venv-build
uv pip sync -q --python .venv-build/bin/python requirements.lock
uv pip install -q --python .venv-build/bin/python --no-deps --config-settings editable_mode=compat -e .
TORCH_WHEEL=$(ls /opt/wheels/torch-2.13.0*cp311*.whl 2>/dev/null | head -n1 || true)
if [ -n "$TORCH_WHEEL" ]; then
  uv pip install -q --python .venv-build/bin/python "$TORCH_WHEEL"
else
  # No local CPU wheel: use whatever torch==2.13.0 the configured index serves. On
  # PyPI that is a CUDA build of several GB; point UV_INDEX at a CPU index to avoid it.
  echo "[build-deps] no local torch 2.13.0 CPU wheel in /opt/wheels; installing torch==2.13.0 from the index" >&2
  uv pip install -q --python .venv-build/bin/python torch==2.13.0
fi
uv pip install -q --python .venv-build/bin/python "roma>=1.7.1" safetensors pyyaml pillow requests "fast-simplification>=0.1.7" "rtree>=1.0"
uv pip install -q --python .venv-build/bin/python --no-deps anny==0.6.2
echo "[build-deps] ready: .venv-build/bin/python -m mocap_cli build-body-model --anny 600"

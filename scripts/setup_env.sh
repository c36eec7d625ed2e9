#!/usr/bin/env bash
# Installs everything mocap needs on a fresh Debian/Ubuntu machine with Python 3.11:
# the EGL/Mesa libraries pyrender renders with (headless), uv, and a virtual environment
# in .venv synced to requirements.lock. Safe to run again: each step is skipped when done.
# Usage: source scripts/setup_env.sh   (or bash scripts/setup_env.sh)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

EGL_PKGS="libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libopengl0"
missing=""
for p in $EGL_PKGS; do
  dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    echo "[setup] installing system packages:$missing"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing >/dev/null
  elif command -v sudo >/dev/null && command -v apt-get >/dev/null; then
    sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing >/dev/null
  else
    echo "[setup] WARNING: cannot install$missing (not root, no sudo): RGB rendering with pyrender will be unavailable" >&2
  fi
fi

PY="${PYTHON:-python3.11}"
command -v "$PY" >/dev/null || PY=python3
if ! command -v uv >/dev/null; then
  echo "[setup] installing uv"
  "$PY" -m pip install -q --user uv 2>/dev/null || "$PY" -m pip install -q uv
  export PATH="$HOME/.local/bin:$PATH"
fi
export UV_PYTHON_DOWNLOADS=never
stamp=".venv/.synced-$(sha1sum requirements.lock pyproject.toml | sha1sum | cut -c1-12)"
if [ ! -f "$stamp" ]; then
  echo "[setup] creating .venv (first run takes about a minute)"
  [ -x .venv/bin/python ] || uv venv -q --python "$PY" .venv
  uv pip sync -q --python .venv/bin/python requirements.lock
  uv pip install -q --python .venv/bin/python --no-deps --config-settings editable_mode=compat -e .
  rm -f .venv/.synced-*; touch "$stamp"
  .venv/bin/rerun analytics disable >/dev/null 2>&1 || true
fi

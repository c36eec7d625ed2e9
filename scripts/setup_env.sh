#!/usr/bin/env bash
# Installs everything mocap needs on a fresh Debian/Ubuntu machine: Python 3.11 with venv
# (from the system's packages if missing), the EGL/Mesa libraries pyrender renders with
# (headless), xvfb + Mesa Vulkan for the headless Rerun viewer test, and a virtual
# environment in .venv holding uv and the locked dependencies (requirements.lock), plus the
# optional detector of `mocap detect` (requirements-detect.txt, without its declared
# dependencies). Safe to run again: each step is skipped when done.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

as_root() {
  if [ "$(id -u)" = "0" ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi
}
apt_install() {
  command -v apt-get >/dev/null || return 1
  as_root apt-get update -qq && as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}

PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do command -v "$cand" >/dev/null && { PY="$cand"; break; }; done
fi
if [ -z "$PY" ] || ! "$PY" -c 'import venv, ensurepip' 2>/dev/null; then
  echo "[setup] installing Python 3 with venv from the system packages"
  apt_install python3 python3-venv python3-pip || { echo "[setup] ERROR: need Python 3.11 with venv" >&2; exit 1; }
  PY="${PY:-python3}"
fi
"$PY" -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' 2>/dev/null \
  || echo "[setup] WARNING: $("$PY" --version) found; mocap is tested on Python 3.11" >&2

EGL_PKGS="libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libopengl0"
missing=""
for p in $EGL_PKGS; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  echo "[setup] installing system packages:$missing"
  apt_install $missing || echo "[setup] WARNING: could not install$missing: RGB rendering with pyrender will be unavailable" >&2
fi

# the real Rerun viewer, headless (tests/recording/test_viewer_shows_body.py): a virtual X
# server and Mesa's Vulkan software rasteriser (the viewer's GL renderer fails on llvmpipe)
VIEWER_PKGS="xvfb mesa-vulkan-drivers libvulkan1"
missing=""
for p in $VIEWER_PKGS; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  echo "[setup] installing system packages:$missing"
  apt_install $missing || echo "[setup] WARNING: could not install$missing: the headless viewer test will be skipped" >&2
fi

export UV_PYTHON_DOWNLOADS=never
stamp=".venv/.synced-$(cat requirements.lock requirements-detect.txt pyproject.toml | sha1sum | cut -c1-12)"
if [ ! -f "$stamp" ]; then
  echo "[setup] creating .venv (the first run takes a minute or two)"
  [ -x .venv/bin/python ] || "$PY" -m venv .venv
  [ -x .venv/bin/uv ] || .venv/bin/python -m pip install -q uv
  .venv/bin/uv pip install -q --python .venv/bin/python -r requirements.lock
  .venv/bin/uv pip install -q --python .venv/bin/python --no-deps --config-settings editable_mode=compat -e .
  # the detector (mediapipe's legacy pose solution): its declared jax / opencv-contrib are not needed
  .venv/bin/uv pip install -q --python .venv/bin/python --no-deps -r requirements-detect.txt \
    || echo "[setup] WARNING: could not install requirements-detect.txt: mocap detect and its tests are unavailable" >&2
  # bytecode compiled now, once, not by every process that starts: where PYTHONDONTWRITEBYTECODE=1
  # (containers, CI) nothing is cached and each `mocap` would compile its modules again (issue 38).
  # Exit status ignored: a few files shipped inside packages are not Python 3 source.
  .venv/bin/python -m compileall -q -j 0 "$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" \
    >/dev/null 2>&1 || true
  rm -f .venv/.synced-*; touch "$stamp"
  .venv/bin/rerun analytics disable >/dev/null 2>&1 || true
fi
# the project's own bytecode (a no-op when up to date; a checkout's edited files are recompiled)
.venv/bin/python -m compileall -q -j 0 mocap mocap_cli >/dev/null \
  || echo "[setup] WARNING: mocap did not compile to bytecode" >&2
# the compiled kernels, built once on every core into numba's cache (mocap/kernel_cache.py): the first
# run and the test suite's workers then load them instead of each compiling the same ones (a no-op
# load of a few seconds when built; a stale entry of the list is skipped, compiled at first call)
.venv/bin/python -m mocap.kernel_cache \
  || echo "[setup] WARNING: the kernels were not built ahead; each is compiled at its first call" >&2

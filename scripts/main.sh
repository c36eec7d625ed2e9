#!/usr/bin/env bash
# The main job: installs what it needs (first run), then runs the mission's comparison of
# trackers on the built-in synthetic data (small enough for a laptop: 4 views at 320x240,
# 20 frames of walking), writes each run's recording.rrd and metrics.json, and prints the
# ablation table. Extra arguments are Hydra overrides for every run (e.g. data=walk_mpi08).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
SWEEP="outputs/main/$(date +%Y-%m-%d_%H-%M-%S)"
TRACKERS="${TRACKERS:-apf,apf_prior,apf_25x10}"
.venv/bin/python experiments/track.py --multirun "tracker=$TRACKERS" data=walk_small seed=0 \
  "hydra.sweep.dir=$SWEEP" "$@"
.venv/bin/python experiments/ablate.py "$SWEEP" \
  --title "Tracker comparison (synthetic walking, 4 views, 20 frames)"
echo
echo "recordings (open with: .venv/bin/rerun <file>, or python experiments/replay.py <run dir>):"
find "$SWEEP" -name recording.rrd | sort | sed 's/^/  /'

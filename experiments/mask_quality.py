"""Question: which segmentation method gives the best silhouettes on real video, measured
against hand-checked reference masks?

Mask quality on the Pose2Sim demo: IoU of each segmentation method against the hand-checked
reference silhouettes in tests/data/pose2sim_demo_reference (see experiments/reference_masks.py).

    python experiments/mask_quality.py [demo folder] [out.json]

Every method segments source frames 0:100:2 at 272x480 (the background models see those 50
frames; no background clip exists for this recording) and is scored on the reference frames.
Prints a table and writes it as JSON (default outputs/mask_quality.json).
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np

from mocap.video.segmentation import iou, segment_sequence
from mocap.video.sequence import load_video_sequence

REPO = Path(__file__).resolve().parents[1]
REF = REPO / "tests" / "data" / "pose2sim_demo_reference"

#: reference frames left out while the segmentation's settings were developed (frames 0, 40, 80)
HELD_OUT = (20, 60)

METHODS = {
    "median": dict(method="median", keypoints=False),
    "mog2": dict(method="mog2", keypoints=False),
    "knn": dict(method="knn", keypoints=False),
    "median + keypoint clean-up": dict(method="median"),
    "keypoint GrabCut (median bg)": dict(method="keypoint_grabcut", background="median"),
    "keypoint GrabCut (masked median bg)": dict(method="keypoint_grabcut", background="masked_median"),
    "keypoint GrabCut (no bg model)": dict(method="keypoint_grabcut", background="none"),
    "keypoint GrabCut (masked median) + multi-view": dict(method="keypoint_grabcut",
                                                          background="masked_median", multiview=True),
}


def load_reference(names, frames) -> np.ndarray:
    """(R, C, H, W) bool reference masks of the source ``frames``."""
    return np.stack([[cv2.imread(str(REF / f"{cam}_{n:04d}.png"), cv2.IMREAD_GRAYSCALE) > 127
                      for cam in names] for n in frames])


def main(path: str = str(REPO.parent / "shared" / "data" / "pose2sim-demo"),
         out: str = "outputs/mask_quality.json") -> dict:
    ann = json.loads((REF / "annotations.json").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = load_video_sequence(path, start=0, stop=100, step=2, scale=ann["scale"])
    src = seq.meta["source_frames"]
    idx = [src.index(n) for n in ann["frames"]]
    ref = load_reference(seq.rig.names, ann["frames"])
    table = {}
    for name, kw in METHODS.items():
        res = segment_sequence(seq, **kw)
        scores = np.array([[iou(res.masks[i, c], ref[r, c]) for c in range(seq.num_views)]
                           for r, i in enumerate(idx)])
        held = [r for r, n in enumerate(ann["frames"]) if n in HELD_OUT]
        dev = [r for r in range(len(idx)) if r not in held]
        table[name] = {"iou_mean": float(scores.mean()), "iou_min": float(scores.min()),
                       "iou_dev": float(scores[dev].mean()), "iou_held_out": float(scores[held].mean()),
                       "iou_per_view": dict(zip(seq.rig.names, scores.mean(0).round(4).tolist(),
                                                strict=True)),
                       "ms_per_frame_per_view": 1000 * res.info["seconds_per_frame_per_view"],
                       "settings": res.info}
        print(f"{name:48s} IoU {scores.mean():.3f} (min {scores.min():.3f}, dev {scores[dev].mean():.3f}, "
              f"held out {scores[held].mean():.3f}, per view "
              f"{' '.join(f'{s:.3f}' for s in scores.mean(0))}), "
              f"{1000 * res.info['seconds_per_frame_per_view']:.0f} ms/frame/view", flush=True)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps({"resolution": list(seq.image_size), "frames": ann["frames"],
                                     "methods": table}, indent=2))
    return table


if __name__ == "__main__":
    main(*sys.argv[1:])

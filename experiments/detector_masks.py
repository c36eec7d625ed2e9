"""Question: does the built-in detector's person mask, alone or combined with GrabCut, a
background model and multi-view carving, beat today's silhouettes on real video?

Mask quality of `mocap detect`'s masks on the Pose2Sim demo against the hand-checked reference
(tests/data/pose2sim_demo_reference: 5 frames x 4 views at 272x480; experiments/reference_masks.py).

    mocap detect ../shared/data/pose2sim-demo --out outputs/detect/demo_0_100_2 --stop 100 --step 2
    python -m experiments.detector_masks outputs/detect/demo_0_100_2 [out.json]

Source frames 0:100:2 (the background model sees those 50 frames, as in
experiments/mask_quality.py) at 272x480; the detector's keypoints guide GrabCut and carving. Prints
mean / min IoU per method and the combination's time per frame per view (detection excluded:
detect.json has it), and writes them as JSON (default outputs/detector_masks.json).
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from experiments.mask_quality import REF, load_reference
from mocap.video.detect import read_masks
from mocap.video.person_masks import combine_masks
from mocap.video.segmentation import iou, keypoint_dict, segment_sequence
from mocap.video.sequence import load_video_sequence

METHODS = {
    "detector (probability >= 0.5)": None,
    "detector + clean-up": dict(grabcut=False),
    "detector + GrabCut": dict(),
    "detector + GrabCut + masked-median background": dict(background="masked_median"),
    "detector + GrabCut + multi-view carving": dict(multiview=True),
    "detector + GrabCut + background + carving": dict(background="masked_median", multiview=True),
}


def main(folder: str, out: str = "outputs/detector_masks.json") -> dict:
    ann = json.loads((REF / "annotations.json").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = load_video_sequence(folder, keypoints="pose", layout="auto", start=0, stop=100, step=2,
                                  scale=ann["scale"])
    names, src = list(seq.rig.names), seq.meta["source_frames"]
    idx = [src.index(n) for n in ann["frames"]]
    ref = load_reference(names, ann["frames"])
    prob = read_masks(Path(folder) / "masks", names, src, seq.image_size, probability=True)
    images = np.stack([np.asarray(seq.images[f]) for f in range(seq.num_frames)])
    kps = [[keypoint_dict(seq.detections.select(f, c), 0.3) for c in range(seq.num_views)]
           for f in range(seq.num_frames)]
    rows = {}
    for name, cfg in METHODS.items():
        t0 = time.perf_counter()
        if cfg is None:
            masks = prob[idx] >= 0.5
        else:
            use = idx if cfg.get("background", "none") == "none" else list(range(len(src)))
            masks = combine_masks(images[use], prob[use], [kps[i] for i in use], seq.rig, **cfg)
            masks = masks if use == idx else masks[idx]
        rows[name] = (masks, (time.perf_counter() - t0) / (len(cfg and use or idx) * seq.num_views))
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seg = segment_sequence(seq, method="keypoint_grabcut", background="masked_median", multiview=True)
    rows["keypoint GrabCut + masked median + carving (segment, detector keypoints)"] = (
        seg.masks[idx], (time.perf_counter() - t0) / (seq.num_frames * seq.num_views))
    table = {}
    print("| method | mean IoU | min IoU | per view (cam 01 / 02 / 03 / 04) | ms per frame per view |")
    print("|---|---|---|---|---|")
    for name, (masks, sec) in rows.items():
        v = np.array([[iou(masks[k, c], ref[k, c]) for c in range(len(names))] for k in range(len(idx))])
        table[name] = {"mean_iou": float(v.mean()), "min_iou": float(v.min()),
                       "per_view": v.mean(0).round(4).tolist(), "seconds_per_frame_per_view": sec}
        per = " / ".join(f"{x:.3f}" for x in v.mean(0))
        print(f"| {name} | {v.mean():.3f} | {v.min():.3f} | {per} | {1000 * sec:.0f} |")
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(table, indent=1))
    return table


if __name__ == "__main__":
    main(*sys.argv[1:])

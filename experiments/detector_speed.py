"""Question: how long does the built-in detector take per frame and view, at the videos' full
resolution and at the tracked resolution?

    python -m experiments.detector_speed [demo folder] [--frames 30] [--scale 0.25]

Decodes the first ``frames`` frames of every view once, then times PoseDetector (one per
view, tracking mode, segmentation on) on the same frames at full resolution and downscaled by
``scale``, alternating the two per view so that both see the same machine load. Prints the
median and mean ms per frame per view (decoding excluded) and whether the person was found.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

from mocap.video.detector import PoseDetector
from mocap.video.sequence import load_video_sequence

DEMO = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "pose2sim-demo"


def time_view(images: np.ndarray) -> tuple[list[float], int]:
    times, found = [], 0
    with PoseDetector() as det:
        for img in images:
            t0 = time.perf_counter()
            found += det(img).found
            times.append(time.perf_counter() - t0)
    return times[1:], found                        # the first call builds the graph


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("demo", type=Path, nargs="?", default=DEMO)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--scale", type=float, default=0.25)
    args = ap.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = load_video_sequence(args.demo, keypoints=None, stop=args.frames)
    full = {"times": [], "found": 0}
    small = {"times": [], "found": 0}
    size = None
    for c in range(seq.num_views):
        imgs = np.stack([np.asarray(seq.images[f, c]) for f in range(args.frames)])
        h, w = imgs.shape[1:3]
        size = (round(w * args.scale), round(h * args.scale))
        down = np.stack([cv2.resize(im, size, interpolation=cv2.INTER_AREA) for im in imgs])
        for res, batch in ((full, imgs), (small, down)):
            t, k = time_view(batch)
            res["times"] += t
            res["found"] += k
    out = {}
    for label, res, (w, h) in (("full", full, seq.image_size), ("scaled", small, size)):
        ms = 1000 * np.array(res["times"])
        out[label] = {"size": [w, h], "median_ms": float(np.median(ms)), "mean_ms": float(ms.mean()),
                      "found": res["found"], "images": args.frames * seq.num_views}
        print(f"{w}x{h}: median {np.median(ms):.0f} ms, mean {ms.mean():.0f} ms per frame per view; person "
              f"found in {res['found']}/{args.frames * seq.num_views} images")
    return out


if __name__ == "__main__":
    main()

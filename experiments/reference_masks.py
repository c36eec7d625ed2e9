"""Question: what are the subject's true silhouettes on the Pose2Sim demo frames (the
reference mask_quality.py scores against)?

Hand-checked reference silhouettes of the Pose2Sim demo, made by assisted labelling.

    python experiments/reference_masks.py                # masks + overlays from annotations.json
    python experiments/reference_masks.py /path/to/pose2sim-demo cam_02_0040   # one item only

``tests/data/pose2sim_demo_reference/annotations.json`` holds, per (camera, source frame), the
subject's outline traced by hand as a polygon (``poly``, in pixels of the 272x480 output, read
off zoomed frames with a coordinate grid) and, where the first result was wrong, hand-placed
strokes (``fg`` / ``bg`` polylines with a thickness) and filled background areas
(``bg_poly``). GrabCut (OpenCV, 8 iterations) runs on the frame at twice that resolution
(544x960): inside the polygon shrunk by ``band`` px is sure foreground, outside it grown by
``band`` px sure background, GrabCut decides the band, the
strokes and areas override it. The result is downscaled (area > 0.5) to 272x480 and saved as
``<camera>_<frame>.png`` (0 / 255); overlays go to outputs/pose2sim_demo_reference_overlays.
Polygons, strokes and areas were placed and corrected by looking at zoomed overlays of each
result until the outline followed the subject (20 masks: frames 0, 20, 40, 60, 80 x 4 views).
No keypoints, no background model and none of mocap.video.segmentation's code are involved.
A later check of the overlays found three shins left out (cam_02_0040, cam_03_0060,
cam_04_0060: thin limbs the first polygon missed); each got its own outline polygon.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np

from mocap.video.sequence import load_video_sequence

REPO = Path(__file__).resolve().parents[1]
REF = REPO / "tests" / "data" / "pose2sim_demo_reference"
OVERLAYS = REPO / "outputs" / "pose2sim_demo_reference_overlays"


def reference_mask(image: np.ndarray, item: dict, up: int, iterations: int = 8) -> np.ndarray:
    """(H, W) bool at the output resolution from ``image`` (H*up, W*up, 3) RGB and one annotation."""
    Hu, Wu = image.shape[:2]
    gc = np.full((Hu, Wu), cv2.GC_BGD, np.uint8)
    if "poly" in item:                                   # a hand-traced outline, refined in a band
        inside = np.zeros((Hu, Wu), np.uint8)
        for poly in item["poly"]:
            cv2.fillPoly(inside, [((np.array(poly, float) + 0.5) * up - 0.5).round().astype(np.int32)], 1)
        band = max(1, int(item.get("band", 4) * up))
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band + 1, 2 * band + 1))
        core, grown = cv2.erode(inside, k), cv2.dilate(inside, k)
        gc[grown > 0] = cv2.GC_PR_BGD
        gc[inside > 0] = cv2.GC_PR_FGD
        gc[core > 0] = cv2.GC_FGD
        ys, xs = np.nonzero(grown)
        x0, y0, x1, y1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
    else:                                                # a rectangle (GrabCut's own mode)
        x0, y0, x1, y1 = (int(v * up) for v in item["rect"])   # (kept for rectangle-only items)
        gc[y0:y1, x0:x1] = cv2.GC_PR_FGD
    for key, value in (("maybe_bg", cv2.GC_PR_BGD), ("bg_poly", cv2.GC_BGD)):   # areas judged background
        for poly in item.get(key, []):
            cv2.fillPoly(gc, [(np.array(poly, float).reshape(-1, 2) * up).astype(np.int32)], int(value))
    for kind, value in (("bg", cv2.GC_BGD), ("fg", cv2.GC_FGD)):
        for stroke in item.get(kind, []):
            *pts, thick = stroke
            pts = (np.array(pts, float).reshape(-1, 2) * up).astype(np.int32)
            cv2.polylines(gc, [pts], False, int(value), max(1, int(thick * up)))
            if len(pts) == 1:
                cv2.circle(gc, tuple(pts[0]), max(1, int(thick * up)), int(value), -1)
    pad = 16 * up                                        # GrabCut on the rectangle plus a margin
    cx0, cy0, cx1, cy1 = max(0, x0 - pad), max(0, y0 - pad), min(Wu, x1 + pad), min(Hu, y1 + pad)
    crop = np.ascontiguousarray(gc[cy0:cy1, cx0:cx1])
    bgd, fgd = np.zeros((1, 65)), np.zeros((1, 65))
    cv2.grabCut(np.ascontiguousarray(image[cy0:cy1, cx0:cx1, ::-1]), crop, None, bgd, fgd, iterations,
                cv2.GC_INIT_WITH_MASK)
    gc[cy0:cy1, cx0:cx1] = crop
    fg = ((gc == cv2.GC_FGD) | (gc == cv2.GC_PR_FGD)).astype(np.float32)
    small = cv2.resize(fg, (Wu // up, Hu // up), interpolation=cv2.INTER_AREA) > 0.5
    return small


def overlay(image: np.ndarray, mask: np.ndarray, item: dict) -> np.ndarray:
    img = image.copy()
    img[mask] = (0.55 * img[mask] + [0, 110, 0]).astype(np.uint8)
    cnts, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(img, cnts, -1, (255, 0, 0), 1)
    if "poly" not in item:
        x0, y0, x1, y1 = item["rect"]
        cv2.rectangle(img, (x0, y0), (x1, y1), (255, 255, 0), 1)
    for kind, colour in (("fg", (255, 0, 255)), ("bg", (0, 255, 255))):
        for stroke in item.get(kind, []):
            *pts, thick = stroke
            cv2.polylines(img, [np.array(pts, np.int32).reshape(-1, 2)], False, colour, 1)
    return img


def grid(img: np.ndarray, step: int = 40) -> np.ndarray:
    """Grid lines every ``step`` px with their coordinates (for placing strokes by eye)."""
    img = img.copy()
    H, W = img.shape[:2]
    for x in range(step, W, step):
        img[:, x] = (0.5 * img[:, x] + [127, 127, 127]).astype(np.uint8)
        cv2.putText(img, str(x), (x + 1, 8), cv2.FONT_HERSHEY_PLAIN, 0.6, (255, 255, 255), 1)
    for y in range(step, H, step):
        img[y] = (0.5 * img[y] + [127, 127, 127]).astype(np.uint8)
        cv2.putText(img, str(y), (1, y - 1), cv2.FONT_HERSHEY_PLAIN, 0.6, (255, 255, 255), 1)
    return img


def main(path: str = str(REPO.parent / "shared" / "data" / "pose2sim-demo"), only: str | None = None) -> None:
    ann = json.loads((REF / "annotations.json").read_text())
    up = int(ann["upsample"])
    frames = ann["frames"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        step = frames[1] - frames[0]
        seq = load_video_sequence(path, keypoints=None, start=min(frames), stop=max(frames) + 1,
                                  step=step, scale=ann["scale"])
        big = load_video_sequence(path, keypoints=None, start=min(frames), stop=max(frames) + 1,
                                  step=step, scale=ann["scale"] * up)
    OVERLAYS.mkdir(parents=True, exist_ok=True)
    for f, n in enumerate(frames):
        tiles = []
        for c, cam in enumerate(seq.rig.names):
            key = f"{cam}_{n:04d}"
            if only and only not in key:
                continue
            item = ann["items"][key]
            m = reference_mask(big.images[f, c], item, up)
            cv2.imwrite(str(REF / f"{key}.png"), m.astype(np.uint8) * 255)
            tiles.append(grid(overlay(seq.images[f, c], m, item)))
        if tiles:
            sheet = np.hstack(tiles)
            sheet = cv2.resize(sheet, (sheet.shape[1] * 2, sheet.shape[0] * 2),
                               interpolation=cv2.INTER_NEAREST)
            name = f"{n:04d}.png" if not only else f"{only}.png"
            cv2.imwrite(str(OVERLAYS / name), sheet[..., ::-1])


if __name__ == "__main__":
    main(*sys.argv[1:])

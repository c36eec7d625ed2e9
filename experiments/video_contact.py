"""Question: where, in the images, does a video-check run's body miss the subject (its worst
frame by reprojection error)?

Contact sheet of a ``mocap video-check`` run: per view, the video frame, its mask, and the video with
the tracked body projected on it (filled outline) plus the confident keypoints (green) and the
body's landmarks (red; with the keypoint-to-joint offsets of the run's metrics.json).

    python experiments/video_contact.py multirun/video_check_demo_0_40_2/hybrid [frame ...] [--out x.png]

Frames are indices into the run's selection (default: the worst frame by the offset-corrected
reprojection error, and frame 0 when that is another one).
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mocap.body.catalogue import make_landmark_set  # noqa: E402
from mocap.cameras import project  # noqa: E402
from mocap.export.motion import load_motion  # noqa: E402
from mocap.render import rasterize_silhouettes  # noqa: E402
from mocap.run_folder import run_body, run_sequence  # noqa: E402


def main(argv: list[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("frames", type=int, nargs="*")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--full", action="store_true", help="whole images (default: zoom on the mask)")
    args = ap.parse_args(argv)
    m = json.loads((args.run / "metrics.json").read_text())
    cfg = m["config"]
    body = run_body(cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = run_sequence(cfg, body)
    motion = load_motion(args.run / "motion.npz")
    chis, shaped = motion.chi, body.shaped(motion.alpha[-1])
    per_frame = m["reprojection"]["fitted_per_frame_px"]
    frames = args.frames or sorted({0, int(np.nanargmax(per_frame))})
    det = seq.detections
    lms = make_landmark_set(body, "auto", det.labels)
    offsets = np.array([m["reprojection"]["offsets_m"][n] for n in lms.names])
    min_conf = cfg["check"]["min_confidence"]
    C = len(seq.rig)
    fig, axes = plt.subplots(len(frames) * C, 3, figsize=(7.5, 5.3 * C * len(frames)), squeeze=False)
    for i, t in enumerate(frames):
        out = shaped.pose(chis[t])
        verts = out.vertices[0].astype(np.float64)
        X = lms.positions(shaped, chis[t:t + 1]).astype(np.float64)[0] + offsets
        px_v, depth = project(seq.rig, verts, return_depth=True)
        H, W = seq.masks.shape[-2:]
        sil = rasterize_silhouettes(px_v, body.faces, H, W, depth, near=0.05)
        px_l = project(seq.rig, X)
        d = det.select(t)
        for c in range(C):
            img, mask = seq.images[t][c], seq.masks[t][c]
            inter, union = (sil[c] & mask).sum(), (sil[c] | mask).sum()
            row = axes[i * C + c]
            row[0].imshow(img)
            row[0].set_title(f"{seq.rig.names[c]} frame {t} (source {m['source_frames'][t]})", fontsize=8)
            row[1].imshow(mask, cmap="gray")
            row[1].set_title("mask", fontsize=8)
            over = img.astype(float) / 255.0
            over[sil[c]] = 0.55 * over[sil[c]] + 0.45 * np.array([0.2, 0.4, 1.0])
            row[2].imshow(over)
            row[2].contour(mask, levels=[0.5], colors="yellow", linewidths=0.6)
            keep = (d.view == c) & (d.confidence >= min_conf) & (d.label >= 0)
            row[2].scatter(d.xy[keep, 0], d.xy[keep, 1], s=6, c="lime", label="keypoints")
            row[2].scatter(px_l[c, :, 0], px_l[c, :, 1], s=10, c="red", marker="x", linewidths=0.8,
                           label="body landmarks + offsets")
            row[2].set_title(f"{m['tracker']}: body blue, mask yellow\nIoU {inter / max(union, 1):.2f}, "
                             f"frame median {per_frame[t]:.0f} px (all views)", fontsize=7)
            x0, x1, y0, y1 = 0, W, 0, H
            if not args.full and (mask | sil[c]).any():
                ys, xs = np.nonzero(mask | sil[c])
                pad = 0.1 * (ys.max() - ys.min())
                x0, x1 = max(0, xs.min() - pad), min(W, xs.max() + pad)
                y0, y1 = max(0, ys.min() - pad), min(H, ys.max() + pad)
            for ax in row:
                ax.set_axis_off()
                ax.set_xlim(x0, x1)
                ax.set_ylim(y1, y0)
    axes[0][2].legend(fontsize=6, loc="lower right")
    fig.tight_layout()
    path = args.out or args.run / f"contact_{'_'.join(map(str, frames))}.png"
    fig.savefig(path, dpi=110)
    print(path)
    return path


if __name__ == "__main__":
    main()

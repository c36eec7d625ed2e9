"""Question: tracked from `mocap detect`'s keypoints and masks only, how well does the body fit
the Pose2Sim demo's shipped OpenPose keypoints (which the tracker never saw)?

    python -m experiments.detector_end_to_end RUN [RUN ...] [--demo ../shared/data/pose2sim-demo]
        [--contact RUN --frame 0 --out contact.png]

For each run folder (``mocap track``): the median reprojection error (px, full resolution
1088x1920) of the tracked body's landmarks (the marker tracker's landmark set for the
OpenPose labels, as in metrics.json) against the demo's shipped BODY_25B keypoints of the
subject, over all views and per view, on the run's source frames. ``--contact``: a contact
sheet of one run (per view: video | mask | body projected onto the video with the shipped
keypoints in green).
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
from mocap.cameras import load_calibration, project  # noqa: E402
from mocap.data.openpose import load_openpose_sequence  # noqa: E402
from mocap.eval.keypoint_metrics import keypoint_metrics  # noqa: E402
from mocap.export.motion import load_motion  # noqa: E402
from mocap.render import rasterize_silhouettes  # noqa: E402
from mocap.run_folder import run_body, run_sequence  # noqa: E402
from mocap.video.sequence import rescale_detections  # noqa: E402

DEMO = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "pose2sim-demo"


def source_frames(config: dict, frames: int) -> list[int]:
    data = config["data"]
    start, step = int(data.get("start") or 0), int(data.get("step") or 1)
    return [start + step * i for i in range(frames)]


def against_openpose(run: Path, demo: Path) -> dict:
    """keypoint_metrics of the run's body landmarks against the shipped keypoints."""
    config = json.loads((run / "metrics.json").read_text())["config"]
    body = run_body(config)
    motion = load_motion(run)
    shipped = load_openpose_sequence(demo, layout="auto")
    rig = load_calibration(shipped.meta["calibration"])
    frames = source_frames(config, motion.num_frames)
    det = rescale_detections(shipped.detections, [n - shipped.meta["first_frame"] for n in frames], 1.0, 1.0)
    lms = make_landmark_set(body, "auto", det.labels)
    X = lms.positions(body.shaped(motion.alpha[-1]), motion.chi).astype(np.float64)
    out = keypoint_metrics(rig, X, lms.names, det)
    return {"run": str(run), "tracker": config.get("tracker", {}).get("name", "?"), "frames": len(frames),
            "median_px": out["reprojection_median_px"], "per_view": out["reprojection_median_px_per_view"],
            "lost": int(np.sum(motion.per_frame.get("lost", 0)))}


def contact_sheet(run: Path, demo: Path, frame: int, out: Path) -> Path:
    config = json.loads((run / "metrics.json").read_text())["config"]
    body = run_body(config)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seq = run_sequence(config, body)
    motion = load_motion(run)
    shaped = body.shaped(motion.alpha[-1])
    verts = shaped.pose(motion.chi[frame]).vertices[0].astype(np.float64)
    px, depth = project(seq.rig, verts, return_depth=True)
    H, W = seq.masks.shape[-2:]
    sil = rasterize_silhouettes(px, body.faces, H, W, depth, near=0.05)
    shipped = load_openpose_sequence(demo, layout="auto")
    n = source_frames(config, motion.num_frames)[frame]
    sx = W / float(load_calibration(shipped.meta["calibration"]).sizes[0][0])
    det = rescale_detections(shipped.detections, [n - shipped.meta["first_frame"]], sx, sx)
    C, tracker = seq.num_views, config.get("tracker", {}).get("name", "")
    fig, axes = plt.subplots(C, 3, figsize=(7.5, 4.6 * C), squeeze=False)
    for c in range(C):
        img, mask = seq.images[frame][c], seq.masks[frame][c]
        over = img.astype(float) / 255.0
        over[sil[c]] = 0.55 * over[sil[c]] + 0.45 * np.array([0.2, 0.4, 1.0])
        iou = (sil[c] & mask).sum() / max((sil[c] | mask).sum(), 1)
        keep = (det.view == c) & (det.confidence > 0.3)
        for ax, im, title in zip(axes[c], (img, mask, over),
                                 (f"{seq.rig.names[c]} source frame {n}", "mask (mocap detect)",
                                  f"{tracker}: body blue, mask yellow, IoU {iou:.2f}\n"
                                  "green: shipped OpenPose (never seen)"), strict=True):
            ax.imshow(im, cmap="gray" if im.ndim == 2 else None)
            ax.set_title(title, fontsize=7)
            ax.set_axis_off()
        axes[c][2].contour(mask, levels=[0.5], colors="yellow", linewidths=0.6)
        axes[c][2].scatter(det.xy[keep, 0], det.xy[keep, 1], s=5, c="lime")
        ys, xs = np.nonzero(mask | sil[c])
        if len(ys):
            pad = 0.1 * np.ptp(ys)
            for ax in axes[c]:
                ax.set_xlim(max(0, xs.min() - pad), min(W, xs.max() + pad))
                ax.set_ylim(min(H, ys.max() + pad), max(0, ys.min() - pad))
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    return out


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="*")
    ap.add_argument("--demo", type=Path, default=DEMO)
    ap.add_argument("--contact", type=Path, default=None, help="a run folder with masks (video data)")
    ap.add_argument("--frame", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("outputs/detector_contact.png"))
    args = ap.parse_args(argv)
    rows = [against_openpose(r, args.demo) for r in args.runs]
    if rows:
        print("| run | tracker | frames | median px vs shipped OpenPose | per view | frames lost |")
        print("|---|---|---|---|---|---|")
    for r in rows:
        per = " / ".join(f"{v:.1f}" for v in r["per_view"].values())
        print(f"| {r['run']} | {r['tracker']} | {r['frames']} | {r['median_px']:.1f} | {per} | {r['lost']} |")
    if args.contact is not None:
        print(contact_sheet(args.contact, args.demo, args.frame, args.out))
    return rows


if __name__ == "__main__":
    main()

"""Question: how many of the rendered colour markers does the chrominance detector find, how
many false positives does it add, and how far off are they, for several thresholds?

The colour marker detector of Canton-Ferrer et al. 2010 (Sec. 4.2) on rendered images.

Renders a synthetic sequence with green marker spheres (pyrender; headless via EGL), learns
the marker chrominance from the visible markers of frame 0 (the "one labelled frame"),
detects markers in the other frames by a Mahalanobis threshold, and reports detection rate,
false-positive rate and pixel error against the true projections of the visible markers,
for several thresholds. Writes detector.json, detector.md and detections.png into --out.

    PYOPENGL_PLATFORM=egl python experiments/marker_detector.py --frames 12 --out outputs/marker_detector
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import cv2
import numpy as np

from experiments.tools.marker_detector import ChromaModel, detect_markers, match_detections
from mocap import presets
from mocap.body import load_body_model
from mocap.cameras import project, rig_from_config
from mocap.data.generate import make_synthetic
from mocap.data.synthetic import marker_visibility


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--motion", default="walk")
    p.add_argument("--frames", type=int, default=12)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cameras", default="humaneva")
    p.add_argument("--thresholds", type=float, nargs="+", default=[2.0, 3.0, 4.0, 6.0])
    p.add_argument("--radius", type=float, default=5.0, help="matching radius, px")
    p.add_argument("--out", type=Path, default=Path("outputs") / "marker_detector")
    args = p.parse_args(argv)
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    dofs = presets.read("body", "paper22")["dofs"]
    body = load_body_model(dofs, name="paper22")
    rig = rig_from_config(args.cameras)
    seq = make_synthetic(body, rig, motion=args.motion, frames=args.frames, fps=25, seed=args.seed,
                         masks=False, images=True, marker_spheres=True)
    shaped = body.shaped(seq.gt.alpha)
    F, C = seq.images.shape[:2]
    truth = project(rig, seq.gt.markers)                                   # (F, C, L, 2)
    visible = np.stack([marker_visibility(shaped.pose(seq.gt.chi[f]).vertices[0], body.faces,
                                          seq.gt.markers[f], rig) for f in range(F)])   # (F, C, L)
    model = ChromaModel.fit(list(seq.images[0]), [truth[0, c][visible[0, c]] for c in range(C)])
    rows = []
    for thr in args.thresholds:
        tot = {"visible": 0, "matched": 0, "false_positives": 0}
        errs = []
        for f in range(1, F):
            for c in range(C):
                xy, _ = detect_markers(seq.images[f, c], model, threshold=thr)
                m = match_detections(xy, truth[f, c], visible[f, c], args.radius)
                for k in tot:
                    tot[k] += m[k]
                if m["matched"]:
                    errs.append((m["pixel_error_px"], m["matched"]))
        V = max(tot["visible"], 1)
        err = sum(e * n for e, n in errs) / max(sum(n for _, n in errs), 1) if errs else float("nan")
        rows.append({"threshold": thr, **tot, "detection_rate": tot["matched"] / V,
                     "false_positive_rate": tot["false_positives"] / V, "pixel_error_px": err})
    args.out.mkdir(parents=True, exist_ok=True)
    result = {"motion": args.motion, "frames": F, "views": C, "seed": args.seed, "cameras": args.cameras,
              "chroma_mean": model.mean.tolist(), "chroma_cov": model.cov.tolist(),
              "markers_visible_per_view_frame": float(visible[1:].sum(axis=-1).mean()),
              "markers_per_frame": int(seq.gt.markers.shape[1]), "rows": rows}
    (args.out / "detector.json").write_text(json.dumps(result, indent=2))
    md = ["# Colour marker detector (Canton-Ferrer et al. 2010, Sec. 4.2)", "",
          f"{args.motion}, {F - 1} test frames x {C} views, learned from frame 0; "
          f"{result['markers_visible_per_view_frame']:.1f} of {result['markers_per_frame']} markers "
          "visible per view and frame (the others are inside the body).", "",
          "| Mahalanobis threshold | detection rate | false-positive rate | pixel error (px) |",
          "|---|---|---|---|"]
    md += [f"| {r['threshold']:g} | {r['detection_rate']:.3f} | {r['false_positive_rate']:.3f} | "
           f"{r['pixel_error_px']:.2f} |" for r in rows]
    (args.out / "detector.md").write_text("\n".join(md) + "\n")
    thr = args.thresholds[len(args.thresholds) // 2]
    img = seq.images[F - 1, 0][..., ::-1].copy()
    for x, y in detect_markers(seq.images[F - 1, 0], model, threshold=thr)[0]:
        cv2.circle(img, (int(round(x)), int(round(y))), 6, (0, 0, 255), 1)
    for x, y in truth[F - 1, 0][visible[F - 1, 0]]:
        cv2.drawMarker(img, (int(round(x)), int(round(y))), (255, 255, 0), cv2.MARKER_CROSS, 6)
    cv2.imwrite(str(args.out / "detections.png"), img)
    print("\n".join(md))
    print(f"wrote {args.out}/detector.json, detector.md, detections.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A contact sheet of one frame: every view with its silhouette and the projected skeleton."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from mocap.cameras import project
from mocap.data.sequence import Sequence


def contact_sheet(seq: Sequence, frame: int, parents: np.ndarray | None = None, cols: int = 4,
                  tile_width: int = 360) -> np.ndarray:
    """(H, W, 3) uint8 RGB mosaic of all views of ``frame``: the image (or a grey canvas), the
    silhouette tinted green, ground-truth joints and bones projected in red/yellow."""
    C = seq.num_views
    w, h = seq.image_size
    s = tile_width / w
    th = int(round(h * s))
    rows = int(np.ceil(C / cols))
    sheet = np.full((rows * th, cols * tile_width, 3), 255, np.uint8)
    joints_px = None
    if seq.gt is not None:
        joints_px = project(seq.rig, seq.gt.joints[frame])            # (C, J, 2)
    for c in range(C):
        img = (seq.images[frame, c].copy() if seq.images is not None
               else np.full((h, w, 3), 70, np.uint8))
        if seq.masks is not None:
            m = seq.masks[frame, c]
            img[m] = (0.55 * img[m] + 0.45 * np.array([60, 220, 90])).astype(np.uint8)
        tile = cv2.resize(img, (tile_width, th), interpolation=cv2.INTER_AREA)
        if joints_px is not None:
            pts = (joints_px[c] + 0.5) * s - 0.5
            if parents is not None:
                for j, p in enumerate(parents):
                    if p >= 0:
                        cv2.line(tile, tuple(int(v) for v in pts[p]), tuple(int(v) for v in pts[j]),
                                 (255, 220, 0), 2, cv2.LINE_AA)
            for q in pts:
                cv2.circle(tile, (int(q[0]), int(q[1])), 3, (230, 30, 30), -1, cv2.LINE_AA)
        if seq.detections is not None:
            d = seq.detections.select(frame, c)
            for q in (d.xy + 0.5) * s - 0.5:
                cv2.drawMarker(tile, (int(q[0]), int(q[1])), (255, 0, 255), cv2.MARKER_CROSS, 8, 1)
        cv2.putText(tile, seq.rig.names[c], (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1,
                    cv2.LINE_AA)
        r, k = divmod(c, cols)
        sheet[r * th:(r + 1) * th, k * tile_width:(k + 1) * tile_width] = tile
    return sheet


def save_png(image: np.ndarray, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), image[..., ::-1]):
        raise OSError(f"could not write {path}")
    return path

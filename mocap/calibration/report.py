"""What a calibration run reports: reprojection errors per camera and per view, and a contact
sheet of the reprojections (observed points green, reprojected red, joined by a line)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np


def rms(residuals: np.ndarray) -> float:
    """RMS length of (N, 2) residual vectors (NaN rows ignored); NaN when empty."""
    r = np.asarray(residuals, float).reshape(-1, 2)
    r = r[np.isfinite(r).all(1)]
    return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))) if len(r) else float("nan")


@dataclass(frozen=True)
class Tile:
    """One picture of the contact sheet: title; image (H, W) or (H, W, 3) uint8, or None for a
    dark canvas of ``size`` (width, height); observed and predicted (N, 2) px."""

    title: str
    size: tuple[int, int]
    observed: np.ndarray
    predicted: np.ndarray
    image: np.ndarray | None = None


def contact_sheet(tiles: Sequence[Tile], path: str | Path, tile_width: int = 360, columns: int = 4) -> None:
    """Write the tiles side by side (``columns`` per row) as a PNG."""
    drawn = []
    for t in tiles:
        W, H = t.size
        s = tile_width / W
        if t.image is None:
            img = np.full((H, W, 3), 40, np.uint8)
        else:
            img = t.image if t.image.ndim == 3 else cv2.cvtColor(t.image, cv2.COLOR_GRAY2BGR)
        img = cv2.resize(img, (tile_width, max(1, round(H * s))), interpolation=cv2.INTER_AREA)
        for o, p in zip(np.asarray(t.observed), np.asarray(t.predicted), strict=True):
            if not (np.isfinite(o).all() and np.isfinite(p).all()):
                continue
            a = tuple(int(round(v)) for v in (o + 0.5) * s - 0.5)
            b = tuple(int(round(v)) for v in (p + 0.5) * s - 0.5)
            cv2.line(img, a, b, (0, 255, 255), 1, cv2.LINE_AA)
            cv2.circle(img, a, 3, (0, 200, 0), 1, cv2.LINE_AA)
            cv2.drawMarker(img, b, (0, 0, 255), cv2.MARKER_CROSS, 5, 1, cv2.LINE_AA)
        cv2.rectangle(img, (0, 0), (tile_width, 22), (0, 0, 0), -1)
        cv2.putText(img, t.title, (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
        drawn.append(img)
    height = max(d.shape[0] for d in drawn)
    drawn = [cv2.copyMakeBorder(d, 0, height - d.shape[0], 0, 2, cv2.BORDER_CONSTANT, value=(255, 255, 255))
             for d in drawn]
    blank = np.full_like(drawn[0], 255)
    rows = [np.hstack(drawn[i:i + columns] + [blank] * (columns - len(drawn[i:i + columns])))
            for i in range(0, len(drawn), columns)]
    if not cv2.imwrite(str(path), np.vstack(rows)):
        raise OSError(f"could not write {path}")

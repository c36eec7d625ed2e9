"""Calibration boards (checkerboard, ChArUco): their 3D corners and their detection in images.

A board's frame: corners on the plane z = 0, x along the columns, y along the rows, metres.
Corner ``i`` of a checkerboard with ``cols x rows`` inner corners is at
``(i % cols, i // cols, 0) * square``, the order of ``cv2.findChessboardCorners(image,
(cols, rows))``. A checkerboard's detection is ambiguous up to a half turn (the corner list
read backwards), which :mod:`mocap.calibration.board_extrinsics` resolves across cameras;
ChArUco corners carry their ids and are not ambiguous.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import cv2
import numpy as np

#: Dictionaries accepted for ChArUco boards (cv2.aruco names without the DICT_ prefix).
ARUCO_DICTIONARIES = ("4X4_50", "4X4_100", "4X4_250", "5X5_50", "5X5_100", "5X5_250",
                      "6X6_50", "6X6_250", "7X7_50", "ARUCO_ORIGINAL")


@dataclass(frozen=True)
class Board:
    """kind: "checkerboard" or "charuco"; cols, rows: inner corners along x and y (a ChArUco
    board of ``cols + 1 x rows + 1`` squares); square: side in metres; marker: ArUco marker
    side in metres (ChArUco); dictionary: ArUco dictionary (ChArUco)."""

    kind: str = "checkerboard"
    cols: int = 4
    rows: int = 7
    square: float = 0.06
    marker: float = 0.0
    dictionary: str = "4X4_50"

    def __post_init__(self) -> None:
        if self.kind not in ("checkerboard", "charuco"):
            raise ValueError(f"board kind must be checkerboard or charuco, got {self.kind!r}")
        if min(self.cols, self.rows) < 2:
            raise ValueError(f"board needs at least 2x2 inner corners, got {self.cols}x{self.rows}")
        if not self.square > 0:
            raise ValueError(f"board square size must be positive (metres), got {self.square}")
        if self.kind == "charuco":
            if not 0 < self.marker < self.square:
                raise ValueError(f"ChArUco marker size must be in (0, square={self.square}) metres, "
                                 f"got {self.marker}")
            if self.dictionary not in ARUCO_DICTIONARIES:
                raise ValueError(f"ArUco dictionary {self.dictionary!r} unknown; one of "
                                 f"{', '.join(ARUCO_DICTIONARIES)}")

    @property
    def num_corners(self) -> int:
        return self.cols * self.rows

    @property
    def symmetric(self) -> bool:
        """True when a detection may be the board turned by half a turn (checkerboards)."""
        return self.kind == "checkerboard"

    def object_points(self) -> np.ndarray:
        """(N, 3) corners in the board frame, metres, in detection id order."""
        i = np.arange(self.num_corners)
        return np.stack([i % self.cols, i // self.cols, np.zeros_like(i)], -1) * self.square

    def charuco(self):
        """The cv2.aruco.CharucoBoard (ChArUco only)."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, f"DICT_{self.dictionary}"))
        b = cv2.aruco.CharucoBoard((self.cols + 1, self.rows + 1), self.square, self.marker, d)
        return b

    def describe(self) -> str:
        if self.kind == "checkerboard":
            return f"checkerboard {self.cols}x{self.rows} inner corners, {self.square * 1000:g} mm squares"
        return (f"ChArUco {self.cols + 1}x{self.rows + 1} squares of {self.square * 1000:g} mm, "
                f"markers {self.marker * 1000:g} mm, {self.dictionary}")


def parse_board(text: str) -> Board:
    """``checkerboard:COLSxROWS:SQUARE_M`` or ``charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT]``
    (COLS x ROWS inner corners), e.g. ``checkerboard:4x7:0.06``."""
    parts = str(text).split(":")
    m = re.fullmatch(r"(\d+)x(\d+)", parts[1]) if len(parts) >= 3 else None
    try:
        if parts[0] == "checkerboard" and len(parts) == 3 and m:
            return Board("checkerboard", int(m[1]), int(m[2]), float(parts[2]))
        if parts[0] == "charuco" and len(parts) in (4, 5) and m:
            return Board("charuco", int(m[1]), int(m[2]), float(parts[2]), float(parts[3]),
                         *(parts[4:] or []))
    except ValueError as exc:
        raise ValueError(f"board {text!r}: {exc}") from None
    raise ValueError(f"board {text!r}: expected checkerboard:COLSxROWS:SQUARE_M (e.g. "
                     "checkerboard:4x7:0.06) or charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT], COLS x ROWS "
                     "inner corners, sizes in metres")


#: Longest image side the coarse checkerboard search runs at (corners refined at full size).
SEARCH_SIDE = 1000


def detect_board(image: np.ndarray, board: Board) -> tuple[np.ndarray, np.ndarray] | None:
    """Board corners in one image: (corners (N, 2) pixels, ids (N,) int) or None when the board
    is not found. Checkerboards: ``cv2.findChessboardCorners`` on a copy at most
    :data:`SEARCH_SIDE` px wide, then ``cv2.cornerSubPix`` at full size; the sector-based
    ``findChessboardCornersSB`` when that fails. ChArUco: ``cv2.aruco.CharucoDetector``
    (at least 6 corners)."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if board.kind == "charuco":
        det = cv2.aruco.CharucoDetector(board.charuco())
        corners, ids, _, _ = det.detectBoard(gray)
        if ids is None or len(ids) < 6:
            return None
        return corners.reshape(-1, 2).astype(np.float64), ids.reshape(-1).astype(np.int64)
    size = (board.cols, board.rows)
    scale = min(1.0, SEARCH_SIDE / max(gray.shape))
    small = gray if scale == 1.0 else cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(small, size, flags=flags)
    if found:
        corners = (corners.reshape(-1, 2) + 0.5) / scale - 0.5
        # window: a quarter of the smallest distance between neighbouring corners, 2-11 px
        step = np.linalg.norm(np.diff(corners.reshape(board.rows, board.cols, 2), axis=1), axis=-1).min()
        win = int(np.clip(step / 4, 2, 11))
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
        corners = cv2.cornerSubPix(gray, corners.astype(np.float32).reshape(-1, 1, 2), (win, win), (-1, -1),
                                   crit)
    else:
        found, corners = cv2.findChessboardCornersSB(
            gray, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
        if not found:
            return None
    return corners.reshape(-1, 2).astype(np.float64), np.arange(board.num_corners)

"""Extrinsics from a board seen by several cameras at the same moments.

Per camera and frame, ``cv2.solvePnP`` gives the board's pose in the camera. Cameras are
placed one at a time, starting from the reference camera (the world frame): the next camera is
the one sharing most frames with a placed camera, its pose the consensus over those frames of
``camera-from-board @ (world-from-board)``. A checkerboard's detection may be the board turned
by half a turn; per frame the reading whose pose agrees with the consensus is kept (the
consensus is the candidate, over both readings of every shared frame, with most candidates
within 5 degrees and 5 % of the board's size). Then every camera pose and board pose is refined
together (:func:`mocap.calibration.bundle.adjust_boards`). Metres come from the board's squares.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from mocap.calibration.boards import Board
from mocap.calibration.bundle import BundleSettings, adjust_boards
from mocap.calibration.compare import rotation_angle_deg
from mocap.calibration.errors import CalibrationInputError
from mocap.cameras import rodrigues_from_rotation, rotation_from_rodrigues

Detection = tuple[np.ndarray, np.ndarray]      # corners (N, 2) px, ids (N,)
#: the joint refinement's settings: corners are sub-pixel, a Huber loss at 1 px
BOARD_BUNDLE = BundleSettings(loss="huber", f_scale=1.0)


@dataclass(frozen=True)
class BoardExtrinsicsResult:
    """cams (C, 6) rvec | t world-to-camera (world: the reference camera); boards: frame ->
    (6,) board-to-world pose; residuals: (camera, frame) -> (N, 2) px."""

    cams: np.ndarray
    boards: dict[str, np.ndarray]
    residuals: dict[tuple[int, str], np.ndarray]


def _mat(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _pnp(obj: np.ndarray, img: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    ok, r, t = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        ok, r, t = cv2.solvePnP(obj, img, K, dist)
    r, t = cv2.solvePnPRefineLM(obj, img, K, dist, r, t)
    return _mat(cv2.Rodrigues(r)[0], t.reshape(3))


def _readings(board: Board, det: Detection, K, dist) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(camera-from-board 4x4, ids)] for the detection, and for the half-turned reading."""
    obj = board.object_points()
    corners, ids = det
    out = [(_pnp(obj[ids], corners, K, dist), ids)]
    if board.symmetric:
        flipped = board.num_corners - 1 - ids
        out.append((_pnp(obj[flipped], corners, K, dist), flipped))
    return out


def _consensus(candidates: list[np.ndarray], size: float) -> np.ndarray:
    """The 4x4 candidate with most others within 5 degrees and 5 % of ``size``."""
    T = np.stack(candidates)
    ang = rotation_angle_deg(T[:, None, :3, :3] @ np.swapaxes(T[None, :, :3, :3], -1, -2))
    dist = np.linalg.norm(T[:, None, :3, 3] - T[None, :, :3, 3], axis=-1)
    near = 0.05 * max(size, 1e-9) + 0.05 * np.linalg.norm(T[:, None, :3, 3], axis=-1)
    votes = ((ang < 5) & (dist < near)).sum(1)
    return T[int(np.argmax(votes))]


def calibrate_board_extrinsics(names: Sequence[str], K: np.ndarray, dist: np.ndarray, board: Board,
                               detections: Sequence[dict[str, Detection]], reference: int = 0,
                               settings: BundleSettings = BOARD_BUNDLE) -> BoardExtrinsicsResult:
    """detections: per camera, frame name -> the board found there (frames with the same name
    are the same moment). Raises :class:`CalibrationInputError` for a camera that shares no
    frame with the others."""
    C = len(names)
    size = board.square * max(board.cols, board.rows)
    for c in range(C):
        shared = [f for f in detections[c] if any(f in detections[o] for o in range(C) if o != c)]
        if not shared:
            raise CalibrationInputError(names[c], "sees the board in no frame where another camera sees it: "
                                                  "no overlap; show the board to this camera and a neighbour "
                                                  "at the same time")
    readings = [{f: _readings(board, d, K[c], dist[c]) for f, d in detections[c].items()} for c in range(C)]
    world = [None] * C
    world[reference] = np.eye(4)                                  # camera-from-world
    board_world: dict[str, np.ndarray] = {}                       # world-from-board
    chosen: dict[tuple[int, str], np.ndarray] = {}                # ids used per (camera, frame)
    for f, rs in readings[reference].items():
        board_world[f] = rs[0][0]
        chosen[(reference, f)] = rs[0][1]
    while any(w is None for w in world):
        shared = [sum(f in board_world for f in readings[c]) if world[c] is None else -1 for c in range(C)]
        c = int(np.argmax(shared))
        if shared[c] <= 0:
            lost = [names[i] for i in range(C) if world[i] is None]
            raise CalibrationInputError(
                lost[0], f"cameras {lost} share no board frame with camera {names[reference]!r}'s group: "
                         "the rig is in unconnected parts")
        cands = [T @ np.linalg.inv(board_world[f]) for f, rs in readings[c].items() if f in board_world
                 for T, _ in rs]
        W = _consensus(cands, size)
        world[c] = W
        for f, rs in readings[c].items():
            if f in board_world:
                errs = [rotation_angle_deg((T @ np.linalg.inv(board_world[f]))[:3, :3] @ W[:3, :3].T)
                        for T, _ in rs]
                chosen[(c, f)] = rs[int(np.argmin(errs))][1]
            else:
                board_world[f] = np.linalg.inv(W) @ rs[0][0]
                chosen[(c, f)] = rs[0][1]
    frames = sorted(board_world)
    fidx = {f: i for i, f in enumerate(frames)}
    cams = np.stack([np.concatenate([rodrigues_from_rotation(W[:3, :3]), W[:3, 3]]) for W in world])
    boards = np.stack([np.concatenate([rodrigues_from_rotation(board_world[f][:3, :3]),
                                       board_world[f][:3, 3]]) for f in frames])
    obj = board.object_points()
    oc, ob, oo, oxy, keys = [], [], [], [], []
    for (c, f), ids in chosen.items():
        corners = detections[c][f][0]
        oc.append(np.full(len(ids), c))
        ob.append(np.full(len(ids), fidx[f]))
        oo.append(obj[ids])
        oxy.append(corners)
        keys.append(((c, f), len(ids)))
    fixed = np.zeros(C, bool)
    fixed[reference] = True
    res = adjust_boards(cams, boards, K, dist, np.concatenate(oc), np.concatenate(ob), np.concatenate(oo),
                        np.concatenate(oxy), fixed_cams=fixed, settings=settings)
    residuals, start = {}, 0
    for key, n in keys:
        residuals[key] = res.residuals[start:start + n]
        start += n
    return BoardExtrinsicsResult(res.cams, {f: res.structure[i] for i, f in enumerate(frames)}, residuals)


def board_pose_matrix(pose: np.ndarray) -> np.ndarray:
    """(6,) rvec | t -> 4x4."""
    return _mat(rotation_from_rodrigues(pose[:3]), pose[3:])

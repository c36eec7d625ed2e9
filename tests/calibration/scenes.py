"""Known answers for the calibration tests: boards rendered through known cameras, keypoints of
a walking body projected through a known rig."""

from __future__ import annotations

import functools

import numpy as np

from mocap.calibration.boards import Board, detect_board
from mocap.calibration.synthetic import (
    board_poses_facing,
    keypoints_through,
    openpose_keypoints,
    render_board,
    walking_rig,
)
from mocap.cameras import Rig, look_at_camera
from mocap.data.openpose import write_openpose_folders

__all__ = ["walking_rig"]

BOARD = Board("checkerboard", 7, 5, 0.05)
BIG_BOARD = Board("checkerboard", 7, 5, 0.08)
K = np.array([[700.0, 0, 330], [0, 700, 235], [0, 0, 1]])
DIST = (-0.1, 0.05, 0, 0, 0)


def close_camera():
    """A 640x480 camera 1 m in front of where the boards are held (the board fills the view)."""
    return look_at_camera("close", [0, -1.0, 1.0], [0, 0, 1.0], K, 640, 480, dist=DIST)


@functools.cache
def close_views(n: int = 12, seed: int = 0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The board detected in n renders through :func:`close_camera`, tilted up to 45 degrees."""
    cam = close_camera()
    poses = board_poses_facing(np.random.default_rng(seed), n, BOARD, np.array([0, 0, 1.0]),
                               np.array([0, -1.0, 0]), spread=0.15, tilt_deg=45)
    out = {}
    for f, T in enumerate(poses):
        d = detect_board(render_board(cam, BOARD, T, supersample=2), BOARD)
        if d is not None:
            out[f"view{f:02d}"] = d
    return out


def arc_rig() -> Rig:
    """Four 640x480 cameras on an arc 2.2 m from where the board is held, at different heights."""
    return Rig(tuple(look_at_camera(f"c{i}", [2.2 * np.sin(a), -2.2 * np.cos(a), 1.3 + 0.2 * i], [0, 0, 1.0],
                                    K, 640, 480, dist=DIST)
                     for i, a in enumerate(np.radians([-50, -15, 20, 55]))))


@functools.cache
def arc_views(n: int = 6, seed: int = 1) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], ...]:
    """Per camera of :func:`arc_rig`, frame -> the big board detected in its render."""
    rig = arc_rig()
    poses = board_poses_facing(np.random.default_rng(seed), n, BIG_BOARD, np.array([0, 0, 1.0]),
                               np.array([0, -1.0, 0]), spread=0.3, tilt_deg=20)
    out = tuple({} for _ in rig)
    for f, T in enumerate(poses):
        for c, cam in enumerate(rig):
            d = detect_board(render_board(cam, BIG_BOARD, T, supersample=2), BIG_BOARD)
            if d is not None:
                out[c][f"{f:03d}"] = d
    return out


@functools.cache
def walking_joints(frames: int = 60) -> tuple[np.ndarray, tuple[str, ...]]:
    """(F, J, 3) joints of the body walking (mocap.synthetic_sequence), and their names."""
    import mocap

    seq = mocap.synthetic_sequence(mocap.load_body("paper22"), cameras="ring4_small", motion="walk",
                                   frames=frames, masks=False)
    return np.asarray(seq.gt.joints), tuple(seq.gt.joint_names)


def walking_keypoints(rig: Rig, noise_px: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(xy (C, F*J, 2), confidence (C, F*J)): :func:`walking_joints` through ``rig`` plus Gaussian
    noise; points outside an image have confidence 0."""
    return keypoints_through(rig, walking_joints()[0], noise_px, seed)


def openpose_folders(root, rig: Rig, xy: np.ndarray, conf: np.ndarray, frames: int) -> None:
    """OpenPose JSON per camera: the walking body's 19 joints in BODY_25B's first 19 slots."""
    write_openpose_folders(root, rig.names, openpose_keypoints(xy, conf, frames))

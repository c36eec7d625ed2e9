"""Known answers for calibration: a board rendered through a known camera (every pixel's ray
meets the board plane, supersampled), so the detectors run on real images."""

from __future__ import annotations

import cv2
import numpy as np

from mocap.calibration.boards import Board
from mocap.cameras import Camera, project, ring_rig


def render_board(camera: Camera, board: Board, world_from_board: np.ndarray, supersample: int = 3,
                 background: int = 128) -> np.ndarray:
    """(H, W) uint8 image of a checkerboard (white margin of one square) posed by the 4x4
    ``world_from_board`` seen by ``camera`` (with its distortion). The pattern is printed on
    the board's -z side; seen from behind the board is a plain grey card."""
    s = int(supersample)
    W, H = camera.width, camera.height
    out = np.full((H, W), float(background))
    # only the pixels around the board (its margin's corners projected, 10 % larger) are traced
    m = np.array([[-2, -2], [board.cols + 1, -2], [board.cols + 1, board.rows + 1], [-2, board.rows + 1]],
                 float) * board.square
    corners = world_from_board[:3, :3] @ np.c_[m, np.zeros(4)].T + world_from_board[:3, 3:4]
    cam = camera.R @ corners + camera.t[:, None]
    if (cam[2] <= 0).any():
        raise ValueError("render_board: the board reaches behind the camera")
    px, _ = cv2.projectPoints(corners.T, cv2.Rodrigues(camera.R)[0], camera.t, camera.K, camera.dist)
    lo, hi = px.reshape(-1, 2).min(0), px.reshape(-1, 2).max(0)
    pad = 0.1 * (hi - lo) + 2
    u0, v0 = np.maximum(np.floor(lo - pad), 0).astype(int)
    u1, v1 = np.minimum(np.ceil(hi + pad), [W - 1, H - 1]).astype(int)
    if u1 < u0 or v1 < v0:
        return np.full((H, W), background, np.uint8)
    w, h = u1 - u0 + 1, v1 - v0 + 1
    u = u0 + (np.arange(w * s) + 0.5) / s - 0.5
    v = v0 + (np.arange(h * s) + 0.5) / s - 0.5
    uv = np.stack(np.meshgrid(u, v), -1).reshape(-1, 1, 2)
    xy = cv2.undistortPoints(uv, camera.K, camera.dist).reshape(-1, 2)    # ~1e-5 px here
    d = np.concatenate([xy, np.ones((len(xy), 1))], 1) @ camera.R          # world directions
    o = camera.center
    n, p0 = world_from_board[:3, 2], world_from_board[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = ((p0 - o) @ n) / (d @ n)
    X = o + lam[:, None] * d
    b = (X - p0) @ world_from_board[:3, :3]                                 # board coordinates
    i = np.floor(b[:, 0] / board.square).astype(np.int64) + 1
    j = np.floor(b[:, 1] / board.square).astype(np.int64) + 1
    inside = (i >= 0) & (i <= board.cols) & (j >= 0) & (j <= board.rows)
    margin = (i >= -1) & (i <= board.cols + 1) & (j >= -1) & (j <= board.rows + 1)
    img = np.full(len(b), float(background))
    img[margin] = 255.0
    img[inside & ((i + j) % 2 == 0)] = 0.0
    if (camera.center - p0) @ n > 0:                                        # the back of the board
        img[margin] = 200.0
    img[~(lam > 0)] = background
    out[v0:v1 + 1, u0:u1 + 1] = img.reshape(h, s, w, s).mean(axis=(1, 3))
    img = out
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def board_pose(rvec, t) -> np.ndarray:
    """4x4 world-from-board from a Rodrigues vector and a translation."""
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, float))[0]
    T[:3, 3] = t
    return T


def board_poses_facing(rng: np.random.Generator, n: int, board: Board, centre: np.ndarray,
                       facing: np.ndarray, spread: float = 0.3, tilt_deg: float = 30.0) -> list[np.ndarray]:
    """n world-from-board poses: the board's centre within ``spread`` m of ``centre``, its
    printed side towards ``facing`` (a unit vector, the board's -z) tilted up to
    ``tilt_deg`` about random axes, its rows roughly down the world -z."""
    f = np.asarray(facing, float) / np.linalg.norm(facing)
    down = np.array([0.0, 0.0, -1.0]) - f[2] * f
    down /= np.linalg.norm(down)
    R0 = np.stack([np.cross(down, -f), down, -f], axis=1)                   # columns: board x, y, z
    half = np.array([board.cols - 1, board.rows - 1, 0]) * board.square / 2
    out = []
    for _ in range(n):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        Rt = cv2.Rodrigues(axis * np.radians(rng.uniform(0, tilt_deg)))[0]
        R = Rt @ R0
        c = np.asarray(centre, float) + rng.uniform(-spread, spread, 3)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, c - R @ half
        out.append(T)
    return out


def walking_rig():
    """The known rig of the keypoint-calibration answers: four 1280x960 cameras with lens
    distortion on a 3.5 m ring at 1.5 m height, looking at a person's hips."""
    return ring_rig(4, 3.5, 1.5, 1280, 960, fov_deg=50, look_at=(0, 0, 0.9), dist=[-0.05, 0.02, 0, 0, 0],
                    start_deg=30)


def keypoints_through(rig, joints: np.ndarray, noise_px: float,
                      seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """joints (F, J, 3) seen by ``rig`` as a detector would: (xy (C, F*J, 2) the projections plus
    N(0, noise_px) pixels, confidence (C, F*J) 1 inside the image, 0 outside)."""
    px = np.transpose(project(rig, joints), (1, 0, 2, 3)).reshape(len(rig), -1, 2)
    xy = px + np.random.default_rng(seed).normal(0, noise_px, px.shape)
    W, H = rig.sizes[:, 0:1], rig.sizes[:, 1:2]
    inside = (xy[..., 0] > 0) & (xy[..., 0] < W) & (xy[..., 1] > 0) & (xy[..., 1] < H)
    return xy, inside.astype(float)


def openpose_keypoints(xy: np.ndarray, confidence: np.ndarray, frames: int,
                       num_keypoints: int = 25) -> np.ndarray:
    """:func:`keypoints_through`'s (xy (C, F*J, 2), confidence (C, F*J)) as OpenPose keypoints
    (C, F, num_keypoints, 3): the J points in the layout's first J slots (the rest confidence 0),
    what :func:`mocap.data.openpose.write_openpose_folders` writes."""
    C = len(xy)
    xy, confidence = np.reshape(xy, (C, frames, -1, 2)), np.reshape(confidence, (C, frames, -1))
    out = np.zeros((C, frames, num_keypoints, 3))
    out[:, :, :xy.shape[2], :2], out[:, :, :xy.shape[2], 2] = xy, confidence
    return out

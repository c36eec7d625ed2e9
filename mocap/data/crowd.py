"""Synthetic scenes with several people, as a keypoint detector sees them: per frame and view,
one skeleton of labelled keypoints per visible person, grouped by ``Detections.person`` (the
detector's per-view index, shuffled so that it says nothing about identity across views or
frames). For tests and figures of the multi-person start-up and tracking.

    det, points = crowd_detections(body, rig, chis, alphas, labels, noise_px=1.0, seed=0)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mocap.body.catalogue import make_landmark_set
from mocap.body.model import BodyModel
from mocap.cameras import Rig, project
from mocap.data.sequence import Detections


def crowd_detections(body: BodyModel, rig: Rig, chis: np.ndarray, alphas: np.ndarray,
                     labels: Sequence[str], noise_px: float = 1.0, seed: int = 0,
                     confidence: float = 0.8) -> tuple[Detections, np.ndarray]:
    """chis: (N, F, D) poses of N people over F frames; alphas: (N, K) their shapes; labels:
    keypoint names of the landmark catalogue. Returns the detections (every keypoint in
    front of a camera and inside its image; pixel noise ``noise_px``) and the true
    keypoints (N, F, L, 3) world metres."""
    rng = np.random.default_rng(seed)
    lms = make_landmark_set(body, list(labels))
    chis = np.asarray(chis, np.float64)
    N, F, _ = chis.shape
    pts = np.stack([lms.positions(body.shaped(alphas[n]), chis[n]).astype(np.float64) for n in range(N)])
    rows = []
    sizes = np.asarray(rig.sizes, np.float64)                          # (C, 2) width, height
    for f in range(F):
        for c in range(len(rig)):
            order = rng.permutation(N)                                 # the detector's own order
            for slot, n in enumerate(order):
                px, depth = project(rig[c], pts[n, f], return_depth=True)
                px = px + rng.normal(0.0, noise_px, px.shape)
                ok = (depth > 0.1) & np.all((px >= 0) & (px < sizes[c]), axis=1)
                for k in np.flatnonzero(ok):
                    rows.append((f, c, k, px[k, 0], px[k, 1], confidence, slot))
    a = np.array(rows, np.float64).reshape(-1, 7)
    det = Detections(tuple(lms.names), a[:, 0].astype(np.int64), a[:, 1].astype(np.int64),
                     a[:, 2].astype(np.int64), a[:, 3:5], a[:, 5], a[:, 6].astype(np.int64))
    return det, pts


def straight_walk(body: BodyModel, frames: int, start: Sequence[float], end: Sequence[float],
                  yaw: float, seed: int = 0, action: str = "walk") -> np.ndarray:
    """(frames, D) poses: the joint angles of ``action`` (:func:`mocap.data.motion.generate_motion`)
    with the root moved in a straight line from ``start`` to ``end`` (x, y world metres, the
    generated root height kept) and turned by ``yaw`` radians about the vertical."""
    from mocap.body.twists import se3_exp, se3_log
    from mocap.data.motion import generate_motion

    chi = generate_motion(body, action, frames, fps=25, seed=seed)
    T = se3_exp(chi[:, :6].astype(np.float64))                      # (F, 4, 4) root motion
    s = np.linspace(0.0, 1.0, frames)[:, None]
    xy = (1 - s) * np.asarray(start, np.float64) + s * np.asarray(end, np.float64)
    c, si = np.cos(yaw), np.sin(yaw)
    Rz = np.array([[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]])
    # keep the generated root orientation relative to its own heading at frame 0; place it
    out = np.array(T)
    root_rest = body.shaped(np.zeros(body.num_shape)).rest_joints[0].astype(np.float64)
    for f in range(frames):
        R = Rz @ T[f, :3, :3]
        pos = np.array([xy[f, 0], xy[f, 1], (T[f, :3, :3] @ root_rest + T[f, :3, 3])[2]])
        out[f, :3, :3] = R
        out[f, :3, 3] = pos - R @ root_rest                          # the root joint lands at pos
    chi = np.array(chi, np.float64)
    chi[:, :6] = se3_log(out)
    return chi


def crossing_scene(body: BodyModel, frames: int, people: int = 3, gap: float = 0.35,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(chis (N, F, D), alphas (N, K)): two people walking towards each other on parallel
    lines ``gap`` metres apart, crossing at the centre of the volume half way through, and
    (people=3) a third gesturing 1.2 m to the side. Shapes differ per person."""
    chis = [straight_walk(body, frames, (-1.2, 0.0), (1.2, 0.0), 0.0, seed),
            straight_walk(body, frames, (1.2, gap), (-1.2, gap), np.pi, seed + 1)]
    if people >= 3:
        chis.append(straight_walk(body, frames, (0.0, -1.2), (0.2, -1.2), np.pi / 2, seed + 2,
                                  action="gestures"))
    alphas = np.random.default_rng(seed).normal(0, 0.8, (len(chis), body.num_shape))
    return np.stack(chis), alphas

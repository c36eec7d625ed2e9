"""The body's heading as a search direction: a pose turned about the vertical (z) through its
pelvis. The hybrid's repair tries a few such turns of the tracked pose when most limb chains are
flagged at once (``apf.heading_chains``): a dancer who turns faster than the local step follows
leaves every limb off the silhouettes, and a search over the limbs' angles alone never turns the
torso back (docs/results/surface.md, "Silhouette-only hybrid: repair and start over frames")."""

from __future__ import annotations

import numpy as np

from mocap.body.twists import se3_exp, se3_log


def turned_by(rest_pelvis: np.ndarray, chi: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """The pose ``chi`` (D,) turned by each of ``angles`` (A,) rad about the vertical through its
    pelvis (``rest_pelvis`` (3,): the pelvis joint of the shaped body at rest) -> (A, D): the
    global twist changed, the joint angles as they are; the pelvis stays where it is."""
    chi = np.asarray(chi, np.float64)
    angles = np.atleast_1d(np.asarray(angles, np.float64))
    T = se3_exp(chi[:6])                                              # (4, 4)
    pelvis = T[:3, :3] @ np.asarray(rest_pelvis, np.float64) + T[:3, 3]
    c, s = np.cos(angles), np.sin(angles)
    turn = np.zeros((len(angles), 4, 4))
    turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1] = c, -s, s, c
    turn[:, 2, 2] = turn[:, 3, 3] = 1.0
    turn[:, :3, 3] = pelvis - turn[:, :3, :3] @ pelvis                # (A, 3): the pelvis held
    out = np.repeat(chi[None], len(angles), axis=0)
    out[:, :6] = se3_log(turn @ T)
    return out


def chains_flagged(chains: list[tuple[int, list[int]]], flagged: np.ndarray) -> np.ndarray:
    """(C,) bool: whether each limb chain (``chains``: (root joint, its limbs),
    :func:`~mocap.local.misalignment.limb_chains`) has a flagged joint (``flagged`` (J,) bool)
    among its limbs or root."""
    flagged = np.asarray(flagged, bool)
    return np.array([flagged[[root, *limbs]].any() for root, limbs in chains], bool)


def flagged_chains(chains: list[tuple[int, list[int]]], flagged: np.ndarray) -> int:
    """How many limb chains have a flagged joint (:func:`chains_flagged`)."""
    return int(chains_flagged(chains, flagged).sum())

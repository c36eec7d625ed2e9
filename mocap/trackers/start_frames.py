"""Start hypotheses scored over several frames (the silhouette-only hybrid's start,
``HybridSettings.start_frames``).

One frame's silhouettes hardly tell which arm is where, or front from back: a body turned 180
degrees about the vertical with its left and right limbs exchanged casts nearly the same outlines,
and so does a pose with its two arms exchanged where they hang close to the torso. A few frames of
motion do tell them apart: a wrong hypothesis has to move its limbs against the way the observed
ones move, and the local step cannot follow the silhouettes as well from it. So the start and its
ambiguous alternatives (:func:`start_hypotheses`) are each tracked over the first frames with the
local step alone (:func:`track_hypotheses`), and the one with the lowest silhouette energy summed
over those frames is kept (:func:`chosen_hypothesis`); the tracker then tracks the frames again from
it (:meth:`~mocap.trackers.hybrid_tracker.HybridTracker.step`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.model import BodyModel
from mocap.energy.smoothness import predict_constant_velocity
from mocap.local.misalignment import limb_chains
from mocap.trackers.heading import turned_by
from mocap.trackers.initialization import mirror_map


def chain_pairs(body: BodyModel) -> list[tuple[str, np.ndarray]]:
    """The body's left/right limb chain pairs (:func:`~mocap.local.misalignment.limb_chains`
    whose root joints are named ``l_X`` / ``r_X``) as (X, (D,) bool: the joint-angle DOFs of both
    chains), in the order of the chains (paper22: ("shoulder", arms), ("hip", legs))."""
    names = body.joint_names
    dof_joint = np.asarray(body.dof_joint)
    chains = limb_chains(body)
    out = []
    for root, limbs in chains:
        name = names[root]
        if not name.startswith("l_"):
            continue
        other = [(r, ls) for r, ls in chains if names[r] == "r_" + name[2:]]
        if not other:
            continue
        joints = {root, *limbs, other[0][0], *other[0][1]}
        dofs = np.zeros(body.num_dofs, bool)
        dofs[6:] = np.isin(dof_joint, list(joints))
        out.append((name[2:], dofs))
    return out


def swapped(chi: np.ndarray, dofs: np.ndarray, perm: np.ndarray, sign: np.ndarray,
            limits: np.ndarray) -> np.ndarray:
    """The pose ``chi`` (D,) with the left and right angles of the DOFs ``dofs`` (D,) bool
    exchanged (``perm``, ``sign``: :func:`~mocap.trackers.initialization.mirror_map`), the others
    as they are, within ``limits`` (D, 2)."""
    chi = np.asarray(chi, np.float64)
    mirrored = chi.copy()
    mirrored[6:] = sign * chi[6:][perm]
    out = np.where(dofs, mirrored, chi)
    return np.clip(out, limits[:, 0], limits[:, 1])


def start_hypotheses(body: BodyModel, rest_pelvis: np.ndarray, chi: np.ndarray,
                     turns: Sequence[float] = ()) -> tuple[np.ndarray, list[str]]:
    """The start ``chi`` (D,) and the alternatives one frame's silhouettes hardly tell from it:
    each left/right limb chain pair exchanged alone (``swap_shoulder``: the arms,
    ``swap_hip``: the legs), all limbs exchanged (``swap_all``), the body turned 180 degrees about
    the vertical through its pelvis (``turned``; ``rest_pelvis`` (3,): the shaped body's pelvis at
    rest) and turned with all limbs exchanged (``turned_swap_all``: the outline's near twin); then
    the start turned by each of ``turns`` (degrees; ``turned_<deg>``). Returns (poses (H, D),
    names (H,)); the first is the start itself (``start``)."""
    chi = np.asarray(chi, np.float64)
    perm, sign = mirror_map(body)
    pairs = chain_pairs(body)
    everything = np.zeros(body.num_dofs, bool)
    everything[6:] = True
    poses, names = [chi], ["start"]
    for name, dofs in pairs:
        poses.append(swapped(chi, dofs, perm, sign, body.limits))
        names.append(f"swap_{name}")
    all_swapped = swapped(chi, everything, perm, sign, body.limits)
    if len(pairs) > 1:
        poses.append(all_swapped)
        names.append("swap_all")
    turn = turned_by(rest_pelvis, chi, np.array([np.pi]))[0]
    poses += [turn, turned_by(rest_pelvis, all_swapped, np.array([np.pi]))[0]]
    names += ["turned", "turned_swap_all"]
    for deg in turns:
        poses.append(turned_by(rest_pelvis, chi, np.array([np.deg2rad(deg)]))[0])
        names.append(f"turned_{deg:g}")
    return np.stack(poses), names


@dataclass(frozen=True)
class HypothesisTracks:
    """Each hypothesis's local-step track over the first frames: the hypotheses ``starts`` (H, D),
    their tracks ``poses`` (H, F, D) (frame 0: after the local step on it), the silhouette energy of
    each frame ``energy`` (H, F) and its sum over the frames ``total`` (H,)."""

    starts: np.ndarray
    poses: np.ndarray
    energy: np.ndarray

    @property
    def total(self) -> np.ndarray:
        return self.energy.sum(axis=1)


def track_hypotheses(starts: np.ndarray, frames: Sequence, step: Callable, energy: Callable,
                     damping: float = 1.0) -> HypothesisTracks:
    """Each start (H, D) tracked over ``frames`` (F; the first is the start's own frame) by
    ``step(frame, predicted (D,)) -> pose (D,)`` (the local step; on the first frame from the
    start itself, then from the constant-velocity prediction of the track so far, damped by
    ``damping``), each frame's pose scored by ``energy(frame, poses (P, D)) -> (P,)`` (the mean
    per-view silhouette energy)."""
    starts = np.atleast_2d(np.asarray(starts, np.float64))
    if len(frames) == 0:
        raise ValueError("track_hypotheses: no frames to track the start hypotheses over")
    H, F = len(starts), len(frames)
    poses = np.zeros((H, F, starts.shape[1]))
    e = np.zeros((H, F))
    for h in range(H):
        history = [starts[h]]
        for f, frame in enumerate(frames):
            predicted = starts[h] if f == 0 else predict_constant_velocity(history[-2:], damping)
            chi = np.asarray(step(frame, predicted), np.float64)
            history = (history + [chi])[-3:] if f else [chi]
            poses[h, f] = chi
    for f, frame in enumerate(frames):
        e[:, f] = energy(frame, poses[:, f])
    return HypothesisTracks(starts, poses, e)


def chosen_hypothesis(total: np.ndarray, margin: float = 0.0) -> int:
    """The index of the hypothesis kept: the one of lowest ``total`` (H,) energy where it is lower
    than the start's (index 0) by more than the share ``margin`` of it; else 0, the start."""
    total = np.asarray(total, np.float64)
    best = int(np.argmin(total))
    if best and total[best] < (1.0 - float(margin)) * total[0]:
        return best
    return 0

"""One frame's people across views, for the left/right check of several people: which person
of each view is which person of the others (at most one per view), by how well the
mirror-invariant centres of their keypoints (the nose and the midpoints of shoulders, hips,
knees, ankles: the same whether or not a view has left and right swapped) triangulate from two
views.

    groups = group_views(rig, people)      # people: per view (N_c, 33, 3) -> [{view: person index}]

The tracker (``tracker=marker_people``) does its own association; this one only decides which
keypoints :func:`mocap.video.detect.left_right_fixes` compares.
"""

from __future__ import annotations

import warnings

import numpy as np

from mocap.cameras import project, triangulate

#: BlazePose keypoint pairs whose midpoint does not change when left and right are swapped
#: (a pair (i, i) is the point itself: the nose)
CENTRE_PAIRS = np.array([(0, 0), (11, 12), (23, 24), (25, 26), (27, 28)])


def centres(kp: np.ndarray, min_confidence: float = 0.5) -> np.ndarray:
    """(..., 33, 3) keypoints -> (..., 5, 2) mirror-invariant centres (NaN where either
    keypoint of a pair is below ``min_confidence``)."""
    a, b = kp[..., CENTRE_PAIRS[:, 0], :], kp[..., CENTRE_PAIRS[:, 1], :]
    ok = (a[..., 2] >= min_confidence) & (b[..., 2] >= min_confidence)
    return np.where(ok[..., None], (a[..., :2] + b[..., :2]) / 2, np.nan)


def pair_costs(rig, a: int, b: int, people_a: np.ndarray, people_b: np.ndarray,
               min_confidence: float = 0.5) -> np.ndarray:
    """(Na, Nb) cost of person i of view a being person j of view b: the median over the
    centres seen in both of the two-view triangulation's reprojection error, divided by the
    person's keypoint height in that view (mean of the two views); inf with fewer than 3 centres."""
    ca, cb = centres(people_a, min_confidence), centres(people_b, min_confidence)   # (Na|Nb, 5, 2)
    Na, Nb = len(ca), len(cb)
    if Na == 0 or Nb == 0:
        return np.zeros((Na, Nb))
    px = np.stack([np.broadcast_to(ca[:, None], (Na, Nb, 5, 2)),
                   np.broadcast_to(cb[None], (Na, Nb, 5, 2))]).reshape(2, -1, 2)
    pair = rig[[a, b]]
    X = triangulate(pair, px)                                                           # (Na*Nb*5, 3)
    back = project(pair, np.nan_to_num(X))                                             # (2, Na*Nb*5, 2)
    err = np.linalg.norm(back - px, axis=-1)                                           # (2, n)
    ha, hb = _heights(people_a, min_confidence), _heights(people_b, min_confidence)
    rel = (err[0].reshape(Na, Nb, 5) / ha[:, None, None] + err[1].reshape(Na, Nb, 5) / hb[None, :, None]) / 2
    rel = np.where(np.isfinite(X[:, 0]).reshape(Na, Nb, 5), rel, np.nan)
    seen = np.isfinite(rel).sum(-1)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        cost = np.nanmedian(rel, axis=-1)
    return np.where(seen >= 3, cost, np.inf)


def _heights(people: np.ndarray, min_confidence: float) -> np.ndarray:
    """(N, 33, 3) -> (N,) vertical extent of the keypoints with confidence >= min_confidence
    (NaN where fewer than 2)."""
    y = np.where(people[..., 2] >= min_confidence, people[..., 1], np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmax(y, -1) - np.nanmin(y, -1)


def group_views(rig, people: list[np.ndarray], max_cost: float = 0.05,
                min_confidence: float = 0.5) -> list[dict[int, int]]:
    """One frame: people[c] (N_c, 33, 3) per view -> groups {view: person index}, each person
    in exactly one group (alone where it matches nobody). Greedy over all cross-view pairs,
    cheapest first (:func:`pair_costs` below ``max_cost``), merging two groups when they share no
    view and every cross pair between them is below ``max_cost``."""
    C = len(people)
    group_of = {(c, i): k for k, (c, i) in enumerate((c, i) for c in range(C) for i in range(len(people[c])))}
    members: dict[int, dict[int, int]] = {k: {c: i} for (c, i), k in group_of.items()}
    costs: dict[tuple[int, int], np.ndarray] = {}
    edges = []
    for a in range(C):
        for b in range(a + 1, C):
            cost = pair_costs(rig, a, b, people[a], people[b], min_confidence)
            costs[a, b] = cost
            for i, j in zip(*np.nonzero(cost < max_cost), strict=True):
                edges.append((float(cost[i, j]), a, int(i), b, int(j)))

    def cost_of(c, i, d, j):
        return costs[c, d][i, j] if c < d else costs[d, c][j, i]

    for _, a, i, b, j in sorted(edges):
        ga, gb = group_of[a, i], group_of[b, j]
        if ga == gb or set(members[ga]) & set(members[gb]):
            continue
        if all(cost_of(c, p, d, q) < max_cost
               for c, p in members[ga].items() for d, q in members[gb].items()):
            for c, p in members.pop(gb).items():
                members[ga][c] = p
                group_of[c, p] = ga
    return [members[k] for k in sorted(members)]


__all__ = ["CENTRE_PAIRS", "centres", "group_views", "pair_costs"]

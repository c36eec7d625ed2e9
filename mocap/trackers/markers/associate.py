"""Cross-view association of people before triangulation (the marker tracker's start-up).

A keypoint detector groups its keypoints into skeletons per view (``Detections.person``), but
does not say which skeleton in one view is which in another. Matching each keypoint across
views on its own (as a per-landmark RANSAC does) mixes people: a left knee of one person and
of another can both be consistent with some epipolar line, and the fitted body then takes a
thigh from one and a shin from the other. Here whole skeletons are matched: two skeletons in
views a and b are the same person when the median symmetric epipolar distance of their
common keypoints (:func:`mocap.energy.epipolar.skeleton_epipolar_distance`) is below a
threshold, and a person is a set of at most one skeleton per view whose every pair agrees.
People are extracted greedily: the consistent set with the most views (then the smallest
mean distance) first, its skeletons removed, and again.
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass

import numpy as np

from mocap.cameras import Rig, undistort_points
from mocap.data.sequence import Detections
from mocap.energy.epipolar import skeleton_epipolar_distance


@dataclass(frozen=True)
class Skeletons:
    """One frame's skeletons per view: xy[c]: (N_c, L, 2) undistorted pixels, valid[c]:
    (N_c, L) bool, ids[c]: (N_c,) the detector's person index in that view."""

    xy: list[np.ndarray]
    valid: list[np.ndarray]
    ids: list[np.ndarray]


def skeletons_of(det: Detections, landmark_names, rig: Rig) -> Skeletons | None:
    """Group one frame's detections (``det``, one frame) by view and person; None when the
    detections carry no person grouping. Labels the landmark set does not hold are dropped."""
    if det.person is None or not len(det) or np.all(det.person < 0):
        return None
    index = {n: i for i, n in enumerate(landmark_names)}
    lab = np.array([index.get(n, -1) for n in det.labels] + [-1])[np.where(det.label >= 0, det.label, -1)]
    L = len(landmark_names)
    xy, valid, ids = [], [], []
    for c in range(len(rig)):
        sel = (det.view == c) & (lab >= 0) & (det.person >= 0)
        people = np.unique(det.person[sel])
        X = np.zeros((len(people), L, 2))
        V = np.zeros((len(people), L), bool)
        if sel.any():
            und = undistort_points(rig[c], np.asarray(det.xy[sel], np.float64))
            row = np.searchsorted(people, det.person[sel])
            X[row, lab[sel]] = und
            V[row, lab[sel]] = True
        xy.append(X)
        valid.append(V)
        ids.append(people)
    return Skeletons(xy, valid, ids)


def associate_people(sk: Skeletons, F: np.ndarray, threshold_px: float, min_views: int = 2,
                     max_combinations: int = 50000) -> list[tuple[list[int | None], float]]:
    """People across views: [(one skeleton index per view or None, mean pairwise distance px)],
    best first (most views, then smallest distance). F: (C, C, 3, 3) fundamental matrices of
    the undistorted views."""
    C = len(sk.xy)
    D = {}
    for a, b in itertools.combinations(range(C), 2):
        D[a, b] = skeleton_epipolar_distance(F[a, b], sk.xy[a], sk.valid[a], sk.xy[b], sk.valid[b])
    free = [set(range(len(x))) for x in sk.xy]
    people = []
    while sum(len(f) > 0 for f in free) >= min_views:
        best, best_key = None, None
        options = [sorted(f) + [None] for f in free]
        if np.prod([len(o) for o in options], dtype=float) > max_combinations:
            combos = _greedy_combos(D, free, threshold_px)
        else:
            combos = itertools.product(*options)
        for combo in combos:
            views = [c for c in range(C) if combo[c] is not None]
            if len(views) < min_views:
                continue
            d = [D[a, b][combo[a], combo[b]] for a, b in itertools.combinations(views, 2)]
            if max(d) >= threshold_px:
                continue
            key = (len(views), -float(np.mean(d)))
            if best_key is None or key > best_key:
                best, best_key = list(combo), key
        if best is None:
            break
        people.append((best, -best_key[1]))
        for c, i in enumerate(best):
            if i is not None:
                free[c].discard(i)
    return people


def _greedy_combos(D, free, threshold_px):
    """Candidate people when the full enumeration is too large: for every skeleton, the set
    grown view by view with the best-agreeing free skeleton."""
    C = len(free)
    for a in range(C):
        for i in free[a]:
            combo: list[int | None] = [None] * C
            combo[a] = i
            for b in range(C):
                if b == a or not free[b]:
                    continue
                cost = []
                for j in free[b]:
                    trial = [(c, combo[c]) for c in range(C) if combo[c] is not None]
                    d = [D[min(c, b), max(c, b)][(k, j) if c < b else (j, k)] for c, k in trial]
                    cost.append((max(d), j))
                m, j = min(cost)
                if m < threshold_px:
                    combo[b] = j
            yield combo


def _landing(u: np.ndarray, depth: np.ndarray, sizes: np.ndarray | None) -> np.ndarray:
    """(..., L, C) bool: the keypoints projected to u (..., L, C, 2) at depth (..., L, C) that are
    known (finite), land in front of the camera and (``sizes`` (C, 2) width, height given) inside
    its image."""
    ok = np.all(np.isfinite(u), axis=-1) & np.isfinite(depth) & (np.nan_to_num(depth) > 0)
    if sizes is not None:
        ok &= np.all((u >= 0) & (u < np.asarray(sizes, np.float64)), axis=-1)
    return ok


def _boxes(u: np.ndarray, depth: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`projected_boxes` of the keypoints ``ok`` (:func:`_landing`)."""
    x, y = np.where(ok, u[..., 0], np.nan), np.where(ok, u[..., 1], np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        box = np.stack([np.nanmin(x, -2), np.nanmin(y, -2), np.nanmax(x, -2), np.nanmax(y, -2)], -1)
        n = ok.sum(axis=-2)
        mean = np.where(ok, depth, 0.0).sum(axis=-2) / np.maximum(n, 1)
        return box, np.where(n > 0, mean, np.nan)


def projected_boxes(u: np.ndarray, depth: np.ndarray, sizes: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per person and view, the box x0, y0, x1, y1 (..., C, 4) and the mean depth (..., C) of
    the keypoints projected to u (..., L, C, 2) at depth (..., L, C) (NaN: unknown) that land
    in front of the camera (and inside images of ``sizes`` (C, 2) width, height when given);
    NaN where none does."""
    return _boxes(u, depth, _landing(u, depth, sizes))


def views_expected(u: np.ndarray, depth: np.ndarray, sizes: np.ndarray, others_box: np.ndarray,
                   others_depth: np.ndarray, cover: float) -> np.ndarray:
    """(C,) bool: the views that should see a person whose keypoints project to u (L, C, 2)
    undistorted pixels at depth (L, C) metres (NaN: keypoint unknown), in images of ``sizes``
    (C, 2) width, height: half or more of its known keypoints land in front of the camera and
    inside the image, and no other person nearer that camera (mean depth; ``others_box`` (P, C, 4),
    ``others_depth`` (P, C): the other people's :func:`projected_boxes`) covers ``cover`` or
    more of the box of those keypoints (the person may stand hidden behind them). A person
    missing from such a view is evidence against it; one outside a view's image, or hidden in
    it, is not."""
    known = np.all(np.isfinite(u), axis=-1) & np.isfinite(depth)                        # (L, C)
    inside = _landing(u, depth, sizes)
    n = known.sum(axis=0)
    in_image = (n > 0) & (2 * inside.sum(axis=0) >= np.maximum(n, 1))                 # (C,)
    box, near = _boxes(u, depth, inside)                                               # (C, 4), (C,)
    area = np.maximum((box[:, 2] - box[:, 0]) * (box[:, 3] - box[:, 1]), 1e-9)
    ob = others_box                                                                    # (P, C, 4)
    w = np.clip(np.minimum(ob[..., 2], box[:, 2]) - np.maximum(ob[..., 0], box[:, 0]), 0, None)
    h = np.clip(np.minimum(ob[..., 3], box[:, 3]) - np.maximum(ob[..., 1], box[:, 1]), 0, None)
    with np.errstate(invalid="ignore"):
        hidden = np.any((others_depth < near) & (np.nan_to_num(w * h) >= cover * area), axis=0)   # (C,)
    return in_image & ~hidden


def person_detections(det: Detections, sk: Skeletons, person: list[int | None]) -> Detections:
    """The rows of ``det`` (one frame) that belong to one associated person."""
    keep = np.zeros(len(det), bool)
    for c, i in enumerate(person):
        if i is not None:
            keep |= (det.view == c) & (det.person == sk.ids[c][i])
    return Detections(det.labels, det.frame[keep], det.view[keep], det.label[keep], det.xy[keep],
                      det.confidence[keep], det.person[keep])

"""Scoring tracks against the ground truth of several people (a person axis in gt.npz: joints
(F, P, J, 3), :class:`mocap.data.sequence.GroundTruth`), joints matched by name as in
:mod:`mocap.eval.by_name`.

Tracks are named points (name -> (F, 3) metres, NaN in frames where a track does not exist),
one dict per track: the one estimate of a single-person tracker, or one per person of a
multi-person tracker. Every track gets at most one ground-truth person and every person at
most one track: the assignment minimising the sum of mean joint errors (the Hungarian method
on the (tracks x people) matrix of each pair's mean joint error over the frames both exist,
mm); a pair never within ``gate_mm`` of each other in any frame stays unassigned. The result
does not depend on the order of the people in the file (nor of the tracks).

Per person (under ``people``, by person name): ``track`` (the assigned track's index, None:
not tracked), ``frames`` (frames with ground truth), ``tracked_frames`` (frames where the
assigned track exists too), ``coverage``, and over the tracked frames the metrics of
:func:`mocap.eval.by_name.score_by_name` (``mpjpe_mm``, ``mpjpe_std_mm``, ``per_joint_mm``,
``pcp``, ``pcp_per_limb``); ``pcp_all_frames`` counts the person's frames without the track as
wrong. ``identity_switches``: frame by frame, tracks and people are matched the same way
(Hungarian on the frame's mean joint errors, gated); a switch is a person matched to another
track than at its previous matched frame (the CLEAR-MOT definition). ``track_jumps`` per
track (under ``tracks``): the track matched to another person than at its previous matched
frame (a single-person tracker moving to a bystander).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from mocap.data.sequence import GroundTruth
from mocap.eval.by_name import score_by_name

#: a track and a person further apart than this (mean joint error, mm) are never matched
GATE_MM = 500.0


def _assign(cost: np.ndarray, gate: float) -> list[tuple[int, int]]:
    """Hungarian assignment on cost (T, P) (NaN: no overlap), pairs above ``gate`` dropped."""
    if not cost.size:
        return []
    big = np.where(np.isfinite(cost), cost, 1e12)
    rows, cols = linear_sum_assignment(big)
    return [(int(t), int(p)) for t, p in zip(rows, cols, strict=True) if np.isfinite(cost[t, p])
            and cost[t, p] <= gate]


def _switches(sequence: list[int | None]) -> int:
    seen = [s for s in sequence if s is not None]
    return int(sum(a != b for a, b in zip(seen, seen[1:], strict=False)))


def score_people(tracks: Sequence[Mapping[str, np.ndarray]], gt: GroundTruth,
                 mapping: Mapping[str, str | None], *, skeleton: str | None = None,
                 only: Sequence[str] | None = None, required: Sequence[str] = (),
                 gate_mm: float = GATE_MM, start: int = 0) -> dict:
    """Per-person scores of ``tracks`` against ``gt`` (the module docstring). ``mapping``:
    ground-truth joint name -> estimate name (:func:`mocap.eval.by_name.resolve_mapping`);
    skeleton, only, required: as :func:`mocap.eval.by_name.score_by_name`. Tracks cover
    ground-truth frames start..start+F-1."""
    if not tracks:
        raise ValueError("no track to score")
    F = len(next(iter(tracks[0].values())))
    P = gt.num_people
    names = list(gt.joint_names)
    scored = [n for n in names if mapping.get(n) is not None and (only is None or n in only)]
    if not scored:
        raise ValueError("no ground-truth joint has a counterpart in the estimate")
    idx = [names.index(n) for n in scored]
    people = [gt.person(p) for p in range(P)]
    G = np.stack([g.joints[start:start + F][:, idx] for g in people], axis=1)             # (F, P, S, 3)
    V = np.isfinite(G).all(axis=-1)
    if gt.joint_valid is not None:
        V &= np.stack([g.joint_valid[start:start + F][:, idx] for g in people], axis=1)
    E = np.stack([np.stack([np.asarray(t[mapping[n]], np.float64)[:F] for n in scored], axis=1)
                  for t in tracks])                                                    # (T, F, S, 3)
    present = np.isfinite(E).all(axis=-1).any(axis=-1)                                 # (T, F)
    err = 1e3 * np.linalg.norm(E[:, :, None] - G[None], axis=-1)                       # (T, F, P, S)
    ok = V[None] & np.isfinite(err)
    with np.errstate(invalid="ignore"):
        cost = np.where(ok, err, 0.0).sum(-1) / ok.sum(-1)                             # (T, F, P): NaN none
        total = np.where(np.isfinite(cost), cost, 0.0).sum(1) / np.isfinite(cost).sum(1)  # (T, P)
    near = (np.where(np.isfinite(cost), cost, np.inf) <= gate_mm).any(axis=1)           # (T, P)
    assigned = {p: t for t, p in _assign(np.where(near, total, np.nan), np.inf)}
    # frame by frame: who follows whom
    matched = [[None] * F for _ in range(P)]
    followed: list[list[int | None]] = [[None] * F for _ in tracks]
    for f in range(F):
        for t, p in _assign(cost[:, f], gate_mm):
            matched[p][f], followed[t][f] = t, p
    person_names = list(gt.person_names) or ["person0"]
    out_people: dict[str, dict] = {}
    for p, pname in enumerate(person_names):
        has = V[:, p].any(axis=1)
        t = assigned.get(p)
        entry: dict = {"track": t, "frames": int(has.sum()),
                       "identity_switches": _switches(matched[p])}
        if t is None:
            entry.update(tracked_frames=0, coverage=0.0)
            out_people[pname] = entry
            continue
        both = has & present[t]
        entry.update(tracked_frames=int(both.sum()),
                     coverage=float(both.sum() / has.sum()) if has.any() else 0.0)
        full_valid = V[:, p] & present[t][:, None]
        gt_p = people[p].joints[start:start + F]
        valid_p = np.zeros(gt_p.shape[:2], bool)
        valid_p[:, idx] = full_valid
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)     # frames without the track: empty means
            s = score_by_name(tracks[t], names, gt_p, valid_p, skeleton, only, required)
        entry.update({k: v for k, v in s.items() if k not in ("scored", "unscored", "per_frame_mm")})
        if "pcp" in s:
            entry["pcp_all_frames"] = float(s["pcp"] * entry["coverage"])
        entry["per_frame_mm"] = s["per_frame_mm"]
        out_people[pname] = entry
    scored_people = [e for e in out_people.values() if e["track"] is not None and np.isfinite(e["mpjpe_mm"])]
    out: dict = {
        "people": out_people,
        "people_in_ground_truth": P,
        "people_tracked": len(scored_people),
        "identity_switches": int(sum(e["identity_switches"] for e in out_people.values())),
        "tracks": {str(t): {"person": next((person_names[p] for p, tt in assigned.items() if tt == t), None),
                            "frames": int(present[t].sum()), "track_jumps": _switches(followed[t])}
                   for t in range(len(tracks))},
    }
    if scored_people:
        out["mpjpe_mm"] = float(np.mean([e["mpjpe_mm"] for e in scored_people]))
        pcps = [e["pcp"] for e in scored_people if "pcp" in e]
        if pcps:
            out["pcp"] = float(np.mean(pcps))
    return out

"""Scores of several people: each ground-truth person against the estimated track that
explains it best, identity switches, and how soon people are picked up.

    scores = people_scores(est, gt, limbs)     # est: (T, P_est, J, 3), gt: (T, P_gt, J, 3)

Both arrays are world metres with the same J joints in the same order and NaN where a person
is absent (a track not live, a person not in the scene) or a joint unmeasured. Nothing here
knows the tracker or the skeleton: :func:`people_run_metrics` makes the arrays from a
several-people run.

- Assignment (``assignment``): one track per ground-truth person, the Hungarian method on
  the mean over the person's frames of the per-frame error (mean joint error, clipped at
  ``gate_mm``; a frame where the track is absent costs ``gate_mm``); a person whose best cost
  is ``gate_mm`` or more has no track (-1).
- Per person (``people``, in ground-truth order): ``mpjpe_mm`` (mean over the frames where the
  person and its track are both present), ``pcp`` (the Shelf/Campus rule of
  :mod:`mocap.eval.by_name` over the same frames: a limb is correct when the mean of its two
  endpoint errors is at most half its true length), ``frames`` (present), ``tracked_frames``
  (its track present within ``gate_mm``), ``first_frame``, ``first_tracked_frame`` and
  ``latency_frames`` (their difference; None when never tracked), ``switches``.
- Identity switches (CLEAR-MOT): per frame, the present people and tracks are matched by the
  Hungarian method on the same error, gated at ``gate_mm``; a person's switch is a frame
  where it is matched to another track than at its previous matched frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from mocap.eval.by_name import PCP_LIMBS


def _frame_errors(est: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(T, P_gt, P_est) mean joint error m (NaN where either is absent)."""
    d = np.linalg.norm(gt[:, :, None] - est[:, None], axis=-1)                # (T, G, E, J)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(d)
        n = ok.sum(-1)
        return np.where(n > 0, np.where(ok, d, 0.0).sum(-1) / np.maximum(n, 1), np.nan)


def people_scores(est: np.ndarray, gt: np.ndarray, limbs: Sequence[tuple[int, int]] = (),
                  gate_mm: float = 500.0) -> dict:
    """See the module docstring. est: (T, P_est, J, 3); gt: (T, P_gt, J, 3) world metres,
    NaN where absent; limbs: (a, b) joint index pairs for PCP (none: no PCP)."""
    est, gt = np.asarray(est, np.float64), np.asarray(gt, np.float64)
    if est.ndim != 4 or gt.ndim != 4 or est.shape[0] != gt.shape[0] or est.shape[2:] != gt.shape[2:]:
        raise ValueError(f"estimates {est.shape} and ground truth {gt.shape} must be (T, P, J, 3) with the "
                         "same frames and joints")
    T, G, E = gt.shape[0], gt.shape[1], est.shape[1]
    gate = gate_mm / 1000.0
    err = _frame_errors(est, gt)                                          # (T, G, E)
    gt_on = np.isfinite(gt[..., 0]).any(-1)                               # (T, G)
    est_on = np.isfinite(est[..., 0]).any(-1)                             # (T, E)
    clipped = np.where(np.isfinite(err), np.minimum(err, gate), gate)
    cost = np.array([[clipped[gt_on[:, g], g, e].mean() if gt_on[:, g].any() else gate for e in range(E)]
                     for g in range(G)]).reshape(G, E)
    assignment = np.full(G, -1)
    if G and E:
        rows, cols = linear_sum_assignment(cost)
        for g, e in zip(rows, cols, strict=True):
            if cost[g, e] < gate:
                assignment[g] = e
    matched = np.full((T, G), -1)                                         # per-frame matching
    for t in range(T):
        g_on, e_on = np.flatnonzero(gt_on[t]), np.flatnonzero(est_on[t])
        if len(g_on) and len(e_on):
            c = np.where(np.isfinite(err[t][np.ix_(g_on, e_on)]), err[t][np.ix_(g_on, e_on)], 1e9)
            for i, j in zip(*linear_sum_assignment(c), strict=True):
                if c[i, j] < gate:
                    matched[t, g_on[i]] = e_on[j]
    people = []
    for g in range(G):
        seq = matched[:, g][matched[:, g] >= 0]
        switches = int((seq[1:] != seq[:-1]).sum())
        present = np.flatnonzero(gt_on[:, g])
        row: dict = {"track": int(assignment[g]), "frames": int(len(present)), "switches": switches,
                     "first_frame": int(present[0]) if len(present) else None}
        e = assignment[g]
        both = present[est_on[present, e]] if e >= 0 else present[:0]
        near = both[err[both, g, e] < gate] if e >= 0 else both
        row["tracked_frames"] = int(len(near))
        row["first_tracked_frame"] = int(near[0]) if len(near) else None
        row["latency_frames"] = (row["first_tracked_frame"] - row["first_frame"]
                                 if row["first_tracked_frame"] is not None else None)
        row["mpjpe_mm"] = 1000.0 * float(np.nanmean(err[both, g, e])) if len(both) else float("nan")
        if limbs and len(both):
            row["pcp"] = _pcp(est[both, e], gt[both, g], limbs)
        people.append(row)
    return {"assignment": assignment.tolist(), "people": people,
            "switches": int(sum(p["switches"] for p in people)),
            "unassigned_tracks": [int(e) for e in range(E) if e not in set(assignment.tolist())]}


def _pcp(est: np.ndarray, gt: np.ndarray, limbs: Sequence[tuple[int, int]]) -> float:
    """Share of correct limb instances (frames x limbs) of (n, J, 3) estimate and truth."""
    a, b = np.array([p[0] for p in limbs]), np.array([p[1] for p in limbs])
    ea = np.linalg.norm(est[:, a] - gt[:, a], axis=-1)
    eb = np.linalg.norm(est[:, b] - gt[:, b], axis=-1)
    length = np.linalg.norm(gt[:, a] - gt[:, b], axis=-1)
    ok = np.isfinite(ea) & np.isfinite(eb) & np.isfinite(length)
    return float(((ea + eb) / 2 <= length / 2)[ok].mean()) if ok.any() else float("nan")


def pcp_limbs(joint_names: Sequence[str]) -> list[tuple[int, int]]:
    """The PCP limbs (:data:`mocap.eval.by_name.PCP_LIMBS`) whose ends are both among
    ``joint_names`` (mocap's names), as index pairs; the head is neck-head when there is no
    head_top."""
    index = {n: i for i, n in enumerate(joint_names)}
    out = []
    for a, b in PCP_LIMBS.values():
        if b == "head_top" and b not in index:
            b = "head"
        if a in index and b in index:
            out.append((index[a], index[b]))
    return out


def births_deaths(live: np.ndarray, ids: Sequence[int]) -> dict:
    """Per frame, the ids born (first live frame) and ended (last live frame) of (T, P) bool
    ``live``: {"births": {frame: [ids]}, "deaths": {frame: [ids]}} (frames as strings, for JSON);
    a track live in the last frame has not ended."""
    births: dict[str, list[int]] = {}
    deaths: dict[str, list[int]] = {}
    T = len(live)
    for p, pid in enumerate(ids):
        on = np.flatnonzero(live[:, p])
        if len(on):
            births.setdefault(str(int(on[0])), []).append(int(pid))
            if on[-1] < T - 1:
                deaths.setdefault(str(int(on[-1])), []).append(int(pid))
    return {"births": births, "deaths": deaths}


def people_run_metrics(joints: np.ndarray, ids: Sequence[int], truth: Mapping | None,
                       estimate_joint_names: Sequence[str], gate_mm: float = 500.0) -> dict:
    """Metrics of a several-people run: joints (T, P, J, 3) of the tracks ``ids`` (NaN where a
    track is not live; joints named ``estimate_joint_names``); truth: None or an object with
    ``joints`` (T', P_gt, J', 3) and ``joint_names`` (the joints it shares with the estimate by
    name are scored, first T frames). Keys: ``people`` (tracks), ``births``, ``deaths``, and with
    truth: ``per_person`` (each ground-truth person), ``identity_switches``, ``assignment``
    ({ground-truth person: track id or -1}), ``pcp_min``, ``mpjpe_mm`` (mean over people)."""
    live = np.isfinite(joints[..., 0]).any(-1)
    out: dict = {"people": [int(i) for i in ids], **births_deaths(live, ids)}
    if truth is None:
        return out
    names = [str(n) for n in truth.joint_names]
    shared = [n for n in names if n in estimate_joint_names]
    if not shared:
        raise ValueError(f"the several-people ground truth's joints ({', '.join(names[:5])}, ...) share no "
                         "name with the body's joints")
    T = min(len(joints), len(truth.joints))
    ei = [list(estimate_joint_names).index(n) for n in shared]
    gi = [names.index(n) for n in shared]
    scores = people_scores(joints[:T, :, ei], np.asarray(truth.joints, np.float64)[:T, :, gi],
                           pcp_limbs(shared), gate_mm)
    per = []
    for g, row in enumerate(scores["people"]):
        per.append({"person": g, **row, "track": int(ids[row["track"]]) if row["track"] >= 0 else -1})
    out.update(per_person=per, identity_switches=scores["switches"],
               assignment={str(p["person"]): p["track"] for p in per},
               mpjpe_mm=float(np.nanmean([p["mpjpe_mm"] for p in per])) if per else float("nan"))
    pcps = [p["pcp"] for p in per if "pcp" in p]
    if pcps:
        out["pcp_min"] = float(np.min(pcps))
    return out

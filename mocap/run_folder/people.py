"""The metrics of a several-people run (``mocap track tracker=marker_people``; the run itself is
:mod:`mocap.run_folder.tracking`'s, whose frame loop serves one person and several alike):

- ``motion.npz``: every person with a person axis (format ``mocap-people-v1``,
  :mod:`mocap.export.people_motion`);
- ``metrics.json``: ``people`` (track ids), ``births`` / ``deaths`` ({frame: ids}: first and
  last frame with an estimate), ``ended_at`` ({frame: ids}: when the tracker ended them),
  ``people_per_frame``, ``reprojection_px_per_person`` (median landmark reprojection error),
  speed (``sec_per_frame``, ``frames_per_second``, ``frames_per_second_by_people``: {people
  live: fps} over the frames without a new person's start-up, ``start_up_seconds``); with
  ground truth, the accuracy of :func:`people_accuracy_metrics`.

Ground truth is scored per person with the best assignment of tracks to true people
(:func:`people_accuracy_metrics`, what ``mocap rescore`` recomputes): the synthetic crowd's
(:mod:`mocap.data.people_truth`: ``per_person`` with MPJPE, PCP, switches, frames from
appearance to tracked; :func:`mocap.eval.people_metrics.people_run_metrics`), or a
``gt.npz`` (``data.gt=`` or the folder's; a person axis or one person; joints by name in any
skeleton: :mod:`mocap.eval.people`, each person's coverage, MPJPE, PCP and identity switches).
Either way ``per_person`` (a list, in ground-truth order, ``track`` the track id or -1),
``assignment`` ({true person: track id or -1}), ``identity_switches``, ``mpjpe_mm`` (mean
over the people tracked) and ``pcp_min``; the body surface is not scored for several people.

Births and ends are read from what the tracker answered frame by frame
(:attr:`mocap.trackers.run.TrackResult.live`): a person is born in the first frame it is
answered for, and ended in the first frame it is no longer answered for.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mocap.data.people_truth import people_truth
from mocap.eval.people_metrics import people_run_metrics


def births_and_ends(live: list[tuple[int, ...]]) -> tuple[dict[int, list[int]], dict[int, list[int]]]:
    """({frame: ids born}, {frame: ids ended}) from the ids answered for in each frame."""
    born: dict[int, list[int]] = {}
    ended: dict[int, list[int]] = {}
    seen: set[int] = set()
    before: set[int] = set()
    for f, ids in enumerate(live):
        now = set(ids)
        if now - seen:
            born[f] = sorted(now - seen)
        if before - now:
            ended[f] = sorted(before - now)
        seen |= now
        before = now
    return born, ended


def people_accuracy_metrics(body, seq, arrays) -> dict:
    """``people``, ``births``, ``deaths`` of a people motion's ``arrays``
    (:mod:`mocap.export.people_motion`) and, with ground truth in ``seq``, the per-person scores
    of the module docstring."""
    ids = [int(i) for i in arrays["person_ids"]]
    joints = np.asarray(arrays["joints"], np.float64)
    truth = people_truth(seq)
    out = people_run_metrics(joints, ids, truth, body.joint_names)
    if truth is not None or seq.gt is None:
        return out
    from mocap.eval.run_metrics import people_accuracy

    chi, alpha = np.asarray(arrays["chi"], np.float64), np.asarray(arrays["alpha"], np.float64)
    tracks = []
    for p in range(len(ids)):
        a = alpha[:, p]
        have = np.isfinite(a).all(axis=1)
        fill = a[have][-1] if have.any() else np.zeros(a.shape[1])
        tracks.append((np.where(have[:, None], a, fill), chi[:, p]))
    scores = people_accuracy(body, seq.gt, tracks)
    per = []
    for name, row in scores["people"].items():
        t = row["track"]
        per.append({"person": name, **{k: v for k, v in row.items() if k != "per_frame_mm"},
                    "track": -1 if t is None else ids[t], "switches": row["identity_switches"]})
    out.update(per_person=per, identity_switches=scores["identity_switches"],
               assignment={p["person"]: p["track"] for p in per},
               people_in_ground_truth=scores["people_in_ground_truth"],
               people_tracked=scores["people_tracked"],
               frames_lost=scores["frames_lost"],
               track_jumps={str(ids[int(t)]): v["track_jumps"] for t, v in scores["tracks"].items()},
               mpjpe_mm=scores.get("mpjpe_mm", float("nan")))
    pcps = [p["pcp"] for p in per if "pcp" in p and p["track"] >= 0]
    if pcps:
        out["pcp_min"] = float(np.min(pcps))
    return out


def people_metrics(body, seq, tracker, result, arrays: dict, start_seconds: float) -> dict:
    """The metrics of a several-people run (see the module docstring) from its result
    (:class:`mocap.trackers.run.TrackResult`) and motion arrays; ``start_seconds``: the start-up's."""
    F = result.frames
    ids = [int(i) for i in arrays["person_ids"]]
    metrics = {"tracker": tracker.name, "seed": int(arrays["seed"]), "data": seq.name, "frames": F,
               **people_accuracy_metrics(body, seq, arrays)}
    born, ended = births_and_ends(result.live)
    live = arrays["live"].sum(axis=1)
    steps = np.asarray(result.seconds[1:])
    tracking_seconds = float(steps.sum())
    steady = (live[1:] > 0) & ~np.isin(np.arange(1, F), list(born))
    by_people = {str(int(n)): float(1.0 / steps[steady & (live[1:] == n)].mean())
                 for n in np.unique(live[1:][steady]) if steps[steady & (live[1:] == n)].mean() > 0}
    if "reprojection_px" in arrays:           # without ground truth: how well each person fits
        with np.errstate(all="ignore"):
            med = [np.nanmedian(col) if np.isfinite(col).any() else float("nan")
                   for col in arrays["reprojection_px"].T]
        metrics["reprojection_px_per_person"] = {str(i): float(v) for i, v in zip(ids, med, strict=True)}
    metrics.update(
        ended_at={str(f): ids_ for f, ids_ in sorted(ended.items())},
        people_per_frame=[int(n) for n in live],
        start_up_seconds=start_seconds,
        sec_per_frame=float(steps.mean()) if len(steps) else 0.0,
        frames_per_second=float(len(steps) / tracking_seconds) if tracking_seconds else 0.0,
        frames_per_second_by_people=by_people,
        start_up_flags=list(tracker.start_up_flags),
        tracking_seconds=tracking_seconds)
    return metrics


def several_people_evidence(seq) -> dict | None:
    """What says that ``seq`` holds several people (None: nothing does): {"people": the most
    seen at once, "why": one line}. Read from a ground truth with a person axis, the synthetic
    crowd's truth, detections grouped into several skeletons in one view, or keypoint files
    that held several people in one view (``seq.meta["people_in_view"]``, kept even when
    ``data.person=subject`` kept one)."""
    truth = people_truth(seq)
    if seq.gt is not None and len(seq.gt.person_names) > 1:
        where = seq.meta.get("gt", "its gt.npz")
        return {"people": len(seq.gt.person_names),
                "why": f"the ground truth ({where}) holds {len(seq.gt.person_names)} people"}
    if truth is not None and truth.joints.shape[1] > 1:
        return {"people": int(truth.present.sum(axis=1).max()),
                "why": f"the data holds {truth.joints.shape[1]} people"}
    det = seq.detections
    if det is not None and det.person is not None and len(det):
        keys = np.unique(np.stack([det.frame, det.view, det.person], axis=1), axis=0)
        _, counts = np.unique(keys[:, :2], axis=0, return_counts=True)
        if counts.max() > 1:
            return {"people": int(counts.max()),
                    "why": f"the detections hold up to {int(counts.max())} people in one view"}
    seen = int(seq.meta.get("people_in_view", 0) or 0)
    if seen > 1:
        kept = " (data.person=subject kept one per view)" if seq.meta.get("person") == "subject" else ""
        return {"people": seen, "why": f"the keypoint files hold up to {seen} people in one view{kept}"}
    return None


def one_person_flag(evidence: Mapping) -> str:
    """The flag of a several-people recording tracked as one person."""
    return (f"several people in the data, tracked as one person: {evidence['why']}; to track every "
            "person: tracker=marker_people (with keypoint files: data.person=all)")

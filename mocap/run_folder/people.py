"""The metrics of a several-people run (``mocap track tracker=marker_people``; the run itself is
:mod:`mocap.run_folder.tracking`'s, whose frame loop serves one person and several alike):

- ``motion.npz``: every person with a person axis (format ``mocap-people-v1``,
  :mod:`mocap.export.people_motion`);
- ``metrics.json``: ``people`` (track ids), ``births`` / ``deaths`` ({frame: ids}: first and
  last frame with an estimate), ``ended_at`` ({frame: ids}: when the tracker ended them),
  ``people_per_frame``, ``reprojection_px_per_person`` (median landmark reprojection error),
  speed (``sec_per_frame``, ``frames_per_second``, ``frames_per_second_by_people``: {people
  live: fps} over the frames without a new person's start-up, ``start_up_seconds``); with
  several-people ground truth (:mod:`mocap.data.people_truth`) also ``per_person`` (MPJPE,
  PCP, switches, frames from appearance to tracked), ``identity_switches``, ``assignment``,
  ``pcp_min`` and ``mpjpe_mm`` (:func:`mocap.eval.people_metrics.people_run_metrics`).

Births and ends are read from what the tracker answered frame by frame
(:attr:`mocap.trackers.run.TrackResult.live`): a person is born in the first frame it is
answered for, and ended in the first frame it is no longer answered for.
"""

from __future__ import annotations

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


def people_metrics(body, seq, tracker, result, arrays: dict, start_seconds: float) -> dict:
    """The metrics of a several-people run (see the module docstring) from its result
    (:class:`mocap.trackers.run.TrackResult`) and motion arrays; ``start_seconds``: the start-up's."""
    F = result.frames
    truth = people_truth(seq)
    ids = [int(i) for i in arrays["person_ids"]]
    metrics = {"tracker": tracker.name, "seed": int(arrays["seed"]), "data": seq.name, "frames": F,
               **people_run_metrics(arrays["joints"].astype(np.float64), ids, truth, body.joint_names)}
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

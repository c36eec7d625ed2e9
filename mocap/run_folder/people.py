"""The frame loop of a several-people run (``mocap track tracker=marker_people``): the
tracker's start-up on frame 0, its step on every later frame (people confirmed, tracked and
ended: :mod:`mocap.trackers.markers.people`), each frame into the recording (one colour per
person), then the run folder's files as a single-person run writes them
(:mod:`mocap.run_folder.tracking`):

- ``motion.npz``: every person with a person axis (format ``mocap-people-v1``,
  :mod:`mocap.export.people_motion`);
- ``metrics.json``: ``people`` (track ids), ``births`` / ``deaths`` ({frame: ids}: first and
  last frame with an estimate), ``ended_at`` ({frame: ids}: when the tracker ended them),
  ``people_per_frame``, ``reprojection_px_per_person`` (median landmark reprojection error),
  speed (``sec_per_frame``, ``frames_per_second``, ``frames_per_second_by_people``: {people
  live: fps} over the frames without a new person's start-up, ``start_up_seconds``); with
  several-people ground truth (:mod:`mocap.data.people_truth`) also ``per_person`` (MPJPE,
  PCP, switches, frames from appearance to tracked), ``identity_switches``, ``assignment``,
  ``pcp_min`` and ``mpjpe_mm`` (:func:`mocap.eval.people_metrics.people_run_metrics`);
- ``recording.rrd`` and ``manifest.json`` last.
"""

from __future__ import annotations

import time

import numpy as np
from tqdm import tqdm

from mocap.data.people_truth import people_truth
from mocap.eval.people_metrics import people_run_metrics
from mocap.export.people_motion import people_motion_arrays, write_people_motion
from mocap.recording.sink import RunInfo
from mocap.run_folder.attempt import run_attempt, seal_run
from mocap.run_folder.metadata import run_metadata
from mocap.threads import thread_budget
from mocap.trackers.run import frame_of


def check_people_run(tracker, mode: str, init_cfg: dict, wrap) -> None:
    """What a several-people run refuses, before any work (one-line errors)."""
    if mode != "tracker":
        raise ValueError(f"tracker {tracker.name!r} initialises every person itself: run with "
                         f"init.mode=tracker (got init.mode={mode})")
    if init_cfg.get("cache"):
        raise ValueError(f"tracker {tracker.name!r} does not use init.cache (got {init_cfg['cache']!r}): "
                         "leave it null")
    if wrap is not None:
        raise ValueError(f"tracker {tracker.name!r} runs only with mocap track (this command wraps the "
                         "tracker)")


def track_people(out_dir, config, body, seq, tracker, F, sink, recording, seed, threads, source,
                 overrides) -> dict:
    """Run ``tracker`` (a several-people tracker) over the first F frames of ``seq`` into
    ``out_dir`` (see the module docstring); returns the metrics."""
    from mocap.run_folder.tracking import config_text

    text = config_text(config)
    metadata = run_metadata(text, source, seed, tracker=tracker.name, data=seq.name)
    truth = people_truth(seq)
    sink.start(RunInfo(text, metadata), body, seq)
    shaped: dict = {}
    recording_seconds = 0.0

    def record(f, out, step_seconds):
        nonlocal recording_seconds
        t = time.perf_counter()
        posed = {}
        for pid, est in out.items():
            if pid not in shaped or not np.array_equal(shaped[pid].alpha, est.alpha):
                shaped[pid] = body.shaped(est.alpha)
            posed[pid] = (est, shaped[pid].pose(est.chi).joints[0])
        gt = truth.joints[f] if truth is not None and f < len(truth.joints) else None
        sink.people_frame(frame_of(seq, f), posed, gt, step_seconds)
        recording_seconds += time.perf_counter() - t

    t0 = time.perf_counter()
    seconds = [0.0]
    with run_attempt(out_dir, sink):
        with thread_budget(threads), tqdm(total=F, desc=f"{tracker.name} on {seq.name}", unit="frame") as bar:
            tracks = tracker.start(frame_of(seq, 0))
            start_up = time.perf_counter() - t0
            record(0, {t.id: t.estimates[0] for t in tracks}, start_up)
            bar.update(1)
            for f in range(1, F):
                t = time.perf_counter()
                out = tracker.step(frame_of(seq, f))
                seconds.append(time.perf_counter() - t)
                for pid, est in out.items():
                    if not np.all(np.isfinite(est.chi)):
                        raise FloatingPointError(f"{tracker.name}: non-finite pose of person {pid} "
                                                 f"at frame {f}")
                record(f, out, seconds[-1])
                bar.update(1)
        wall = time.perf_counter() - t0
        people = tracker.estimates_by_person()
        run_id = metadata.get("run_id", "")
        arrays = people_motion_arrays(body, people, F, seconds, seq.fps,
                                      info={"tracker": tracker.name, "data": seq.name, "seed": seed,
                                            "run_id": run_id})
        ids = [int(i) for i in arrays["person_ids"]]
        metrics = {"tracker": tracker.name, "seed": seed, "data": seq.name, "frames": F,
                   **people_run_metrics(arrays["joints"].astype(np.float64), ids, truth, body.joint_names)}
        live = arrays["live"].sum(axis=1)
        steps = np.asarray(seconds[1:])
        tracking_seconds = float(steps.sum())
        steady = (live[1:] > 0) & ~np.isin(np.arange(1, F), [int(f) for f in tracker.births])
        by_people = {str(int(n)): float(1.0 / steps[steady & (live[1:] == n)].mean())
                     for n in np.unique(live[1:][steady]) if steps[steady & (live[1:] == n)].mean() > 0}
        if "reprojection_px" in arrays:           # without ground truth: how well each person fits
            with np.errstate(all="ignore"):
                med = [np.nanmedian(col) if np.isfinite(col).any() else float("nan")
                       for col in arrays["reprojection_px"].T]
            metrics["reprojection_px_per_person"] = {str(i): float(v) for i, v in zip(ids, med, strict=True)}
        metrics.update(
            ended_at={str(f): ids_ for f, ids_ in sorted(tracker.deaths.items())},
            people_per_frame=[int(n) for n in live],
            start_up_seconds=start_up,
            sec_per_frame=float(steps.mean()) if len(steps) else 0.0,
            frames_per_second=float(len(steps) / tracking_seconds) if tracking_seconds else 0.0,
            frames_per_second_by_people=by_people,
            start_up_flags=list(tracker.start_up_flags),
            threads=threads, wall_seconds=wall, tracking_seconds=tracking_seconds,
            recording_seconds=recording_seconds, config=config)
        write_people_motion(out_dir / "motion.npz", arrays)
        seal_run(out_dir, sink, metrics, recording, overrides)
    accuracy = ""
    if "per_person" in metrics:
        accuracy = (f"{metrics['identity_switches']} identity switches, MPJPE {metrics['mpjpe_mm']:.1f} mm, "
                    f"PCP min {100 * metrics.get('pcp_min', float('nan')):.1f} %, ")
    print(f"{tracker.name}: {len(ids)} people, {accuracy}{metrics['frames_per_second']:.2f} frames/s "
          f"-> {out_dir}")
    return metrics

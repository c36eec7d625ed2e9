"""The run behind every tracking command (``mocap track``, ``mocap recovery``, ``mocap
video-check``): resume check, body / data / tracker from their factories, initial pose, the
frame loop (:func:`mocap.trackers.run.track_sequence`) into the recording sink, then
motion.npz, metrics.json and recording.rrd in the run directory, in that order (the motion is
kept when the recording fails), and last ``manifest.json`` (their sizes and checksums,
:mod:`mocap.run_folder.manifest`): without it the folder is not a complete run. Commands differ only in
the tracker they step (``wrap``) and the metrics they add (``extra``).

The run's settings are read from ``config``, the resolved configuration as plain values (what
metrics.json stores under ``"config"``; mocap_cli/conf/tracking.yaml documents the keys):

    seed, frames, threads            the data/tracker seed (an int >= 0), frames to track (an int
                                     >= 1, at most the data's; None or "all": all), thread budget
    init.mode                        gt_noise (ground truth + noise) | tracker (self-initialised)
    init.noise_deg, init.noise_translation, init.cache
    recording.*                      enabled, level (summary | standard | full), every, particles,
                                     images, scale (:func:`mocap.recording.factory.recording_settings`)
    motion.vertices                  keep the posed mesh per frame in motion.npz
    skip_complete, resume_on_change  resuming a sweep (:mod:`mocap.eval.resume`)

Settings are checked before any work (:func:`check_settings`). A re-run moves an earlier
complete run into ``previous_run/`` first, and removes it only when the new run is complete;
SIGTERM is handled like SIGINT (the recording is closed as ``recording.failed.rrd``, no
manifest is written). After a SIGKILL the next run removes the ``recording.rrd.part`` left
behind (a killed recording does not verify) and starts again.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.quality import quality_flags
from mocap.eval.resume import (
    config_changes,
    restore_previous,
    restore_stored_config,
    run_state,
    set_aside,
)
from mocap.eval.run_metadata import run_metadata
from mocap.eval.run_metrics import run_metrics
from mocap.export.motion import motion_arrays, write_motion
from mocap.recording.factory import make_sink, recording_settings
from mocap.recording.sink import RunInfo
from mocap.run_folder.attempt import own_run_folder, run_attempt, seal_run
from mocap.run_folder.manifest import manifest_problem
from mocap.threads import resolve_threads
from mocap.trackers.base import Tracker
from mocap.trackers.init_cache import initial_estimate
from mocap.trackers.run import TrackResult, frame_of, noisy_initial_pose, search_budget, track_sequence

#: wrap(tracker, body, seq): the tracker to step instead
Wrap = Callable[[Tracker, BodyModel, Sequence], Tracker]
#: extra(metrics, result, body, seq): more metrics, merged before metrics.json is written
Extra = Callable[[dict, TrackResult, BodyModel, Sequence], dict]

INIT_MODES = ("gt_noise", "tracker")


class RunDirectoryConflict(FileExistsError):
    """The run directory holds the results of another configuration (resume_on_change=fail)."""


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def check_settings(config: Mapping) -> int | None:
    """The run's own settings, checked before any work; returns the frames to track (None:
    all). Each error names the setting, its value and what is allowed."""
    seed = config.get("seed", 0)
    if not _is_int(seed) or seed < 0:
        raise ValueError(f"setting seed = {seed!r} is not allowed (an integer >= 0)")
    frames = config.get("frames")
    if frames is None or frames == "all":
        return None
    if not _is_int(frames) or frames < 1:
        raise ValueError(f"setting frames = {frames!r} is out of range (an integer >= 1, or all / null "
                         "for every frame of the data)")
    return int(frames)


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt (as SIGINT does), so a terminated run cleans up the
    same way; only in the main thread (where signal handlers can be set)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt(f"terminated (signal {signum})")

    old = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def config_text(config: Mapping) -> str:
    """The configuration as the YAML text a recording stores (and its hash is taken of)."""
    return yaml.dump(dict(config), default_flow_style=False, allow_unicode=True, sort_keys=False)


def run_tracking(out_dir: str | Path, config: Mapping, *,
                 make_body: Callable[[], BodyModel],
                 make_sequence: Callable[[BodyModel], Sequence],
                 make_tracker: Callable[..., Tracker],
                 parallel_jobs: int = 1, source: Path | None = None,
                 wrap: Wrap | None = None, extra: Extra | None = None,
                 overrides: list[str] | None = None) -> dict | None:
    """Track the sequence with the tracker into ``out_dir``; returns the metrics written to
    metrics.json (None: skipped, already complete).

    config: the resolved run configuration (plain values; see the module docstring), stored
    in metrics.json and compared with a finished run's to resume. make_body(): the body;
    make_sequence(body): the data; make_tracker(body=, rig=, rng=, keep_particles=): the
    tracker. parallel_jobs: processes sharing the machine (a sweep's n_jobs; the "auto"
    thread budget divides the cores by it). source: the checkout whose git revision the
    run's metadata records (None: not recorded). wrap(tracker, body, seq): the tracker to step
    instead (it initialises and steps the given one; name, search budget and start-up flags
    are still the given tracker's). extra(metrics, result, body, seq): more metrics.
    overrides: the command line's overrides, kept in the manifest (the labels of the run).
    """
    with _sigterm_as_interrupt(), own_run_folder(out_dir):       # one writer per folder (issue 36)
        return _run(Path(out_dir), dict(config), make_body, make_sequence, make_tracker, parallel_jobs,
                    source, wrap, extra, overrides)


def _run(out_dir, config, make_body, make_sequence, make_tracker, parallel_jobs, source, wrap, extra,
         overrides):
    frames = check_settings(config)
    init_cfg = dict(config.get("init") or {})
    mode = init_cfg.get("mode", "gt_noise")
    if mode not in INIT_MODES:
        raise ValueError(f"init.mode must be one of {INIT_MODES}, got {mode!r}")
    rec_cfg = recording_settings(config.get("recording"))     # checked before any work
    recording = rec_cfg.enabled
    seed = int(config.get("seed", 0))
    threads = resolve_threads(config.get("threads", "auto"), parallel_jobs)
    out_dir.mkdir(parents=True, exist_ok=True)
    probe = out_dir / ".write-check"
    try:
        probe.touch()
        probe.unlink()
    except OSError as exc:
        raise PermissionError(f"run folder {out_dir} is not writable ({exc.strerror})") from None
    state = run_state(out_dir, config, recording, threads)
    if config.get("skip_complete", False):
        if state == "complete":
            print(f"skipping {out_dir}: already complete")
            return None
        killed = (out_dir / "recording.rrd.part").exists()
        if restore_previous(out_dir, config, recording, threads):
            if killed:
                print("removed recording.rrd.part (the recording of a killed run; it does not verify)",
                      file=sys.stderr)
            print(f"skipping {out_dir}: already complete (the run kept in previous_run/ restored)")
            return None
    if state == "changed" and config.get("resume_on_change", "rerun") == "fail":
        restore_stored_config(out_dir)      # Hydra has just overwritten it with the new one
        changed = ", ".join(config_changes(out_dir, config, threads))
        raise RunDirectoryConflict(f"{out_dir} holds a run of another configuration (changed: {changed}); "
                                   "resume_on_change=rerun reruns it")
    if state == "corrupt":
        print(f"{out_dir}: {manifest_problem(out_dir)}: running it again", file=sys.stderr)
    try:
        prepared = _prepare(config, mode, init_cfg, rec_cfg, seed, frames, make_body, make_sequence,
                            make_tracker, wrap)
        sink = make_sink(out_dir, rec_cfg)     # nothing written yet
    except BaseException:
        if state in ("complete", "changed"):
            restore_stored_config(out_dir)      # refused before any work: the old run stays as it was
        raise
    for note in set_aside(out_dir):     # nothing of an earlier attempt may describe this run
        print(note, file=sys.stderr)
    if getattr(prepared[2], "several_people", False):       # marker_people: mocap/run_folder/people.py
        from mocap.run_folder.people import track_people

        body, seq, tracker, *_, F = prepared
        return track_people(out_dir, config, body, seq, tracker, F, sink, recording, seed, threads, source,
                            overrides)
    return _track(out_dir, config, prepared, sink, recording, seed, threads, source, extra, overrides)


def _prepare(config, mode, init_cfg, rec_cfg, seed, frames, make_body, make_sequence, make_tracker, wrap):
    """Body, data, tracker and initial pose, every check before the run directory is touched."""
    body = make_body()
    seq = make_sequence(body)
    if frames is not None and frames > seq.num_frames:
        raise ValueError(f"setting frames = {frames} is beyond the data: {seq.name!r} has {seq.num_frames} "
                         "frames (frames=all or frames=null tracks every frame)")
    if (seq.gt is None or seq.gt.chi is None) and mode == "gt_noise":
        raise ValueError(f"sequence {seq.name!r} has no ground-truth pose chi: use init.mode=tracker")
    rng = np.random.default_rng(seed)
    keep_particles = rec_cfg.keep_particles
    tracker = make_tracker(body=body, rig=seq.rig, rng=np.random.default_rng([seed, 1]),
                           keep_particles=keep_particles)
    if hasattr(tracker, "check_sequence"):        # tracker/data compatibility, before any work
        tracker.check_sequence(seq)
    if getattr(tracker, "several_people", False):
        from mocap.run_folder.people import check_people_run

        check_people_run(tracker, mode, init_cfg, wrap)
        return body, seq, tracker, tracker, None, None, None, {}, seq.num_frames if frames is None else frames
    # ground truth this body cannot be scored against fails here, naming the joints, not after
    # the initialisation and tracking
    scorer = NameScorer(body, seq.gt.person(0)) if seq.gt is not None else None
    if seq.gt is not None and seq.gt.person_names:
        scorer = None           # several people: scored per person at the end (mocap.eval.people)
    if mode == "tracker":
        if not hasattr(tracker, "initial_estimate"):
            raise ValueError(f"tracker {tracker.name!r} cannot initialise itself: use init.mode=gt_noise")
        init, alpha, init_info = initial_estimate(tracker, frame_of(seq, 0), init_cfg.get("cache"))
    else:
        init_info = {}
        init = noisy_initial_pose(body, seq.gt.chi[0], rng, init_cfg["noise_deg"],
                                  init_cfg["noise_translation"])
        alpha = seq.gt.alpha
    stepped = wrap(tracker, body, seq) if wrap is not None else tracker
    F = seq.num_frames if frames is None else frames
    return body, seq, tracker, stepped, scorer, init, alpha, init_info, F


def _track(out_dir, config, prepared, sink, recording, seed, threads, source, extra, overrides):
    body, seq, tracker, stepped, scorer, init, alpha, init_info, F = prepared
    text = config_text(config)
    metadata = run_metadata(text, source, seed, tracker=tracker.name, data=seq.name)
    run_id = metadata.get("run_id", "")
    sink.start(RunInfo(text, metadata), body, seq)
    shapes = {"held": body.shaped(alpha)}
    recording_seconds = [0.0]

    def record(f, est, step_seconds, bar):
        t = time.perf_counter()
        if not np.array_equal(shapes["held"].alpha, est.alpha):     # refined while tracking
            shapes["held"] = body.shaped(est.alpha)
        shaped = shapes["held"]
        out = shaped.pose(est.chi)
        truth = err = None
        if scorer is not None:
            truth = scorer.truth_in_body_order(f)
            err = scorer.metrics(shaped, est.chi, start=f)["mpjpe_mm"]
        sink.frame(frame_of(seq, f), est, out.joints[0], out.vertices[0], truth, err, step_seconds)
        recording_seconds[0] += time.perf_counter() - t
        bar.update(1)

    t0 = time.perf_counter()
    with run_attempt(out_dir, sink):
        with tqdm(total=F, desc=f"{tracker.name} on {seq.name}", unit="frame") as bar:
            result = track_sequence(stepped, seq, init, alpha, F,
                                    on_frame=lambda f, e, s: record(f, e, s, bar), threads=threads)
        wall = time.perf_counter() - t0
        tracking_seconds = float(np.sum(result.seconds[1:]))
        metrics = {
            "tracker": tracker.name, "seed": seed, "data": seq.name,
            **run_metrics(body, seq, result.estimates, result.seconds),
            **search_budget(tracker),
            **({"init": init_info} if init_info else {}),
            # the numeric thread budget the run had: results depend on it at rounding level, and
            # a search can turn rounding into another track (rerun with threads=<this>)
            "threads": threads,
            "wall_seconds": wall, "tracking_seconds": tracking_seconds,
            "recording_seconds": recording_seconds[0],
            "recording_overhead": recording_seconds[0] / tracking_seconds if tracking_seconds else 0.0,
            "config": config,
        }
        metrics["quality"] = quality_flags(body, result.estimates[-1].alpha, result.estimates,
                                           float(np.linalg.norm(seq.rig.sizes, axis=1).max()),
                                           extra_flags=getattr(tracker, "start_up_flags", ()))
        if seq.meta.get("dropped_nonfinite"):        # data.nonfinite=drop: what was left out
            metrics["dropped_nonfinite"] = seq.meta["dropped_nonfinite"]
        if extra is not None:
            metrics.update(extra(metrics, result, body, seq))
        for flag in metrics["quality"]["flags"]:
            print(f"WARNING: {flag}", file=sys.stderr)
        # the motion first (kept when the recording fails), then the metrics, the recording,
        # and last the manifest that makes the folder a complete run
        vertices = bool((config.get("motion") or {}).get("vertices"))
        write_motion(out_dir / "motion.npz", motion_arrays(
            body, result.estimates, result.seconds, seq.fps, vertices=vertices,
            info={"tracker": tracker.name, "data": seq.name, "seed": seed, "run_id": run_id}))
        seal_run(out_dir, sink, metrics, recording, overrides)
    accuracy = ""
    if "mpjpe_mm" in metrics:
        spread = f" ± {metrics['mpjpe_std_mm']:.1f}" if "mpjpe_std_mm" in metrics else ""
        accuracy = f"MPJPE {metrics['mpjpe_mm']:.1f}{spread} mm, "
    if "people" in metrics:         # ground truth of several people
        accuracy += (f"{metrics['people_tracked']} of {metrics['people_in_ground_truth']} people tracked, "
                     f"{metrics['identity_switches']} identity switches, ")
    print(f"{tracker.name}: {accuracy}{metrics['sec_per_frame']:.2f} s/frame -> {out_dir}")
    return metrics

"""The run behind every tracking command (``mocap track``, ``mocap recovery``, ``mocap
video-check``): resume check, body / data / tracker from their factories, the start
(:func:`mocap.trackers.run.run_start`), the one frame loop (:func:`mocap.trackers.run.run_frames`,
for one person and for several alike) into the recording sink, then motion.npz, metrics.json
and recording.rrd in the run directory, in that order (the motion is kept when the recording
fails), and last ``manifest.json`` (their sizes and checksums, :mod:`mocap.run_folder.manifest`):
without it the folder is not a complete run. Commands differ only in the tracker they step
(``wrap``) and the metrics they add (``extra``). What differs between a single-person and a
several-people run (the recording of a frame, the motion file, the metrics) are small functions
chosen by the tracker's answer (:attr:`mocap.trackers.contract.Tracker.several_people`).

The run's settings are read from ``config``, the resolved configuration as plain values (what
metrics.json stores under ``"config"``; conf/tracking.yaml documents the keys), as
:class:`mocap.run_folder.settings.RunSettings`.

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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.quality import quality_flags
from mocap.eval.run_metrics import run_metrics
from mocap.export.motion import motion_arrays, write_motion
from mocap.export.people_motion import people_motion_arrays, write_people_motion
from mocap.recording.factory import make_sink
from mocap.recording.sink import RunInfo
from mocap.run_folder.attempt import own_run_folder, run_attempt, seal_run
from mocap.run_folder.manifest import manifest_problem
from mocap.run_folder.metadata import run_metadata
from mocap.run_folder.people import one_person_flag, people_metrics, several_people_evidence
from mocap.run_folder.resume import (
    config_changes,
    restore_previous,
    restore_stored_config,
    run_state,
    set_aside,
)
from mocap.run_folder.settings import INIT_MODES, RunSettings, check_settings  # noqa: F401  (re-exported)
from mocap.threads import resolve_threads, thread_budget
from mocap.trackers.contract import Tracker
from mocap.trackers.run import TrackResult, frame_of, require_pose, run_frames, run_start

#: wrap(tracker, body, seq): the tracker to step instead
Wrap = Callable[[Tracker, BodyModel, Sequence], Tracker]
#: extra(metrics, result, body, seq): more metrics, merged before metrics.json is written
Extra = Callable[[dict, TrackResult, BodyModel, Sequence], dict]


class RunDirectoryConflict(FileExistsError):
    """The run directory holds the results of another configuration (resume_on_change=fail)."""


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
    with _sigterm_as_interrupt(), own_run_folder(out_dir):       # one writer per folder
        return _run(Path(out_dir), dict(config), make_body, make_sequence, make_tracker, parallel_jobs,
                    source, wrap, extra, overrides)


def _run(out_dir, config, make_body, make_sequence, make_tracker, parallel_jobs, source, wrap, extra,
         overrides):
    settings = RunSettings.from_config(config)          # checked before any work
    recording = settings.recording.enabled
    threads = resolve_threads(settings.threads, parallel_jobs)
    out_dir.mkdir(parents=True, exist_ok=True)
    probe = out_dir / ".write-check"
    try:
        probe.touch()
        probe.unlink()
    except OSError as exc:
        raise PermissionError(f"run folder {out_dir} is not writable ({exc.strerror})") from None
    state = run_state(out_dir, config, recording, threads)
    if settings.skip_complete:
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
    if state == "changed" and settings.resume_on_change == "fail":
        restore_stored_config(out_dir)      # Hydra has just overwritten it with the new one
        changed = ", ".join(config_changes(out_dir, config, threads))
        raise RunDirectoryConflict(f"{out_dir} holds a run of another configuration (changed: {changed}); "
                                   "resume_on_change=rerun reruns it")
    if state == "corrupt":
        print(f"{out_dir}: {manifest_problem(out_dir)}: running it again", file=sys.stderr)
    try:
        prepared = _prepare(settings, threads, make_body, make_sequence, make_tracker, wrap)
        sink = make_sink(out_dir, settings.recording)     # nothing written yet
    except BaseException:
        if state in ("complete", "changed"):
            restore_stored_config(out_dir)      # refused before any work: the old run stays as it was
        raise
    for note in set_aside(out_dir):     # nothing of an earlier attempt may describe this run
        print(note, file=sys.stderr)
    return _track(out_dir, config, settings, prepared, sink, threads, source, extra, overrides)


@dataclass(frozen=True)
class _Prepared:
    """What a run tracks with: the body, the data, the tracker (``stepped``: the one stepped,
    ``wrap``'s), the single-person scorer (None: none), the start and its report, the frames."""

    body: BodyModel
    seq: Sequence
    tracker: Tracker
    stepped: Tracker
    scorer: NameScorer | None
    initial: dict
    init_info: dict
    frames: int
    several_people: dict | None = None


def _prepare(settings: RunSettings, threads, make_body, make_sequence, make_tracker, wrap) -> _Prepared:
    """Body, data, tracker and start, every check before the run directory is touched."""
    body = make_body()
    seq = make_sequence(body)
    frames = settings.frames
    if frames is not None and frames > seq.num_frames:
        raise ValueError(f"setting frames = {frames} is beyond the data: {seq.name!r} has {seq.num_frames} "
                         "frames (frames=all or frames=null tracks every frame)")
    init = settings.init
    if init.mode == "gt_noise":
        require_pose(seq)           # before the tracker is built
    rng = np.random.default_rng(settings.seed)
    tracker = make_tracker(body=body, rig=seq.rig, rng=np.random.default_rng([settings.seed, 1]),
                           keep_particles=settings.recording.keep_particles)
    tracker.check_sequence(seq)         # tracker/data compatibility, before any work
    if tracker.several_people and wrap is not None:
        raise ValueError(f"tracker {tracker.name!r} runs only with mocap track (this command wraps the "
                         "tracker)")
    # several people in the data, one followed: said now and kept in metrics.json (a flag, not an
    # error: following one subject among bystanders is what data.person=subject is for)
    several = several_people_evidence(seq)
    if tracker.several_people and several is not None and seq.meta.get("person") == "subject":
        # the opposite mistake, and one that cannot be what was meant: refused before any work
        raise ValueError(f"tracker {tracker.name!r} tracks several people, but data.person=subject keeps one "
                         f"per view ({several['why'].split(' (')[0]}): use data.person=all")
    several = None if tracker.several_people else several
    if several is not None:
        print(f"WARNING: {one_person_flag(several)}", file=sys.stderr)
    start = run_start(init.mode, tracker, body, seq, rng, init.noise_deg, init.noise_translation, init.cache)
    # ground truth this body cannot be scored against fails here, naming the joints, not after
    # the initialisation and tracking; several people are scored per person at the end
    scorer = None
    if seq.gt is not None:
        scorer = NameScorer(body, seq.gt.person(0))
        if seq.gt.person_names or tracker.several_people:
            scorer = None       # several people in the truth or the run: scored per person at the end
    with thread_budget(threads):
        initial, init_info = start(frame_of(seq, 0))
    stepped = wrap(tracker, body, seq) if wrap is not None else tracker
    return _Prepared(body, seq, tracker, stepped, scorer, initial, init_info,
                     seq.num_frames if frames is None else frames, several)


def _track(out_dir, config, settings: RunSettings, p: _Prepared, sink, threads, source, extra, overrides):
    body, seq, tracker = p.body, p.seq, p.tracker
    recording = settings.recording.enabled
    text = config_text(config)
    metadata = run_metadata(text, source, settings.seed, tracker=tracker.name, data=seq.name)
    sink.start(RunInfo(text, metadata), body, seq)
    record = (_people_recorder if tracker.several_people else _person_recorder)(body, seq, sink, p.scorer)
    start_seconds = float(p.init_info.get("seconds", 0.0))
    t0 = time.perf_counter()
    # a tracker whose final tracks revise the frames' answers (a smoothed track) is recorded from
    # them once tracking ends, so that the recording, motion.npz and metrics hold one track
    later = bool(p.stepped.revises_tracks)
    with run_attempt(out_dir, sink):
        with tqdm(total=p.frames, desc=f"{tracker.name} on {seq.name}", unit="frame") as bar:
            def on_frame(f, out, step_seconds):
                if not later:
                    record(f, out, start_seconds if f == 0 else step_seconds)
                bar.update(1)

            result = run_frames(p.stepped, seq, p.initial, p.frames, on_frame=on_frame, threads=threads)
        if later:
            for f in range(result.frames):
                out = {pid: t[f] for pid, t in result.tracks.items() if f in t}
                record(f, out, start_seconds if f == 0 else result.seconds[f])
        wall = time.perf_counter() - t0
        info = {"tracker": tracker.name, "data": seq.name, "seed": settings.seed,
                "run_id": metadata.get("run_id", "")}
        if result.several_people:
            metrics, arrays = _people_outputs(body, seq, tracker, result, info, start_seconds)
        else:
            metrics, arrays = _person_outputs(body, seq, tracker, result, info, p.init_info, settings.oracle,
                                              settings.motion.vertices)
        metrics.update(threads=threads, wall_seconds=wall, recording_seconds=record.seconds[0],
                       config=config)
        if not result.several_people:
            tracking = metrics["tracking_seconds"]
            metrics["recording_overhead"] = record.seconds[0] / tracking if tracking else 0.0
            metrics["quality"] = quality_flags(body, result.estimates[-1].alpha, result.estimates,
                                               float(np.linalg.norm(seq.rig.sizes, axis=1).max()),
                                               extra_flags=tracker.start_up_flags)
            if p.several_people is not None:
                metrics["several_people_data"] = p.several_people
                metrics["quality"].setdefault("flags", []).append(one_person_flag(p.several_people))
        if seq.meta.get("dropped_nonfinite"):        # data.nonfinite=drop: what was left out
            metrics["dropped_nonfinite"] = seq.meta["dropped_nonfinite"]
        if extra is not None:
            metrics.update(extra(metrics, result, body, seq))
        for flag in metrics.get("quality", {}).get("flags", ()):
            print(f"WARNING: {flag}", file=sys.stderr)
        if metrics.get("frames_without_detections"):        # tracked blind (mocap.eval.run_metrics)
            blind = metrics["frames_without_detections"]
            print(f"WARNING: {len(blind)} of {p.frames} frames had no detection in any view (tracked blind): "
                  f"frames {', '.join(map(str, blind[:20]))}{' ...' if len(blind) > 20 else ''}",
                  file=sys.stderr)
        # the motion first (kept when the recording fails), then the metrics, the recording,
        # and last the manifest that makes the folder a complete run
        (write_people_motion if result.several_people else write_motion)(out_dir / "motion.npz", arrays)
        seal_run(out_dir, sink, metrics, recording, overrides)
    print(f"{tracker.name}: {_summary(metrics)} -> {out_dir}")
    return metrics


# -- the parts that differ by what the estimates hold: one person, or several ----------------

def _person_recorder(body, seq, sink, scorer):
    """record(f, {0: estimate}, step seconds): the body posed at the estimate (its shape
    refined while tracking), its error against the ground truth, into the recording."""
    held = {}

    def record(f, out, step_seconds):
        t = time.perf_counter()
        est = out[0]
        offsets = getattr(est, "joint_offsets", None)
        if "shape" not in held or not held["shape"].is_for(est.alpha, offsets):
            held["shape"] = body.shaped(est.alpha, offsets)
        shaped = held["shape"]
        posed = shaped.pose(est.chi)
        truth = err = None
        if scorer is not None:
            truth = scorer.truth_in_body_order(f)
            err = scorer.metrics(shaped, est.chi, start=f)["mpjpe_mm"]
        sink.frame(frame_of(seq, f), est, posed.joints[0], posed.vertices[0], truth, err, step_seconds)
        record.seconds[0] += time.perf_counter() - t

    record.seconds = [0.0]
    return record


def _people_recorder(body, seq, sink, scorer):
    """record(f, {person id: estimate}, step seconds): each person's skeleton (one colour per
    person) and the several-people ground truth of the frame, into the recording."""
    from mocap.data.people_truth import people_truth

    truth = people_truth(seq)
    shaped: dict = {}

    def record(f, out, step_seconds):
        t = time.perf_counter()
        posed = {}
        for pid, est in out.items():
            if pid not in shaped or not shaped[pid].is_for(est.alpha):
                shaped[pid] = body.shaped(est.alpha)
            posed[pid] = (est, shaped[pid].pose(est.chi).joints[0])
        gt = truth.joints[f] if truth is not None and f < len(truth.joints) else None
        sink.people_frame(frame_of(seq, f), posed, gt, step_seconds)
        record.seconds[0] += time.perf_counter() - t

    record.seconds = [0.0]
    return record


def _person_outputs(body, seq, tracker, result, info, init_info, oracle, vertices):
    """(metrics, motion arrays) of a single-person run (:mod:`mocap.export.motion`)."""
    tracking_seconds = float(np.sum(result.seconds[1:]))
    metrics = {"tracker": tracker.name, "seed": info["seed"], "data": seq.name,
               **run_metrics(body, seq, result.estimates, result.seconds, oracle=oracle),
               **tracker.budget.as_metrics(),
               **({"init": init_info} if init_info else {}),
               "tracking_seconds": tracking_seconds}
    arrays = motion_arrays(body, result.estimates, result.seconds, seq.fps, vertices=vertices, info=info)
    return metrics, arrays


def _people_outputs(body, seq, tracker, result, info, start_seconds):
    """(metrics, motion arrays) of a several-people run (:mod:`mocap.run_folder.people`)."""
    F = result.frames
    arrays = people_motion_arrays(body, result.tracks, F, result.seconds, seq.fps, info=info)
    metrics = people_metrics(body, seq, tracker, result, arrays, start_seconds)
    return metrics, arrays


def _summary(metrics: dict) -> str:
    """The line printed at the end of a run: accuracy and speed."""
    if "people_per_frame" in metrics:           # several people
        accuracy = ""
        if "per_person" in metrics:
            if "people_in_ground_truth" in metrics:
                accuracy = (f"{metrics['people_tracked']} of {metrics['people_in_ground_truth']} people "
                            "tracked, ")
            accuracy += (f"{metrics['identity_switches']} identity switches, "
                         f"MPJPE {metrics['mpjpe_mm']:.1f} mm, "
                         f"PCP min {100 * metrics.get('pcp_min', float('nan')):.1f} %, ")
        return f"{len(metrics['people'])} people, {accuracy}{metrics['frames_per_second']:.2f} frames/s"
    accuracy = ""
    if "mpjpe_mm" in metrics:
        spread = f" ± {metrics['mpjpe_std_mm']:.1f}" if "mpjpe_std_mm" in metrics else ""
        accuracy = f"MPJPE {metrics['mpjpe_mm']:.1f}{spread} mm, "
    if "people" in metrics:         # ground truth of several people
        accuracy += (f"{metrics['people_tracked']} of {metrics['people_in_ground_truth']} people tracked, "
                     f"{metrics['identity_switches']} identity switches, ")
    return f"{accuracy}{metrics['sec_per_frame']:.2f} s/frame"

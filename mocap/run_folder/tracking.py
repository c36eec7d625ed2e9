"""The run behind every tracking command (``mocap track``, ``mocap recovery``, ``mocap
video-check``): resume check, body / data / tracker from their factories, initial pose, the
frame loop (:func:`mocap.trackers.run.track_sequence`) into the recording sink, then
motion.npz, metrics.json and recording.rrd in the run directory. Commands differ only in
the tracker they step (``wrap``) and the metrics they add (``extra``).

The run's settings are read from ``config``, the resolved configuration as plain values (what
metrics.json stores under ``"config"``; mocap_cli/conf/tracking.yaml documents the keys):

    seed, frames, threads            the data/tracker seed, frames to track (None: all), thread budget
    init.mode                        gt_noise (ground truth + noise) | tracker (self-initialised)
    init.noise_deg, init.noise_translation, init.cache
    recording.*                      keyword arguments of :func:`mocap.recording.factory.make_sink`
    motion.vertices                  keep the posed mesh per frame in motion.npz
    skip_complete, resume_on_change  resuming a sweep (:mod:`mocap.eval.resume`)
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from mocap.body.model import BodyModel
from mocap.data.sequence import Sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.quality import quality_flags
from mocap.eval.resume import clear_outputs, config_changes, restore_stored_config, run_state
from mocap.eval.run_metadata import run_metadata
from mocap.eval.run_metrics import run_metrics
from mocap.export.motion import motion_arrays, write_motion
from mocap.recording.factory import make_sink
from mocap.recording.sink import RunInfo
from mocap.run_folder.read import write_json
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


def config_text(config: Mapping) -> str:
    """The configuration as the YAML text a recording stores (and its hash is taken of)."""
    return yaml.dump(dict(config), default_flow_style=False, allow_unicode=True, sort_keys=False)


def run_tracking(out_dir: str | Path, config: Mapping, *,
                 make_body: Callable[[], BodyModel],
                 make_sequence: Callable[[BodyModel], Sequence],
                 make_tracker: Callable[..., Tracker],
                 parallel_jobs: int = 1, source: Path | None = None,
                 wrap: Wrap | None = None, extra: Extra | None = None) -> dict | None:
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
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    config = dict(config)
    init_cfg = dict(config.get("init") or {})
    mode = init_cfg.get("mode", "gt_noise")
    if mode not in INIT_MODES:
        raise ValueError(f"init.mode must be one of {INIT_MODES}, got {mode!r}")
    rec_cfg = dict(config.get("recording") or {})
    seed = int(config.get("seed", 0))
    state = run_state(out_dir, config, bool(rec_cfg.get("enabled", True)))
    if config.get("skip_complete", False) and state == "complete":
        print(f"skipping {out_dir}: already complete")
        return None
    if state == "changed" and config.get("resume_on_change", "rerun") == "fail":
        restore_stored_config(out_dir)      # Hydra has just overwritten it with the new one
        changed = ", ".join(config_changes(out_dir, config))
        raise RunDirectoryConflict(f"{out_dir} holds a run of another configuration (changed: {changed}); "
                                   "resume_on_change=rerun reruns it")
    clear_outputs(out_dir)          # nothing of an earlier attempt may describe this run
    body = make_body()
    seq = make_sequence(body)
    if (seq.gt is None or seq.gt.chi is None) and mode == "gt_noise":
        raise ValueError(f"sequence {seq.name!r} has no ground-truth pose chi: use init.mode=tracker")
    rng = np.random.default_rng(seed)
    keep_particles = bool(rec_cfg.get("enabled", True) and rec_cfg.get("particles", True))
    tracker = make_tracker(body=body, rig=seq.rig, rng=np.random.default_rng([seed, 1]),
                           keep_particles=keep_particles)
    if hasattr(tracker, "check_sequence"):        # tracker/data compatibility, before any work
        tracker.check_sequence(seq)
    # ground truth this body cannot be scored against fails here, naming the joints, not after
    # the initialisation and tracking
    scorer = NameScorer(body, seq.gt) if seq.gt is not None else None
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
    frames = config.get("frames")
    F = seq.num_frames if frames is None else min(int(frames), seq.num_frames)
    text = config_text(config)
    sink = make_sink(out_dir, **rec_cfg)
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

    threads = resolve_threads(config.get("threads", "auto"), parallel_jobs)
    t0 = time.perf_counter()
    try:
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
        if extra is not None:
            metrics.update(extra(metrics, result, body, seq))
    except BaseException:
        sink.finish(None, failed=True)
        raise
    for flag in metrics["quality"]["flags"]:
        print(f"WARNING: {flag}", file=sys.stderr)
    sink.finish(metrics)
    vertices = bool((config.get("motion") or {}).get("vertices"))
    write_motion(out_dir / "motion.npz", motion_arrays(
        body, result.estimates, result.seconds, seq.fps, vertices=vertices,
        info={"tracker": tracker.name, "data": seq.name, "seed": seed, "run_id": run_id}))
    write_json(out_dir / "metrics.json", metrics)
    accuracy = (f"MPJPE {metrics['mpjpe_mm']:.1f} ± {metrics['mpjpe_std_mm']:.1f} mm, "
                if "mpjpe_mm" in metrics else "")
    print(f"{tracker.name}: {accuracy}{metrics['sec_per_frame']:.2f} s/frame -> {out_dir}")
    return metrics

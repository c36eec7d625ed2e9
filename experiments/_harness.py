"""The run behind every tracking entry point (``track.py``, ``recovery.py``): resume check,
instantiate body / data / tracker, initial pose, the frame loop
(:func:`mocap.trackers.run.track_sequence`) into the recording sink, then motion.npz,
metrics.json and recording.rrd in the run directory. Entry points differ only in the
tracker they step (``wrap``) and the metrics they add (``extra``)."""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf
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
from mocap.threads import resolve_threads
from mocap.trackers.base import Tracker
from mocap.trackers.init_cache import initial_estimate
from mocap.trackers.run import TrackResult, frame_of, noisy_initial_pose, search_budget, track_sequence

REPO = Path(__file__).resolve().parents[1]

Wrap = Callable[[Tracker, BodyModel, Sequence], Tracker]
Extra = Callable[[dict, TrackResult], dict]


def write_json(path: Path, data: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    tmp.replace(path)


def parallel_jobs() -> int:
    """Jobs this run shares the machine with: the launcher's n_jobs in a --multirun."""
    hc = HydraConfig.get()
    if hc.mode != RunMode.MULTIRUN:
        return 1
    return int(hc.launcher.get("n_jobs", 1) or 1)


def run_tracking(cfg: DictConfig, wrap: Wrap | None = None, extra: Extra | None = None) -> dict | None:
    """Track ``cfg.data`` with ``cfg.tracker`` into the Hydra run directory; returns the
    metrics written to metrics.json (None: skipped, already complete).

    wrap(tracker, body, seq): the tracker to step instead (it initialises and steps the
    given one; name, search budget and start-up flags are still the given tracker's).
    extra(metrics, result): more metrics, merged before the recording and metrics.json end.
    """
    out_dir = Path(HydraConfig.get().runtime.output_dir)
    requested = OmegaConf.to_container(cfg, resolve=True)
    state = run_state(out_dir, requested, bool(cfg.recording.enabled))
    if cfg.skip_complete and state == "complete":
        print(f"skipping {out_dir}: already complete")
        return None
    if state == "changed" and cfg.get("resume_on_change", "rerun") == "fail":
        restore_stored_config(out_dir)      # Hydra has just overwritten it with the new one
        changed = ", ".join(config_changes(out_dir, requested))
        raise RuntimeError(f"{out_dir} holds a run of another configuration (changed: {changed}); "
                           "resume_on_change=rerun reruns it")
    clear_outputs(out_dir)          # nothing of an earlier attempt may describe this run
    body = instantiate(cfg.body)
    seq = instantiate(cfg.data, _partial_=True)(body=body)
    if cfg.init.mode not in ("gt_noise", "tracker"):
        raise ValueError(f"init.mode must be 'gt_noise' or 'tracker', got {cfg.init.mode!r}")
    if (seq.gt is None or seq.gt.chi is None) and cfg.init.mode == "gt_noise":
        raise ValueError(f"sequence {seq.name!r} has no ground-truth pose chi: use init.mode=tracker")
    rng = np.random.default_rng(cfg.seed)
    # objects go in through a partial: Hydra would turn dataclass kwargs into configs
    rec_cfg = cfg.recording
    tracker = instantiate(cfg.tracker, _partial_=True)(
        body=body, rig=seq.rig, rng=np.random.default_rng([cfg.seed, 1]),
        keep_particles=bool(rec_cfg.enabled and rec_cfg.particles))
    if hasattr(tracker, "check_sequence"):        # tracker/data compatibility, before any work
        tracker.check_sequence(seq)
    # ground truth this body cannot be scored against fails here, naming the joints, not after
    # the initialisation and tracking
    scorer = NameScorer(body, seq.gt) if seq.gt is not None else None
    if cfg.init.mode == "tracker":
        if not hasattr(tracker, "initial_estimate"):
            raise ValueError(f"tracker {tracker.name!r} cannot initialise itself: use init.mode=gt_noise")
        init, alpha, init_info = initial_estimate(tracker, frame_of(seq, 0), cfg.init.get("cache"))
    else:
        init_info = {}
        init = noisy_initial_pose(body, seq.gt.chi[0], rng, cfg.init.noise_deg, cfg.init.noise_translation)
        alpha = seq.gt.alpha
    stepped = wrap(tracker, body, seq) if wrap is not None else tracker
    F = seq.num_frames if cfg.frames is None else min(int(cfg.frames), seq.num_frames)
    config_yaml = OmegaConf.to_yaml(cfg, resolve=True)
    sink = make_sink(out_dir, **OmegaConf.to_container(rec_cfg))
    metadata = run_metadata(config_yaml, REPO, int(cfg.seed), tracker=tracker.name, data=seq.name)
    run_id = metadata.get("run_id", "")
    sink.start(RunInfo(config_yaml, metadata), body, seq)
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

    threads = resolve_threads(cfg.get("threads", "auto"), parallel_jobs())
    t0 = time.perf_counter()
    try:
        with tqdm(total=F, desc=f"{tracker.name} on {seq.name}", unit="frame") as bar:
            result = track_sequence(stepped, seq, init, alpha, F,
                                    on_frame=lambda f, e, s: record(f, e, s, bar), threads=threads)
        wall = time.perf_counter() - t0
        tracking_seconds = float(np.sum(result.seconds[1:]))
        metrics = {
            "tracker": tracker.name, "seed": int(cfg.seed), "data": seq.name,
            **run_metrics(body, seq, result.estimates, result.seconds),
            **search_budget(tracker),
            **({"init": init_info} if init_info else {}),
            # the numeric thread budget the run had: results depend on it at rounding level, and
            # a search can turn rounding into another track (rerun with threads=<this>)
            "threads": threads,
            "wall_seconds": wall, "tracking_seconds": tracking_seconds,
            "recording_seconds": recording_seconds[0],
            "recording_overhead": recording_seconds[0] / tracking_seconds if tracking_seconds else 0.0,
            "config": OmegaConf.to_container(cfg, resolve=True),
        }
        metrics["quality"] = quality_flags(body, result.estimates[-1].alpha, result.estimates,
                                           float(np.linalg.norm(seq.rig.sizes, axis=1).max()),
                                           extra_flags=getattr(tracker, "start_up_flags", ()))
        if extra is not None:
            metrics.update(extra(metrics, result))
    except BaseException:
        sink.finish(None, failed=True)
        raise
    for flag in metrics["quality"]["flags"]:
        print(f"WARNING: {flag}", file=sys.stderr)
    sink.finish(metrics)
    write_motion(out_dir / "motion.npz", motion_arrays(
        body, result.estimates, result.seconds, seq.fps, vertices=bool(cfg.get("motion", {}).get("vertices")),
        info={"tracker": tracker.name, "data": seq.name, "seed": int(cfg.seed), "run_id": run_id}))
    write_json(out_dir / "metrics.json", metrics)
    accuracy = (f"MPJPE {metrics['mpjpe_mm']:.1f} ± {metrics['mpjpe_std_mm']:.1f} mm, "
                if "mpjpe_mm" in metrics else "")
    print(f"{tracker.name}: {accuracy}{metrics['sec_per_frame']:.2f} s/frame -> {out_dir}")
    return metrics

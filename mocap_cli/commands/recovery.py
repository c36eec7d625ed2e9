"""``mocap recovery``: recovery from injected tracking failures: a frame skip, then a
large pose perturbation of the tracker's state, on a sequence with ground truth. The same run
as ``mocap track`` (:func:`mocap.run_folder.run_tracking`: motion.npz, metrics.json, recording.rrd)
with the tracker wrapped in :class:`mocap.trackers.failures.FailureInjection`.

    mocap recovery tracker=local data=walk_mpi08 seed=0 [frames=80]
    mocap recovery recovery.skip_at=10 recovery.skip=3 recovery.perturb_at=30

For each failure metrics.json's "recovery" holds the error before (mean of the 5 seen frames
before it), the error at its first frame and the number of frames until the error is back
under twice the level before (null: not recovered): :func:`mocap.eval.recovery.recovery_figures`.
"""

from __future__ import annotations

from omegaconf import DictConfig

from mocap_cli.hydra_edge import run_command, track_run


def task(cfg: DictConfig) -> None:
    # imported here: --help and argument errors import no numeric stack
    import numpy as np

    from mocap.eval.recovery import recovery_figures
    from mocap.trackers.failures import FailureInjection, FrameSkip, Perturbation

    r = cfg.recovery
    skip = FrameSkip(int(r.skip_at), int(r.skip)) if r.skip else None
    perturbation = None if r.perturb_at is None else Perturbation(
        int(r.perturb_at), float(r.perturb_deg), int(r.perturb_dofs),
        tuple(float(t) for t in r.perturb_translation))
    skips = [skip] if skip else []
    perturbations = [perturbation] if perturbation else []
    failures = {}           # failure -> the first frame the tracker sees after it
    if skip:
        failures["frame_skip"] = skip.resumes_at
    if perturbation:
        failures["perturbation"] = perturbation.at
    skipped = {f for s in skips for f in s.frames}
    window, factor = int(r.window), float(r.factor)

    def inject(tracker, body, seq):
        if seq.gt is None:
            raise ValueError(f"sequence {seq.name!r} has no ground truth: recovery cannot be measured")
        return FailureInjection(tracker, body, skips, perturbations, rng=np.random.default_rng([cfg.seed, 2]))

    def figures(metrics, result, body, seq):
        per_frame = metrics["per_frame_mm"]
        report = {name: recovery_figures(per_frame, at, skipped, window, factor)
                  for name, at in failures.items()}
        report["skipped_frames"] = sorted(skipped)
        return {"recovery": report}

    metrics = track_run(cfg, wrap=inject, extra=figures)
    for name in (metrics or {}).get("recovery", {}).keys() & failures.keys():
        f = metrics["recovery"][name]
        rec = f["frames_to_recover"]
        print(f"{metrics['tracker']} {name} at frame {f['at_frame']}: before {f['error_before_mm']:.1f} mm, "
              f"at {f['error_at_mm']:.1f} mm, "
              + (f"recovered after {rec} frames" if rec is not None else "not recovered"))


def main(argv: list[str] | None = None) -> int:
    """Run ``mocap recovery`` with Hydra overrides ``argv``."""
    return run_command(task, "recovery", "mocap recovery", argv)

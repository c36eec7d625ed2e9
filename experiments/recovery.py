"""Recovery from injected tracking failures (issue 5): a frame skip, then a large pose
perturbation of the tracker's state, on a sequence with ground truth. The same run as
track.py (experiments/_harness.py: motion.npz, metrics.json, recording.rrd) with the tracker
wrapped in :class:`mocap.trackers.failures.FailureInjection`.

    python experiments/recovery.py tracker=local data=walk_mpi08 seed=0 [frames=80]
    python experiments/recovery.py recovery.skip_at=10 recovery.skip=3 recovery.perturb_at=30

For each failure metrics.json's "recovery" holds the error before (mean of the 5 seen frames
before it), the error at its first frame and the number of frames until the error is back
under twice the level before (null: not recovered): :func:`mocap.eval.recovery.recovery_figures`.
"""

from __future__ import annotations

import hydra
import numpy as np
from _harness import run_tracking
from omegaconf import DictConfig

from mocap.eval.recovery import recovery_figures
from mocap.trackers.failures import FailureInjection, FrameSkip, Perturbation


@hydra.main(version_base="1.3", config_path="../mocap_cli/conf", config_name="recovery")
def main(cfg: DictConfig) -> None:
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

    def inject(tracker, body, seq):
        if seq.gt is None:
            raise ValueError(f"sequence {seq.name!r} has no ground truth: recovery cannot be measured")
        return FailureInjection(tracker, body, skips, perturbations, rng=np.random.default_rng([cfg.seed, 2]))

    def figures(metrics, result):
        per_frame = metrics["per_frame_mm"]
        report = {name: recovery_figures(per_frame, at, skipped, int(r.window), float(r.factor))
                  for name, at in failures.items()}
        report["skipped_frames"] = sorted(skipped)
        return {"recovery": report}

    metrics = run_tracking(cfg, wrap=inject, extra=figures)
    for name in (metrics or {}).get("recovery", {}).keys() & failures.keys():
        f = metrics["recovery"][name]
        rec = f["frames_to_recover"]
        print(f"{metrics['tracker']} {name} at frame {f['at_frame']}: before {f['error_before_mm']:.1f} mm, "
              f"at {f['error_at_mm']:.1f} mm, "
              + (f"recovered after {rec} frames" if rec is not None else "not recovered"))


if __name__ == "__main__":
    main()

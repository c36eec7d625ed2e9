"""``mocap track``: track a sequence with one tracker; write motion.npz, metrics.json and
recording.rrd into the Hydra run directory (the run itself: :func:`mocap.run_folder.run_tracking`).

    mocap track tracker=apf_prior data=walk_mpi08 seed=0
    mocap track --multirun tracker=apf,apf_prior seed=0,1,2
"""

from __future__ import annotations

from omegaconf import DictConfig

from mocap_cli.hydra_edge import run_command, track_run


def task(cfg: DictConfig) -> dict | None:
    """One run; returns its metrics (a launcher gathers them: Hydra's JobReturn.return_value)."""
    return track_run(cfg)


def main(argv: list[str] | None = None) -> int:
    """Run ``mocap track`` with Hydra overrides ``argv``."""
    return run_command(task, "track", "mocap track", argv)

"""Track a sequence with one tracker; write motion.npz (mocap/export/motion.py), metrics.json
and recording.rrd into the Hydra run directory (the run itself: experiments/_harness.py).

    python experiments/track.py tracker=apf_prior data=walk_mpi08 seed=0
    python experiments/track.py --multirun tracker=apf,apf_prior seed=0,1,2
"""

from __future__ import annotations

import hydra
from _harness import run_tracking
from omegaconf import DictConfig


@hydra.main(version_base="1.3", config_path="../mocap_cli/conf", config_name="track")
def main(cfg: DictConfig) -> None:
    run_tracking(cfg)


if __name__ == "__main__":
    main()

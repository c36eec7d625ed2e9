"""Training the Parzen pose prior from the procedural motion library's training motions
(``split="train"``, never the test sequences): ``mocap train-prior``. The prior trained on real
motion capture is made by the study experiments/prior_heldout.py (experiments/tools/real_prior.py)."""

from __future__ import annotations

import numpy as np

from mocap.body.model import BodyModel
from mocap.data.motion import ACTIONS, generate_motion
from mocap.energy.prior import ParzenPrior


def training_poses(body: BodyModel, samples: int = 100, seed: int = 0,
                   actions: tuple[str, ...] = ACTIONS, frames: int = 150, fps: float = 25.0) -> np.ndarray:
    """About ``samples`` joint-angle vectors (T, D - 6) drawn evenly from every action's
    training motions (``split="train"``, seeds ``seed, seed+1, ...``)."""
    per_action = int(np.ceil(samples / len(actions)))
    clips_per_action = max(1, per_action // 10)
    out = []
    for a in actions:
        for k in range(clips_per_action):
            chi = generate_motion(body, a, frames, fps=fps, seed=seed + k, split="train")
            pick = np.linspace(0, frames - 1, int(np.ceil(per_action / clips_per_action))).astype(int)
            out.append(chi[pick, 6:])
    poses = np.concatenate(out)[:samples]
    return poses.astype(np.float64)


def train_prior(body: BodyModel, samples: int = 100, seed: int = 0) -> ParzenPrior:
    return ParzenPrior.fit(training_poses(body, samples, seed), body.dof_names[6:],
                           source=f"{samples} poses of the training motions {', '.join(ACTIONS)} "
                                  f"(split=train, seed {seed}) for body '{body.name}'")

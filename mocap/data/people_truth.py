"""Ground truth of several people: joints with a person axis.

    truth = PeopleTruth(joints, joint_names)      # joints: (F, P, J, 3) world metres, NaN where absent

A sequence carries it in ``seq.meta["people_truth"]`` (the synthetic crowd,
:func:`mocap.data.crowd.crowd_sequence`); :func:`people_truth` reads it back.
:func:`mocap.eval.people_metrics.people_scores` scores estimates of several people against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KEY = "people_truth"


@dataclass(frozen=True)
class PeopleTruth:
    """joints: (F, P, J, 3) world metres, NaN where person p is absent (or a joint unmeasured);
    joint_names: (J,) names (mocap's joints, or any skeleton of :mod:`mocap.eval.by_name`)."""

    joints: np.ndarray
    joint_names: tuple[str, ...]

    def __post_init__(self) -> None:
        j = np.asarray(self.joints, np.float64)
        if j.ndim != 4 or j.shape[-1] != 3 or j.shape[2] != len(self.joint_names):
            raise ValueError(f"people truth joints must be (F, P, J={len(self.joint_names)}, 3), "
                             f"got {j.shape}")
        object.__setattr__(self, "joints", j)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))

    @property
    def present(self) -> np.ndarray:
        """(F, P) bool: the person is in the scene (any joint measured)."""
        return np.isfinite(self.joints[..., 0]).any(axis=-1)


def people_truth(seq) -> PeopleTruth | None:
    """The several-people ground truth a sequence carries (None: none)."""
    return (seq.meta or {}).get(KEY)

"""experiments/silhouette_floor.py: from the oracle, E_S lowered by shape then by every pose."""

from __future__ import annotations

from pathlib import Path

import pytest

import mocap
from mocap.data.sources import folder_sequence
from mocap.eval.mismatch import fit_oracle

REPO = Path(__file__).resolve().parents[2]
WALK = REPO / "data" / "mismatch" / "walk"


@pytest.mark.slow
@pytest.mark.skipif(not WALK.is_dir(), reason="the model-mismatch data is not in this checkout")
def test_the_floor_starts_at_the_oracle_and_each_pose_round_lowers_the_silhouette_energy():
    from experiments import silhouette_floor

    out = silhouette_floor.floor("mismatch_walk", rounds=1, keyframes=2, frames=3, seed=0)
    oracle, shape, poses = out["stages"]
    body = mocap.load_body("paper22")
    gt = folder_sequence(body=body, path=str(WALK), images=False).gt
    truth = fit_oracle(body, gt.joint_names, gt.joints[:3], None, gt.skeleton or None)
    assert oracle["raw_mm"] == pytest.approx(truth.metrics["raw_mm"], abs=0.01)   # float32 body vs float64
    # a pose is kept only where it lowers E_S
    assert poses["silhouette_energy"] <= shape["silhouette_energy"] + 1e-9
    assert out["keyframes"] == [0, 2] and out["frames"] == 3


def test_data_our_model_rendered_is_refused():
    from experiments import silhouette_floor

    with pytest.raises(ValueError, match="rendered by our own body model"):
        silhouette_floor.floor("walk_small", rounds=1, keyframes=2, frames=2, seed=0)

"""The pose prior trained on real motion capture (experiments/tools/real_prior.py): the leak
check before any work, training on train types only with the retargeting cached, the DOFs a
skeleton observes, the sample selection."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from experiments.tools.real_prior import (
    LOTO_SIGMAS,
    observed_dofs,
    select_samples,
    train_real_prior,
)
from mocap.clips.split import MotionSplit
from mocap.data.motion import generate_motion
from mocap.energy.prior_eval import kde_log_density


def test_training_with_a_held_out_type_raises_before_any_work(body, tmp_path):
    def never(path, body):
        raise AssertionError("retargeted a clip")

    with pytest.raises(ValueError, match="byebye are held out"):
        train_real_prior(tmp_path / "no-such-folder", body, types=("walk", "byebye"), retarget_fn=never)


def _fake_clips(folder: Path, motions: list[str]) -> None:
    """A clips folder with index.csv; each 'clip' file holds its motion name and take."""
    folder.mkdir()
    with (folder / "index.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["file", "motion"])
        for i, m in enumerate(motions):
            (folder / f"{m}_{i:03d}.bvh").write_text(f"{m} {i}\n")
            w.writerow([f"{m}_{i:03d}.bvh", m])


def test_real_prior_trains_on_train_types_only_and_caches_retargeting(body, tmp_path):
    # stand-in data: procedural actions play the motion types; 'box' is held out here
    split = MotionSplit(train=("walk", "jog"), held_out=("box",), dataset="fake")
    _fake_clips(tmp_path / "clips", ["walk", "walk", "jog", "box"])
    calls = []

    def fake_retarget(path: Path, body):
        motion, take = path.read_text().split()
        calls.append(motion)
        return generate_motion(body, motion, 30, seed=int(take), split="train").astype(np.float64)

    p = train_real_prior(tmp_path / "clips", body, split, samples=40, cache_dir=tmp_path / "cache",
                         retarget_fn=fake_retarget)
    assert sorted(calls) == ["jog", "walk", "walk"]                       # box never read
    assert len(p.samples) == 40 and p.dof_names == body.dof_names[6:]
    assert p.provenance.motion_types == ("jog", "walk") and p.provenance.held_out_types == ("box",)
    assert p.provenance.pool == 90 and p.provenance.clips == 3
    again = train_real_prior(tmp_path / "clips", body, split, samples=40, cache_dir=tmp_path / "cache",
                             retarget_fn=fake_retarget)
    assert len(calls) == 3                                               # all from the cache
    np.testing.assert_array_equal(again.samples, p.samples)
    assert again.provenance.clips_sha256 == p.provenance.clips_sha256
    (tmp_path / "clips" / "walk_000.bvh").write_text("walk 7\n")          # a changed clip
    third = train_real_prior(tmp_path / "clips", body, split, samples=40, cache_dir=tmp_path / "cache",
                             retarget_fn=fake_retarget)
    assert len(calls) == 4 and third.provenance.clips_sha256 != p.provenance.clips_sha256
    # sigma by leave-one-motion-type-out: the grid width under which walk best predicts jog and
    # jog walk; the samples are the same as with the paper's rule
    loto = train_real_prior(tmp_path / "clips", body, split, samples=40, sigma="loto",
                            cache_dir=tmp_path / "cache", retarget_fn=fake_retarget)
    np.testing.assert_array_equal(loto.samples, third.samples)
    motion = np.array(["jog"] * 30 + ["walk"] * 60)[select_samples(np.zeros((90, 1)), 40)]
    ll = [kde_log_density(loto.samples, loto.samples, s, motion, motion).mean() for s in LOTO_SIGMAS]
    assert loto.sigma == LOTO_SIGMAS[int(np.argmax(ll))]
    assert "leave-one-motion-type-out" in loto.provenance.sigma_rule
    sub = train_real_prior(tmp_path / "clips", body, split, samples=40, dofs=("l_knee_flex", "r_knee_flex"),
                           cache_dir=tmp_path / "cache", retarget_fn=fake_retarget)
    knees = [body.dof_names.index(d) - 6 for d in ("l_knee_flex", "r_knee_flex")]
    np.testing.assert_array_equal(sub.samples, third.samples[:, knees])
    with pytest.raises(ValueError, match="dofs l_wrist_flex are not joint angles"):
        train_real_prior(tmp_path / "clips", body, split, dofs=("l_wrist_flex",), retarget_fn=fake_retarget)
    with pytest.raises(ValueError, match="sigma='median'"):
        train_real_prior(tmp_path / "clips", body, split, sigma="median", retarget_fn=fake_retarget)


def test_observed_dofs_are_those_that_move_a_fitted_point(body_full):
    bandai = ("pelvis", "neck_base", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist",
              "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")
    got = observed_dofs(body_full, bandai)
    unseen = {d for d in body_full.dof_names[6:] if d.startswith("neck_") or "_wrist_" in d or "_ankle_" in d}
    assert set(got) == set(body_full.dof_names[6:]) - unseen
    # without the left elbow and wrist, nothing sees the left shoulder's three angles or the elbow
    no_left_arm = observed_dofs(body_full, [p for p in bandai if p not in ("l_elbow", "l_wrist")])
    assert set(got) - set(no_left_arm) == {"l_shoulder_flex", "l_shoulder_abd", "l_shoulder_rot",
                                           "l_elbow_flex"}


def test_sample_selection_uniform_and_farthest():
    pool = np.r_[np.zeros((50, 2)), np.ones((50, 2)), [[10.0, 10.0]]]
    u = select_samples(pool, 11, "uniform")
    np.testing.assert_array_equal(u, np.arange(0, 101, 10))
    f = select_samples(pool, 3, "farthest")
    assert set(map(tuple, pool[f])) == {(0.0, 0.0), (1.0, 1.0), (10.0, 10.0)}
    np.testing.assert_array_equal(select_samples(pool, 500), np.arange(101))
    with pytest.raises(ValueError, match="selection='random'"):
        select_samples(pool, 3, "random")

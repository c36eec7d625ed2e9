"""The model-mismatch benchmark shipped in data/mismatch (mocap_build/mismatch/procedural.py)."""

from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from mocap.body.skeletons import SKELETONS
from mocap.data.corruption import SilhouetteNoise
from mocap.eval.by_name import NameScorer
from mocap_build.mismatch import procedural as mm
from mocap_cli.conf_schema import register_configs

REPO = Path(__file__).resolve().parents[2]
CONF = REPO / "conf"
register_configs()              # the tracker presets and data defaults conf/ composes
CONFIGS = {"mismatch_walk": "walk", "mismatch_box": "box", "mismatch_gesture": "gesture_turn"}


def load(name: str, body, *overrides: str):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=[f"data={name}", *overrides])
    return instantiate(cfg.data, _partial_=True)(body=body)


@pytest.fixture(scope="module")
def sequences(body):
    return {name: load(name, body) for name in CONFIGS}


def test_the_module_does_not_need_torch():
    import subprocess
    import sys

    code = "import sys, mocap_build.mismatch.procedural; assert 'torch' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


@pytest.mark.parametrize("name", list(CONFIGS))
def test_shipped_sequences_load_with_8_views_60_frames_and_gt_by_name(sequences, body, name):
    seq = sequences[name]
    assert seq.masks.shape == (60, 8, 500, 500)
    assert seq.masks.reshape(60, 8, -1).any(axis=-1).all()          # no empty mask
    edge = seq.masks[..., 0, :] | seq.masks[..., -1, :] | seq.masks[..., 0] | seq.masks[..., -1]
    assert not edge.any()                                           # never clipped
    assert seq.gt.chi is None and seq.gt.alpha is None
    assert seq.gt.skeleton == "humaneva15" and seq.gt.joints.shape == (60, 15, 3)
    assert set(seq.gt.joint_names) == set(SKELETONS["humaneva15"])
    assert all(SKELETONS["humaneva15"][n] is not None for n in seq.gt.joint_names)
    NameScorer(body, seq.gt)                    # resolves every name against our model's points
    assert "anny" in seq.meta["source"] and "not by the tracker" in seq.meta["source"]
    assert seq.meta["motion"] == CONFIGS[name]


@pytest.mark.parametrize("name", list(CONFIGS))
def test_ground_truth_is_anatomically_plausible(sequences, name):
    gt = sequences[name].gt
    J = {n: gt.joints[:, i] for i, n in enumerate(gt.joint_names)}
    length = lambda a, b: np.linalg.norm(J[a] - J[b], axis=-1)  # noqa: E731
    for side in "lr":
        thigh, shin = length(f"{side}hip", f"{side}kne"), length(f"{side}kne", f"{side}ank")
        upper, fore = length(f"{side}sho", f"{side}elb"), length(f"{side}elb", f"{side}wri")
        assert 0.33 < thigh.min() and thigh.max() < 0.55
        assert 0.30 < shin.min() and shin.max() < 0.55
        assert 0.2 < upper.min() and upper.max() < 0.4
        assert 0.18 < fore.min() and fore.max() < 0.35
        for bone in (thigh, shin, upper, fore):                      # rigid bones
            assert np.ptp(bone) < 1e-3
    assert 0.2 < length("lhip", "rhip").min() and length("lhip", "rhip").max() < 0.4
    assert (J["head"][:, 2] > J["thorax"][:, 2]).all() and (J["thorax"][:, 2] > J["pelvis"][:, 2]).all()
    assert J["lank"][:, 2].min() > 0.0 and min(J["lank"][:, 2].min(), J["rank"][:, 2].min()) < 0.15
    assert np.linalg.norm(gt.joints[..., :2], axis=-1).max() < 1.3   # stays near the origin


def test_motions_move_the_spine_neck_and_head(sequences):
    for seq in sequences.values():
        J = {n: seq.gt.joints[:, i] for i, n in enumerate(seq.gt.joint_names)}
        head_rel = J["head"] - J["thorax"]
        assert np.ptp(head_rel, axis=0).max() > 0.02
    turn = sequences["mismatch_gesture"].gt
    i, k = turn.joint_names.index("lhip"), turn.joint_names.index("rhip")
    d0, d1 = (turn.joints[f, i, :2] - turn.joints[f, k, :2] for f in (0, -1))
    ang = np.degrees(np.arctan2(np.cross(d0, d1), d0 @ d1))
    assert 75 < ang < 105                                            # turns ~90 deg left


def test_view_subset(body, sequences):
    seq = load("mismatch_walk", body, "data.views=[0,2,4,6]")
    full = sequences["mismatch_walk"]
    assert seq.num_views == 4 and list(seq.rig.names) == ["cam_00", "cam_02", "cam_04", "cam_06"]
    assert np.array_equal(seq.masks, full.masks[:, [0, 2, 4, 6]])
    by_name = load("mismatch_walk", body, "data.views=[cam_02,cam_05]")
    assert np.array_equal(by_name.masks, full.masks[:, [2, 5]])
    with pytest.raises(ValueError, match="views"):
        load("mismatch_walk", body, "data.views=[0,0]")


def test_silhouette_noise_is_deterministic_per_seed(body, sequences):
    noise = "data.silhouette_noise={holes:2,dilate_px:3,shadow:1.0}"
    a = load("mismatch_box", body, noise, "data.views=[1,5]", "seed=3")
    b = load("mismatch_box", body, noise, "data.views=[1,5]", "seed=3")
    c = load("mismatch_box", body, noise, "data.views=[1,5]", "seed=4")
    exact = sequences["mismatch_box"].masks[:, [1, 5]]
    assert np.array_equal(a.masks, b.masks)
    assert not np.array_equal(a.masks, c.masks)
    assert not np.array_equal(a.masks, exact)
    assert a.masks.sum() > exact.sum()                  # dilation and shadow add more than holes remove
    assert a.meta["silhouette_noise"]["shadow"] == 1.0


def test_shadow_attaches_below_the_silhouette():
    mask = np.zeros((200, 200), bool)
    mask[40:150, 70:130] = True
    out = SilhouetteNoise(shadow=1.0).apply(mask, np.random.default_rng(0))
    assert out[mask].all()
    added = out & ~mask
    ys, xs = np.nonzero(added)
    assert len(ys) > 20 and ys.min() >= 140 and ys.max() > 149     # a blob at the feet
    assert SilhouetteNoise(shadow=1.0).active and not SilhouetteNoise().active


def test_frame_zero_regenerates_exactly():
    pytest.importorskip("torch")
    pytest.importorskip("anny")
    seq = load_shipped("box")
    r = mm.render(mm.SEQUENCES["box"], frames=1)
    assert np.array_equal(r.masks[0], seq.masks[0])
    np.testing.assert_allclose(r.joints[0], seq.gt.joints[0], atol=1e-6)


def load_shipped(name):
    from mocap.data.sequence_io import load_sequence

    return load_sequence(REPO / "data" / "mismatch" / name)

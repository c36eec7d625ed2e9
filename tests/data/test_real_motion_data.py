"""The real-motion benchmark shipped in data/real_motion (mocap_build/mismatch/real_motion.py):
real motion-capture clips drive anny's own skeleton and skinning."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from mocap.body.catalogue import make_landmark_set
from mocap.body.skeletons import SKELETONS
from mocap.cameras import project
from mocap.eval.by_name import NameScorer
from mocap_build.mismatch import real_motion as rm
from mocap_cli import data_dir
from mocap_cli.conf_schema import register_configs

REPO = Path(__file__).resolve().parents[2]
CONF = REPO / "conf"
register_configs()              # the tracker presets and data defaults conf/ composes
DATA = REPO / "data" / "real_motion"
CLIPS = REPO.parent / "shared" / "data" / "real-motion"
SPLIT = yaml.safe_load((REPO / "mocap" / "clips" / "split.yaml").read_text())
SPECS = {s.key: s for s in rm.SEQUENCES}


def load(spec, body, *overrides: str):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=[f"data=real_{spec.name}", *overrides])
    return instantiate(cfg.data, _partial_=True)(body=body)


@pytest.fixture(scope="module")
def shipped():
    from mocap.data.sequence_io import load_sequence

    return {k: load_sequence(DATA / k, images=False) for k in SPECS}


def test_the_module_does_not_need_torch():
    import subprocess
    import sys

    code = "import sys, mocap_build.mismatch.real_motion; assert 'torch' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


def test_split_follows_split_yaml_and_every_split_sees_every_subject_and_both_sexes():
    index = json.loads((DATA / "index.json").read_text())["sequences"]
    assert set(index) == set(SPECS) and len(SPECS) >= 12
    for split, allowed in (("dev", SPLIT["train"]), ("test", SPLIT["held_out"])):
        specs = [s for s in SPECS.values() if s.split == split]
        assert {s.motion for s in specs} <= set(allowed)
        assert {s.subject for s in specs} == set(rm.SUBJECTS)
        genders = [rm.SUBJECTS[s.subject].phenotype["gender"] for s in specs]
        assert min(genders) < 0.5 < max(genders)
    assert sorted(s.motion for s in SPECS.values() if s.split == "test") == sorted(SPLIT["held_out"])
    assert len({s.motion for s in SPECS.values()}) >= 6
    for key, entry in index.items():
        spec = SPECS[key]
        assert entry["split"] == spec.split and entry["clip"] == spec.clip
        assert entry["clip_frames"][1] - entry["clip_frames"][0] == 60
        assert 1.55 <= entry["stature_m"] <= 1.95
        assert (DATA / entry["folder"] / "sequence.json").is_file()
    notice = (DATA / "NOTICE.txt").read_text()
    assert "Apache License 2.0" in notice and "CC BY-NC 4.0" in notice and "Bandai Namco Research" in notice


@pytest.mark.parametrize("key", list(SPECS))
def test_shipped_sequences_have_8_views_60_frames_gt_by_name_and_detections(shipped, body, key):
    seq = shipped[key]
    assert seq.masks.shape == (60, 8, 500, 500) and seq.fps == 30.0
    assert seq.masks.reshape(60, 8, -1).any(axis=-1).all()
    edge = seq.masks[..., 0, :] | seq.masks[..., -1, :] | seq.masks[..., 0] | seq.masks[..., -1]
    assert not edge.any()
    assert seq.gt.chi is None and seq.gt.skeleton == "humaneva15" and seq.gt.joints.shape == (60, 15, 3)
    assert set(seq.gt.joint_names) == set(SKELETONS["humaneva15"])
    NameScorer(body, seq.gt)
    assert seq.meta["split"] == SPECS[key].split and "anny" in seq.meta["source"]
    # detections: HumanEva-15 joints under our catalogue's names, corrupted as DETECTION says
    det = seq.detections
    assert len(make_landmark_set(body, "auto", det.labels)) == 15
    order = [det.labels.index(SKELETONS["humaneva15"][n]) for n in seq.gt.joint_names]
    truth = np.stack([project(seq.rig, j) for j in seq.gt.joints])              # (F, C, 15, 2)
    label_of = np.empty(15, int)
    label_of[order] = np.arange(15)
    err = np.linalg.norm(det.xy - truth[det.frame, det.view, label_of[det.label]], axis=-1)
    true_hits = err < 10.0                       # false positives land anywhere, true ones within 5 sigma
    rate = true_hits.sum() / (60 * 8 * 15)
    assert abs(rate - rm.DETECTION["detection_rate"]) < 0.03
    assert abs(np.sqrt(np.mean(err[true_hits] ** 2) / 2) - rm.DETECTION["noise_px"]) < 0.2
    assert (~true_hits).sum() > 0.5 * rm.DETECTION["false_positive_rate"] * 60 * 8 * 15


@pytest.mark.parametrize("key", list(SPECS))
def test_ground_truth_is_rigid_and_knees_bend_forwards(shipped, key):
    gt = shipped[key].gt
    J = {n: gt.joints[:, i] for i, n in enumerate(gt.joint_names)}
    for a, b in (("lhip", "lkne"), ("lkne", "lank"), ("lsho", "lelb"), ("lelb", "lwri"),
                 ("rhip", "rkne"), ("rkne", "rank"), ("rsho", "relb"), ("relb", "rwri")):
        assert np.ptp(np.linalg.norm(J[a] - J[b], axis=-1)) < 1e-3
    left = J["lhip"] - J["rhip"]
    for s in "lr":
        u, f = J[f"{s}kne"] - J[f"{s}hip"], J[f"{s}ank"] - J[f"{s}kne"]
        bend = np.arccos(np.sum(u * f, -1) / np.linalg.norm(u, axis=-1) / np.linalg.norm(f, axis=-1))
        sense = np.sum(np.cross(u, f) * left, -1)             # > 0: the shin swings backwards
        assert (sense[bend > np.deg2rad(15)] > 0).all()
    assert (J["head"][:, 2] > J["pelvis"][:, 2]).all()
    assert min(J["lank"][:, 2].min(), J["rank"][:, 2].min()) < 0.15
    assert np.linalg.norm(gt.joints[..., :2], axis=-1).max() < 1.5


NO_CLIPS = "the real-motion clips (../shared/data/real-motion) are absent"
LIMBS = ((("sho", "elb"), ("UpperArm", "LowerArm")), (("elb", "wri"), ("LowerArm", "Hand")),
         (("hip", "kne"), ("UpperLeg", "LowerLeg")), (("kne", "ank"), ("LowerLeg", "Foot")))


@pytest.mark.skipif(not CLIPS.is_dir(), reason=NO_CLIPS)
@pytest.mark.parametrize("key", list(SPECS))
def test_bone_directions_and_joint_angles_are_the_clips(shipped, key):
    """Directions from the clip, lengths from anny: each limb of the ground truth points where
    the clip's does (after the sequence's turn about z), elbow and knee angles are the clip's."""
    seq = shipped[key]
    a, b = seq.meta["clip_frames"]
    J, _ = rm.load_clip(CLIPS / seq.meta["clip"])
    R = rm._rot_z(np.deg2rad(seq.meta["yaw_deg"]))
    C = {n: v[a:b] @ R.T for n, v in J.items()}
    G = {n: seq.gt.joints[:, i] for i, n in enumerate(seq.gt.joint_names)}
    unit = lambda v: v / np.linalg.norm(v, axis=-1, keepdims=True)  # noqa: E731
    for s, S in (("l", "L"), ("r", "R")):
        for (g0, g1), (c0, c1) in LIMBS:
            cos = np.sum(unit(G[s + g1] - G[s + g0]) * unit(C[f"{c1}_{S}"] - C[f"{c0}_{S}"]), -1)
            assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.05, (s, g0, g1)


def test_config_paths_resolve_from_the_repository_root_and_noise_works(body, monkeypatch, shipped):
    monkeypatch.chdir(REPO)
    spec = next(s for s in SPECS.values() if s.split == "test")
    seq = load(spec, body, "data.views=[0,4]")
    assert seq.num_views == 2 and np.array_equal(seq.masks, shipped[spec.key].masks[:, [0, 4]])
    noise = "data.silhouette_noise={holes:2,dilate_px:3,shadow:1.0}"
    a = load(spec, body, noise, "data.views=[0,4]", "seed=3")
    b = load(spec, body, noise, "data.views=[0,4]", "seed=3")
    assert np.array_equal(a.masks, b.masks) and not np.array_equal(a.masks, seq.masks)
    assert a.masks.sum() > seq.masks.sum()
    for s in SPECS.values():
        cfg = yaml.safe_load((CONF / "data" / f"real_{s.name}.yaml").read_text())
        assert cfg["path"] == f"${{mocap_data:}}/real_motion/{s.key}"
        assert (Path(data_dir()) / "real_motion" / s.key).is_dir()


@pytest.mark.slow
def test_frame_zero_regenerates_exactly(shipped):
    """Deterministic generator: frame 0 of one sequence (masks, joints) and all its detections."""
    pytest.importorskip("torch")
    pytest.importorskip("anny")
    if not CLIPS.is_dir():
        pytest.skip(NO_CLIPS)
    spec = SPECS["test/punch_tall_man"]
    seq = shipped[spec.key]
    r = rm.render(spec, CLIPS, render_frames=[0])
    assert np.array_equal(r.masks[0], seq.masks[0])
    np.testing.assert_allclose(r.joints, seq.gt.joints, atol=1e-9)
    assert r.start == seq.meta["clip_frames"][0]
    assert abs(r.floor_gap.min()) < 1e-9                         # the lowest vertex is on the floor
    det = rm.detect(r.joints, seq.rig, rm.sequence_seed(spec))
    for field in ("frame", "view", "label", "xy", "confidence"):
        assert np.array_equal(getattr(det, field), getattr(seq.detections, field)), field

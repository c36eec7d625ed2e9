"""The realistic detector simulator (mocap/data/detector_semantics.py) does what it promises."""

from pathlib import Path

import numpy as np
import pytest

from mocap.cameras import project, triangulate
from mocap.data.detector_semantics import (
    DetectorSemantics,
    configured_offsets,
    keypoint_frames,
    semantics_from,
    simulate,
)
from mocap.data.sequence_io import load_sequence

DATA = Path(__file__).resolve().parents[2] / "data"
WALK = DATA / "real_motion" / "dev" / "walk_heavy_man"
QUIET = {"swap_rate": 0.0, "foreign_limb_rate": 0.0, "gross_rate": 0.0, "false_positive_rate": 0.0,
         "detection_rate": 1.0, "noise_px": 0.0, "offset_jitter_mm": 0.0}


@pytest.fixture(scope="module")
def walk():
    seq = load_sequence(WALK, images=False)
    from mocap.data.detector_semantics import gt_keypoint_names

    return seq, gt_keypoint_names(seq.gt)


def _table(det, F, C, J):
    """(F, C, J, 2) pixels of the single detection per (frame, view, label), NaN where none."""
    out = np.full((F, C, J, 2), np.nan)
    out[det.frame, det.view, det.label] = det.xy
    return out


def test_the_offsets_mean_is_the_configured_offsets(walk):
    """Exact projections of offset keypoints, triangulated and brought into each keypoint's
    frame, give back the configured offsets ("out" mirrored for right keypoints)."""
    seq, names = walk
    s = DetectorSemantics(**QUIET)
    sim = simulate(seq.gt.joints, names, seq.rig, s, np.random.default_rng(0))
    F, J = seq.gt.joints.shape[:2]
    px = _table(sim.detections, F, len(seq.rig), J)
    X = triangulate(seq.rig, np.moveaxis(px, 1, 0))                       # (F, J, 3)
    frames = keypoint_frames(seq.gt.joints, names)
    local = np.einsum("fjab,fja->fjb", frames, X - seq.gt.joints)        # (F, J, 3) metres
    want = configured_offsets(names, s)
    np.testing.assert_allclose(local.mean(axis=0), want, atol=5e-4)
    hip, r_hip = names.index("l_hip"), names.index("r_hip")
    assert np.linalg.norm(want[hip]) == max(np.linalg.norm(want, axis=1))  # the hips the largest
    assert want[hip, 0] == -want[r_hip, 0] > 0                            # wider on both sides
    assert 0.02 < np.linalg.norm(want, axis=1).mean() < 0.05              # a few cm


def test_offsets_are_fixed_per_sequence_with_jitter_around_the_mean(walk):
    seq, names = walk
    s = DetectorSemantics(**{**QUIET, "offset_jitter_mm": 5.0})
    draws = np.stack([simulate(seq.gt.joints[:2], names, seq.rig, s, np.random.default_rng(k)).offsets_local
                      for k in range(200)])
    np.testing.assert_allclose(draws.mean(axis=0), configured_offsets(names, s), atol=1.5e-3)
    assert draws.std(axis=0).mean() == pytest.approx(0.005, rel=0.15)


def test_swap_frames_exchange_left_and_right_in_one_view(walk):
    seq, names = walk
    s = DetectorSemantics(**{**QUIET, "swap_rate": 0.2})
    sim = simulate(seq.gt.joints, names, seq.rig, s, np.random.default_rng(1))
    assert sim.swapped.any() and sim.swapped.sum(axis=1).max() == 1         # one view at a time
    F, J = seq.gt.joints.shape[:2]
    px = _table(sim.detections, F, len(seq.rig), J)
    true = np.moveaxis(project(seq.rig, sim.keypoints.reshape(-1, 3)).reshape(len(seq.rig), F, J, 2), 0, 1)
    left, right = names.index("l_wrist"), names.index("r_wrist")
    mid = names.index("mid_hip")
    for f, c in zip(*np.nonzero(sim.swapped), strict=True):
        np.testing.assert_allclose(px[f, c, left], true[f, c, right], atol=1e-9)
        np.testing.assert_allclose(px[f, c, right], true[f, c, left], atol=1e-9)
        np.testing.assert_allclose(px[f, c, mid], true[f, c, mid], atol=1e-9)   # no side: unchanged
    ok = ~sim.swapped
    np.testing.assert_allclose(px[ok], true[ok], atol=1e-9)


def test_foreign_limbs_come_from_another_person(walk):
    seq, names = walk
    s = DetectorSemantics(**{**QUIET, "foreign_limb_rate": 0.1})
    sim = simulate(seq.gt.joints, names, seq.rig, s, np.random.default_rng(2))
    F, J = seq.gt.joints.shape[:2]
    assert sim.foreign.any()
    counts = sim.foreign.sum(axis=2)
    assert set(np.unique(counts)) <= {0, 2}                                # a limb: a distal pair
    px = _table(sim.detections, F, len(seq.rig), J)
    true = np.moveaxis(project(seq.rig, sim.keypoints.reshape(-1, 3)).reshape(len(seq.rig), F, J, 2), 0, 1)
    err = np.linalg.norm(px - true, axis=-1)
    seen = np.isfinite(err)
    assert np.all(err[sim.foreign & seen] > 20)                            # ~0.9 m away
    np.testing.assert_allclose(err[~sim.foreign & seen], 0, atol=1e-9)


def test_confidence_says_little_about_the_error(walk):
    seq, names = walk
    sim = simulate(seq.gt.joints, names, seq.rig, semantics_from({"semantics": "realistic"}),
                   np.random.default_rng(3))
    F, J = seq.gt.joints.shape[:2]
    C = len(seq.rig)
    det = sim.detections
    bad = (sim.foreign | sim.swapped[:, :, None])[det.frame, det.view, det.label]
    assert bad.sum() > 10
    # wrong keypoints get about the confidence of right ones
    assert abs(det.confidence[bad].mean() - det.confidence[~bad].mean()) < 0.1
    assert det.confidence[bad].max() > 0.9
    assert len(det) > 0.9 * F * C * J


def test_the_same_seed_gives_the_same_detections_and_another_seed_others(walk):
    seq, names = walk
    s = semantics_from({"semantics": "realistic"})
    a, b, c = (simulate(seq.gt.joints, names, seq.rig, s, np.random.default_rng(k)) for k in (5, 5, 6))
    np.testing.assert_array_equal(a.detections.xy, b.detections.xy)
    np.testing.assert_array_equal(a.detections.confidence, b.detections.confidence)
    np.testing.assert_array_equal(a.swapped, b.swapped)
    assert len(a.detections) != len(c.detections) or not np.array_equal(a.detections.xy, c.detections.xy)


def test_folder_option_simulates_detections_and_views_share_them(body):
    from mocap.data.sources import folder_sequence

    full = folder_sequence(body=body, path=str(WALK), images=False, seed=4,
                           detections={"semantics": "realistic"})
    four = folder_sequence(body=body, path=str(WALK), images=False, seed=4, views=[0, 2, 4, 6],
                           detections={"semantics": "realistic"})
    keep = np.isin(full.detections.view, [0, 2, 4, 6])
    np.testing.assert_array_equal(four.detections.xy, full.detections.xy[keep])
    assert full.meta["detections"]["semantics"] == "realistic"
    plain = folder_sequence(body=body, path=str(WALK), images=False, seed=4, detections={"semantics": None})
    assert len(plain.detections) != len(full.detections)


def test_bad_options_fail_with_one_line():
    with pytest.raises(ValueError, match="detections.semantics must be one of"):
        semantics_from({"semantics": "openpose"})
    with pytest.raises(ValueError, match="unknown option"):
        semantics_from({"semantics": "realistic", "swap": 0.1})
    with pytest.raises(ValueError, match="swap_rate"):
        semantics_from({"semantics": "realistic", "swap_rate": 2.0})


def test_canton_preset_is_canton_ferrer_corruption_alone(walk):
    """``semantics=canton``: the keypoints are the joints (no offsets, swaps or foreign limbs),
    about 90 % of them detected, 2 px Gaussian noise, 0.1 false positives per keypoint."""
    seq, names = walk
    s = semantics_from({"semantics": "canton"})
    sim = simulate(seq.gt.joints, names, seq.rig, s, np.random.default_rng(3))
    np.testing.assert_array_equal(sim.keypoints, seq.gt.joints)
    assert not sim.swapped.any() and not sim.foreign.any()
    F, J = seq.gt.joints.shape[:2]
    C = len(seq.rig)
    det = sim.detections
    truth = np.stack([project(seq.rig, seq.gt.joints[f]) for f in range(F)])     # (F, C, J, 2)
    err = np.linalg.norm(det.xy - truth[det.frame, det.view, det.label], axis=-1)
    true_hits = err < 12.0                       # 6 sigma of 2 px; a false positive this close is rare
    assert 0.86 < true_hits.sum() / (F * C * J) < 0.94          # clipped at the image border: a little less
    assert np.sqrt(np.mean(err[true_hits] ** 2) / 2) == pytest.approx(2.0, rel=0.08)
    assert 0.07 < (~true_hits).sum() / (F * C * J) < 0.13

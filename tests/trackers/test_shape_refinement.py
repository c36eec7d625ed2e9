"""Shape refinement while tracking (:mod:`mocap.trackers.shape_search`): the shape searched on
the silhouettes of several keyframes with their poses held, kept only where it explains them
better; the trackers carry it on, and the scoring follows a shape that changes."""

from __future__ import annotations

import numpy as np
import pytest

from mocap.cameras import project, ring_rig
from mocap.data.generate import make_synthetic
from mocap.eval.estimates import per_shape
from mocap.eval.run_metrics import accuracy_metrics
from mocap.render import get_rasterizer
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import track_sequence
from mocap.trackers.shape_search import refine_shape
from mocap.trackers.tracker_settings import ShapeRefinement

SEARCH = ShapeRefinement(every=1, particles=60, layers=8, std=0.6, shift=0.02, min_gain=0.01,
                         resolution=200)                      # the masks' own size: scale 1


@pytest.fixture(scope="module")
def keyframes(body):
    """Masks of a subject of another build than the mean, in three poses (standing, knees
    bent, arms raised) seen by 4 cameras."""
    rig = ring_rig(4, 3.5, 1.5, 200, 200, fov_deg=45, look_at=(0, 0, 0.9))
    alpha = np.zeros(body.num_shape)
    alpha[:4] = [1.5, -1.2, 1.0, 0.8]
    chis = np.zeros((3, body.num_dofs))
    for name, value in (("l_knee_flex", 1.0), ("r_knee_flex", 0.6), ("l_hip_flex", 0.6)):
        chis[1, body.dof_index(name)] = value
    for name in ("l_shoulder_abd", "r_shoulder_abd"):
        chis[2, body.dof_index(name)] = 1.2
    raster = get_rasterizer(body.faces, body.num_vertices)
    masks = []
    for chi in chis:
        px, depth = project(rig, body.pose(chi[None], alpha[None]).vertices[0], return_depth=True)
        masks.append(raster(px, 200, 200, depth, near=0.05))
    return rig, alpha, chis, masks


def rest_joint_error_mm(body, a, b):
    return 1e3 * float(np.linalg.norm(body.shaped(a).rest_joints - body.shaped(b).rest_joints, axis=1).mean())


def test_refinement_finds_the_subjects_build_from_its_keyframes(body, keyframes):
    rig, truth, chis, masks = keyframes
    mean = np.zeros(body.num_shape)
    found = refine_shape(body, rig, mean, chis, masks, (0, 1, 2), SEARCH, np.random.default_rng(0))
    assert found.accepted and found.energy_after < 0.8 * found.energy_before
    before, after = rest_joint_error_mm(body, mean, truth), rest_joint_error_mm(body, found.alpha, truth)
    assert after < 0.5 * before, (before, after)
    assert np.abs(found.shift).max() <= SEARCH.shift + 1e-12


def test_refinement_keeps_a_shape_that_already_explains_the_keyframes(body, keyframes):
    rig, truth, chis, masks = keyframes
    found = refine_shape(body, rig, truth, chis, masks, (0, 1, 2), SEARCH, np.random.default_rng(0))
    assert not found.accepted
    np.testing.assert_array_equal(found.alpha, truth)
    np.testing.assert_array_equal(found.shift, np.zeros(3))


@pytest.mark.parametrize("bad", [{"every": -1}, {"keyframes": 0}, {"stride": 0}, {"particles": 1},
                                 {"std": 0.0}, {"shift": -0.1}, {"resolution": 0}])
def test_bad_settings_are_refused_when_made(bad):
    with pytest.raises(ValueError, match=f"setting {next(iter(bad))} = .* is out of range"):
        ShapeRefinement(**bad)


@pytest.fixture(scope="module")
def clip(body):
    rig = ring_rig(4, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    return make_synthetic(body, rig, motion="walk", frames=5, fps=25, seed=3, shape_scale=1.5, images=False)


def test_the_local_tracker_refines_on_schedule_and_carries_the_shape_on(body, clip):
    shape = {"every": 2, "keyframes": 3, "stride": 1, "particles": 40, "layers": 6, "std": 0.5}
    tracker = make_tracker("local", body=body, rig=clip.rig, rng=np.random.default_rng(0), iterations=3,
                           shape=shape, misalignment={"threshold": 2.0})      # no limb ever flagged
    mean = np.zeros(body.num_shape)
    result = track_sequence(tracker, clip, clip.gt.chi[0], mean)
    updates = {f: e.diagnostics.shape for f, e in enumerate(result.estimates) if e.diagnostics.shape}
    assert sorted(updates) == [2, 4]
    assert updates[2].keyframes == (1, 2) and updates[4].keyframes == (2, 3, 4)
    alphas = np.stack([e.alpha for e in result.estimates])
    np.testing.assert_array_equal(alphas[1], mean)                      # before the first search
    for f, u in updates.items():                                        # a kept shape from its frame on
        assert u.accepted == (not np.array_equal(alphas[f], alphas[f - 1]))
    assert any(u.accepted for u in updates.values())
    truth = clip.gt.alpha
    assert rest_joint_error_mm(body, alphas[-1], truth) < rest_joint_error_mm(body, mean, truth)
    assert tracker.shaped.alpha is not None and np.array_equal(tracker.shaped.alpha, alphas[-1])


def test_frames_with_a_flagged_limb_are_not_keyframes(body, clip):
    """A shape fitted to a wrong pose would make up for it: with every limb flagged no frame is
    a keyframe, no search runs and the shape stays."""
    shape = {"every": 2, "keyframes": 3, "stride": 1, "particles": 10, "layers": 2}
    tracker = make_tracker("local", body=body, rig=clip.rig, rng=np.random.default_rng(0), iterations=1,
                           shape=shape, misalignment={"threshold": -1.0})     # every limb flagged
    result = track_sequence(tracker, clip, clip.gt.chi[0], np.zeros(body.num_shape))
    assert all(e.diagnostics.misalignment.limbs for e in result.estimates[1:])
    assert not any(e.diagnostics.shape for e in result.estimates) and len(tracker.keyframes) == 0
    np.testing.assert_array_equal(result.estimates[-1].alpha, np.zeros(body.num_shape))


def test_scoring_follows_a_shape_that_changes_during_the_run(body, clip):
    """Per-frame shapes score each frame with its own shape: the same as scoring each frame
    alone; a single shape for the run is the (K,) form."""
    F = clip.num_frames
    chis = clip.gt.chi[:F]
    alphas = np.repeat(clip.gt.alpha[None], F, axis=0)
    alphas[2:, 0] += 1.0
    joints = per_shape(body, alphas, chis, lambda shaped, c: shaped.joints(c))
    for f in range(F):
        np.testing.assert_array_equal(joints[f], body.shaped(alphas[f]).joints(chis[f][None])[0])
    per_frame = accuracy_metrics(body, clip, chis, alphas)["per_frame_mm"]
    assert per_frame[0] == pytest.approx(0.0, abs=1e-3) and per_frame[1] == pytest.approx(0.0, abs=1e-3)
    assert min(per_frame[2:]) > 5.0
    single = accuracy_metrics(body, clip, chis, clip.gt.alpha)
    assert single["mpjpe_mm"] == pytest.approx(0.0, abs=1e-3)
    with pytest.raises(ValueError, match="shapes for"):
        per_shape(body, alphas[:2], chis, lambda shaped, c: shaped.joints(c))

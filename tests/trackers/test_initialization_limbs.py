"""The start's limb hypotheses (``InitSettings.limb_hypotheses``, :func:`scan_limbs`): a limb drawn
anew keeps the other DOFs and its limits, takes a motion library's angles where it has them, and
an arm the start put raised where the silhouettes show it hanging is brought back, the fine E_S
falling; off (0, the default), the start is the old one."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.trackers.initialization import dof_partitions, limb_candidates, scan_limbs
from mocap.trackers.presets import make_tracker
from mocap.trackers.tracker_settings import InitSettings

ARM = ("l_elbow", "l_wrist")


def test_limb_candidates_draw_only_the_free_dofs_within_the_limits(body):
    rng = np.random.default_rng(0)
    chi = np.zeros(body.num_dofs)
    free = dof_partitions(body)[1]
    out = limb_candidates(chi, free, 50, body.limits, rng)
    np.testing.assert_array_equal(out[:, ~free], 0.0)
    assert np.all(out[:, free] >= body.limits[free, 0]) and np.all(out[:, free] <= body.limits[free, 1])
    assert np.ptp(out[:, free], axis=0).min() > 0                    # every free DOF varies


def test_limb_candidates_take_the_library_angles_where_it_has_them(body):
    free = dof_partitions(body)[1]
    cols = np.flatnonzero(free)
    row = np.full(body.num_dofs, np.nan)
    row[cols[0]] = np.mean(body.limits[cols[0]])                   # one known angle, the rest NaN
    out = limb_candidates(np.zeros(body.num_dofs), free, 20, body.limits, np.random.default_rng(1), row[None])
    np.testing.assert_array_equal(out[:, cols[0]], row[cols[0]])
    assert np.ptp(out[:, cols[1:]], axis=0).min() > 0               # NaN: drawn uniformly


def test_off_by_default_on_for_the_silhouette_only_hybrid():
    from mocap.trackers.presets import preset_settings

    assert InitSettings().limb_hypotheses == 0
    assert preset_settings("hybrid").initialization.limb_hypotheses > 0
    assert preset_settings("hybrid").initialization.limb_stage == "end"
    assert preset_settings("hybrid_kp").initialization == InitSettings()      # its keypoints refine it


def test_bad_limb_settings_are_refused_naming_the_field():
    with pytest.raises(ValueError, match="limb_keep"):
        InitSettings(limb_keep=0)
    with pytest.raises(ValueError, match="limb_stage"):
        InitSettings(limb_stage="middle")


def raised_arm(body, chi):
    """The left arm lifted sideways by 1.2 rad and its elbow bent by 1 rad."""
    out = np.array(chi, np.float64)
    out[body.dof_index("l_shoulder_abd")] += 1.2
    out[body.dof_index("l_elbow_flex")] += 1.0
    return np.clip(out, body.limits[:, 0], body.limits[:, 1])


def arm_error_mm(shaped, chi, truth) -> float:
    idx = [shaped.model.joint_names.index(j) for j in ARM]
    got, want = shaped.joints(chi[None])[0][idx], shaped.joints(truth[None])[0][idx]
    return 1000 * float(np.linalg.norm(got - want, axis=1).mean())


def test_a_raised_arm_is_brought_back_and_the_fine_energy_falls(body):
    """With the hybrid's motion library (the pose prior's training poses, mirrored), as the hybrid
    passes it to its start."""
    rig = ring_rig(6, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="walk", frames=1, fps=25, seed=0, images=False)
    shaped = body.shaped(seq.gt.alpha)
    truth = np.asarray(seq.gt.chi[0], np.float64)
    start = raised_arm(body, truth)
    before = arm_error_mm(shaped, start, truth)
    assert before > 150
    coarse, fine = SilhouetteEnergy(shaped, rig, 0.5), SilhouetteEnergy(shaped, rig, 1.0)
    masks = seq.masks[0]
    t_c, t_f = silhouette_target(masks, 0.5), silhouette_target(masks, 1.0)
    settings = InitSettings(limb_hypotheses=150, limb_keep=2, limb_particles=20, limb_layers=5)
    spread = np.r_[np.zeros(6), np.full(body.num_dofs - 6, 0.15)]
    limbs = dof_partitions(body)[1:]
    library = make_tracker("hybrid", body=body, rig=rig, rng=np.random.default_rng(0)).library
    assert library is not None
    chi, changed = scan_limbs(start, lambda x: coarse(x, t_c), lambda x: fine(x, t_f), limbs, body.limits,
                              spread, settings, np.random.default_rng(3), library)
    left_arm = next(k for k, m in enumerate(limbs) if m[body.dof_index("l_elbow_flex")])
    assert left_arm in changed
    assert fine(chi[None], t_f)[0] < fine(start[None], t_f)[0]
    after = arm_error_mm(shaped, chi, truth)
    assert after < 0.3 * before and after < 60, (before, after)
    np.testing.assert_array_equal(chi[:6], start[:6])               # the root is not searched


def test_at_the_end_only_limbs_that_lower_the_fine_energy_change(body):
    """``limb_stage="end"``: the steps before draw the same numbers as without the limb
    hypotheses, so the start differs only in the limbs whose search lowered the winner's fine E_S."""
    from mocap.trackers.initialization import initialize_from_silhouettes

    rig = ring_rig(4, 3.5, 1.5, 160, 120, fov_deg=45, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="walk", frames=1, fps=25, seed=2, images=False)
    cheap = dict(headings=4, hypotheses=1, keep=1, rounds=0, resolution=96, select_resolution=160,
                 pose_particles=12, pose_layers=3, local_iterations=2)
    old, alpha_old, _ = initialize_from_silhouettes(body, rig, seq.masks[0], np.random.default_rng(0),
                                                    InitSettings(**cheap))
    new, alpha_new, diag = initialize_from_silhouettes(
        body, rig, seq.masks[0], np.random.default_rng(0),
        InitSettings(limb_hypotheses=40, limb_keep=1, limb_particles=10, limb_layers=3, limb_stage="end",
                     **cheap))
    np.testing.assert_array_equal(alpha_new, alpha_old)
    fine = SilhouetteEnergy(body.shaped(alpha_old), rig, 1.0)
    target = silhouette_target(seq.masks[0], 1.0)
    e_old, e_new = fine(np.stack([old, new]), target)
    changed = diag["limbs_changed_at_end"]
    assert changed and e_new < e_old                  # cheap settings leave limbs to find: [1, 2], -21 %
    limbs = dof_partitions(body)[1:]
    kept = ~np.any([limbs[k] for k in changed], axis=0)
    np.testing.assert_array_equal(new[kept], old[kept])          # the root and the other limbs as they were

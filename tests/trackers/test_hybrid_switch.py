"""The hybrid tracker's switch: local optimisation every frame, the APF over the misaligned
limbs only when the misalignment check flags one (Zhang et al. 2013)."""

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, track_sequence

LOCAL = {"iterations": 2}
APF = {"particles": 12, "layers": 3}


@pytest.fixture(scope="module")
def seq(body):
    rig = ring_rig(4, 3.5, 1.5, 200, 150, fov_deg=45, look_at=(0, 0, 0.9))
    return make_synthetic(body, rig, motion="walk", frames=3, fps=25, seed=0, images=False)


def hybrid(body, seq, threshold, seed=0):
    return make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(seed),
                        local={**LOCAL, "misalignment": {"threshold": threshold}}, apf=APF)


def test_switch_never_fires_above_every_limb_error_and_then_hybrid_is_local(body, seq):
    h = hybrid(body, seq, threshold=1.5)          # a limb error is a share of vertices: <= 1
    loc = make_tracker("local", body=body, rig=seq.rig, rng=np.random.default_rng(0), **LOCAL)
    rh, rl = (track_sequence(t, seq, seq.gt.chi[0], seq.gt.alpha) for t in (h, loc))
    for e in rh.estimates[1:]:
        m = e.diagnostics.misalignment
        assert m.apf_called is False and m.limbs == () and e.diagnostics.anneal is None
        assert set(m.limb_errors) and max(m.limb_errors.values()) <= 1.0
    np.testing.assert_array_equal(np.stack([e.chi for e in rh.estimates]),
                                  np.stack([e.chi for e in rl.estimates]))


def test_switch_forced_on_searches_every_limb(body, seq):
    h = hybrid(body, seq, threshold=-1.0)         # every limb flagged
    h.initialize(seq.gt.chi[0], seq.gt.alpha)
    e = h.step(frame_of(seq, 1))
    m = e.diagnostics.misalignment
    assert m.apf_called is True
    assert set(m.limbs) == set(body.joint_names)     # the pelvis and all after it in the chain
    assert set(m.free_dofs) == set(body.dof_names)     # root flagged: the global twist too
    assert len(e.diagnostics.anneal.layers) == APF["layers"]
    assert e.diagnostics.anneal.evaluations == APF["particles"] * APF["layers"]


def test_a_wrong_arm_is_flagged_and_searched_alone(body, seq):
    """Frame 1 started with the left arm raised 90 degrees off the truth (shoulder flexion) and
    no local iterations, before or after the search (so nothing else moves): the check flags the left
    upper arm and forearm, the APF searches the DOFs of those limbs and of their parent joint
    only, and brings the left wrist within a fifth of its starting error."""
    start = seq.gt.chi[1].copy()
    k = body.dof_index("l_shoulder_flex")
    start[k] += np.radians(90)
    assert body.limits[k, 0] <= start[k] <= body.limits[k, 1]
    h = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng(0),
                     local={"iterations": 0, "misalignment": {"threshold": 0.15}},
                     apf={"particles": 25, "layers": 6, "refine_iterations": 0})
    h.initialize(start, seq.gt.alpha)
    e = h.step(frame_of(seq, 1))
    m = e.diagnostics.misalignment
    assert m.apf_called is True and "l_elbow" in m.limbs
    assert not {"pelvis", "r_elbow", "l_knee", "r_knee"} & set(m.limbs)
    assert set(m.free_dofs) == {"l_shoulder_flex", "l_shoulder_abd", "l_shoulder_rot", "l_elbow_flex"}
    assert m.limb_errors["l_elbow"] > 0.15 and m.limb_errors["pelvis"] < 0.15
    shaped = body.shaped(seq.gt.alpha)
    wrist = body.joint_names.index("l_wrist")
    err = [1e3 * np.linalg.norm(shaped.pose(c[None]).joints[0, wrist] - seq.gt.joints[1, wrist])
           for c in (start, e.chi)]
    assert err[0] > 400 and err[1] < 0.2 * err[0], err
    free = [body.dof_index(d) for d in m.free_dofs]
    held = np.setdiff1d(np.arange(body.num_dofs), free)
    np.testing.assert_allclose(e.chi[held], start[held], atol=1e-12)   # no local iterations

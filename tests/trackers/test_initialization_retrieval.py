"""The start by retrieval (``InitSettings.search = "retrieval"``, :mod:`mocap.trackers.init_retrieval`):
the library's rows and candidates laid out as documented, distinct picks, a coordinate search that
finds a known minimum and never raises the energy, a body rendered in a library pose at a known
heading retrieved exactly and started within a few cm, the setting checked and in the cache key."""

from __future__ import annotations

import numpy as np
import pytest

import mocap
from mocap.body.twists import se3_exp
from mocap.cameras import project, ring_rig
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.render import get_rasterizer
from mocap.settings import SettingError
from mocap.trackers import init_retrieval as retrieval
from mocap.trackers.initialization import initialize_from_silhouettes, root_twist
from mocap.trackers.tracker_settings import InitSettings


@pytest.fixture(scope="module")
def body():
    return mocap.load_body("paper22")


def rendered(body, chi, size=160):
    rig = ring_rig(4, 3.5, 1.5, size, size, fov_deg=45, look_at=(0, 0, 0.9))
    px, depth = project(rig, body.pose(chi[None]).vertices[0], return_depth=True)
    return rig, get_rasterizer(body.faces, body.num_vertices)(px, size, size, depth, near=0.05)


def test_joint_rows_read_nan_as_rest_clip_to_the_limits_and_drop_duplicates(body):
    D = body.num_dofs
    lib = np.full((3, D), np.nan)
    lib[0, 6] = 10.0                                      # beyond the upper limit
    lib[1, 7] = 0.1
    lib[2] = lib[1]                                       # a duplicate
    rows = retrieval.joint_rows(lib, body.limits)
    want = np.zeros((3, D - 6))                           # the rest pose first, then rows 0 and 1
    want[1, 0] = body.limits[6, 1]
    want[2, 1] = 0.1
    np.testing.assert_array_equal(rows, want)
    np.testing.assert_array_equal(retrieval.joint_rows(None, body.limits), np.zeros((1, D - 6)))


def test_candidates_are_heading_major_with_the_root_turned_about_the_centre(body):
    joints = np.arange(2 * (body.num_dofs - 6), dtype=float).reshape(2, -1)
    yaws = np.array([0.0, np.pi / 2, np.pi])
    cands = retrieval.retrieval_candidates(joints, yaws, np.array([0.3, -0.2, 0.9]))
    assert cands.shape == (6, body.num_dofs)
    for h, yaw in enumerate(yaws):
        for p in range(2):
            np.testing.assert_array_equal(cands[2 * h + p, 6:], joints[p])
            np.testing.assert_allclose(cands[2 * h + p, :6], root_twist(yaw, 0.3, -0.2))
    T = se3_exp(cands[2:3, :6])[0]                         # 90 deg about z, then to (0.3, -0.2)
    np.testing.assert_allclose(T[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [0.3, -0.2, 0.0], atol=1e-12)


def test_distinct_best_skips_a_candidate_near_one_already_picked():
    yaws = np.radians([0.0, 30.0, 180.0])
    joints = np.array([[0.0, 0.0], [0.01, 0.0], [1.0, 1.0]])      # rows 0 and 1 alike, row 2 not
    # heading-major (3 headings x 3 rows); lowest first: (0 deg, row 0), (30 deg, row 1): close
    # in heading and pose, skipped; (0 deg, row 2): another pose; (180 deg, row 0): another heading
    e = np.full(9, 9.0)
    e[[0, 4, 2, 6]] = [0.1, 0.2, 0.3, 0.4]
    assert retrieval.distinct_best(e, yaws, joints, 3, np.pi / 4, 0.25) == [0, 2, 6]
    # the ties at 9.0 in index order: only (180 deg, row 2) is far from every pick
    assert retrieval.distinct_best(e, yaws, joints, 9, np.pi / 4, 0.25) == [0, 2, 6, 8]


def test_the_coordinate_search_finds_a_quadratic_minimum_and_never_raises_the_energy():
    D = 10
    goal = np.r_[np.zeros(6), np.linspace(-0.5, 0.5, D - 6)]
    limits = np.tile([-2.0, 2.0], (D, 1))
    parts = [np.arange(D) < 6, np.arange(D) >= 6]

    def energy(x):
        return np.sum((np.atleast_2d(x) - goal) ** 2, axis=1)

    start = np.r_[np.zeros(6), np.full(D - 6, 0.4)]
    chi, e = retrieval.coordinate_search(energy, start, parts, np.full(D, 0.3), limits,
                                         np.random.default_rng(0), samples=60, sweeps=6, shrink=0.6)
    assert e == energy(chi)[0] and e < 0.05 * energy(start)[0]
    np.testing.assert_allclose(chi, goal, atol=0.1)
    # from the minimum itself nothing is accepted: the pose comes back unchanged
    same, e0 = retrieval.coordinate_search(energy, goal, parts, np.full(D, 0.3), limits,
                                           np.random.default_rng(1), samples=20, sweeps=2)
    np.testing.assert_array_equal(same, goal)
    assert e0 == 0.0
    # a library row holding the limb's exact angles is taken in the first sweep
    lib = np.tile(goal, (3, 1))
    lib[:2, 6:] += 1.0
    found, _ = retrieval.coordinate_search(energy, start, parts[1:], np.zeros(D), limits,
                                           np.random.default_rng(2), samples=1, sweeps=1, library=lib)
    np.testing.assert_array_equal(found, goal)


def test_a_library_pose_at_a_known_heading_is_retrieved_exactly(body):
    lib = retrieval.library_of(body)
    joints = retrieval.joint_rows(lib, body.limits)
    yaws = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    truth_h, truth_p = 3, 17
    cands = retrieval.retrieval_candidates(joints, yaws, np.zeros(3))
    rig, masks = rendered(body, cands[truth_h * len(joints) + truth_p])
    energy = SilhouetteEnergy(body.shaped(), rig, 0.8)
    e = energy(cands, silhouette_target(masks, 0.8))
    assert int(np.argmin(e)) == truth_h * len(joints) + truth_p


def test_the_library_is_the_procedural_priors_poses_and_their_mirror_images(body):
    from mocap.energy.prior import ParzenPrior, default_prior_path
    from mocap.trackers.hybrid_tracker import library_poses

    prior = ParzenPrior.load(default_prior_path(body.name))
    np.testing.assert_array_equal(retrieval.library_of(body),
                                  library_poses(body, prior.samples, prior.dof_names))


@pytest.mark.slow
def test_a_rendered_pose_is_started_within_a_few_centimetres(body):
    """Arms raised and a knee bent (not a library pose), facing 100 deg: the whole start with cheap
    settings lands near it, facing the right way."""
    chi = np.zeros(body.num_dofs)
    chi[:6] = root_twist(np.radians(100), 0.1, -0.05)
    for name, angle in (("l_shoulder_abd", 1.3), ("r_shoulder_abd", 0.6), ("r_elbow_flex", 1.0),
                        ("l_hip_flex", 0.5), ("l_knee_flex", 0.8)):
        chi[body.dof_index(name)] = angle
    chi = np.clip(chi, body.limits[:, 0], body.limits[:, 1])
    rig, masks = rendered(body, chi)
    truth = body.shaped().joints(chi[None])[0]
    cheap = InitSettings(search="retrieval", retrieval_headings=12, retrieval_keep=3, retrieval_samples=30,
                         keep=1, resolution=128, retrieval_resolution=96, select_resolution=160,
                         shape_particles=10, shape_layers=3, local_iterations=5)
    est, alpha, diag = retrieval.initialize_by_retrieval(body, rig, masks, np.random.default_rng(0), cheap)
    assert diag["search"] == "retrieval"
    error_mm = np.linalg.norm(body.shaped(alpha).joints(est[None])[0] - truth, axis=1).mean() * 1000
    assert error_mm < 40, error_mm
    T = se3_exp(est[None, :6])[0]
    yaw = np.degrees(np.arctan2(T[1, 0], T[0, 0]))
    assert abs((yaw - 100 + 180) % 360 - 180) < 30


def test_the_start_runs_the_search_its_settings_name(body, monkeypatch):
    from mocap.trackers import initialization
    from mocap.trackers.base import Frame
    from mocap.trackers.init_cache import SilhouetteStart

    rig, masks = rendered(body, np.zeros(body.num_dofs), size=32)
    ran = []

    def fake(name):
        def compute(body, rig, masks, rng, settings, progress=None, library=None):
            ran.append(name)
            return np.zeros(body.num_dofs), np.zeros(body.num_shape), {}
        return compute

    monkeypatch.setattr(retrieval, "initialize_by_retrieval", fake("retrieval"))
    monkeypatch.setattr(initialization, "initialize_from_silhouettes", fake("anneal"))
    frame = Frame(index=0, masks=masks, images=None, detections=None)
    for settings in (InitSettings(), InitSettings(search="retrieval")):
        SilhouetteStart(body, rig, settings, np.random.default_rng(0), progress=lambda s, f: None)(frame)
    assert ran == ["anneal", "retrieval"]
    monkeypatch.undo()
    with pytest.raises(ValueError, match="search = 'retrieval'"):     # before any work
        initialize_from_silhouettes(body, rig, masks, np.random.default_rng(0),
                                    InitSettings(search="retrieval"))


def test_the_search_setting_is_checked_and_the_default_is_the_annealed_start():
    assert InitSettings().search == "anneal"
    with pytest.raises(SettingError, match="search"):
        InitSettings(search="grid")
    with pytest.raises(SettingError, match="retrieval_keep"):
        InitSettings(retrieval_keep=0)


def test_the_retrieval_start_has_its_own_cache_key():
    from mocap.cameras import rig_from_config
    from mocap.trackers.base import Frame
    from mocap.trackers.init_cache import SilhouetteStart

    body, rig = mocap.load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 4, 4), bool), images=None, detections=None)

    def key(settings):
        return SilhouetteStart(body, rig, settings, np.random.default_rng(0)).cache_key(frame)

    assert key(InitSettings(search="retrieval")) != key(InitSettings())
    lib_a, lib_b = np.zeros((3, body.num_dofs)), np.ones((3, body.num_dofs))

    def key_with(library):
        start = SilhouetteStart(body, rig, InitSettings(search="retrieval"), np.random.default_rng(0),
                                library=library)
        return start.cache_key(frame)

    assert key_with(lib_a) != key_with(lib_b)              # it retrieves from the library it is given
    assert key(InitSettings(search="retrieval", retrieval_keep=3)) != key(InitSettings(search="retrieval"))


def test_a_lean_turns_the_trunk_about_the_hips_and_leaves_the_legs(body):
    shaped = body.shaped()
    lean = retrieval.lean_of(shaped)
    assert lean is not None
    chi = np.zeros(body.num_dofs)
    chi[:6] = root_twist(1.0, 0.3, 0.2)
    chi[body.dof_index("l_hip_flex")] = 0.3
    out = retrieval.leaned(chi, np.array([0.0, 0.4]), lean, np.tile([-9.0, 9.0], (body.num_dofs, 1)))
    np.testing.assert_allclose(out[0], chi, atol=1e-12)           # a lean of 0: the pose itself
    J = shaped.joints(out)
    moved = np.linalg.norm(J[1] - J[0], axis=1)
    name = body.joint_names.index
    for leg in ("l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle"):
        assert moved[name(leg)] < 0.03, (leg, moved[name(leg)])   # the right hip's axis is ~10 deg off
    # the head turns about the hips by the lean: its distance from them times 2 sin(0.4 / 2)
    hips = (J[0, name("l_hip")] + J[0, name("r_hip")]) / 2
    radius = np.linalg.norm(J[0, name("head")] - hips)
    np.testing.assert_allclose(moved[name("head")], 2 * radius * np.sin(0.2), rtol=0.1)


def test_the_annealed_start_keeps_the_cache_key_it_had_before_the_retrieval_settings():
    """The retrieval fields are left out of an annealed start's key: its cached starts stay valid.
    The key below is what the checkout before them (a87b0b3) computes for this frame and library."""
    from mocap.cameras import rig_from_config
    from mocap.trackers.base import Frame
    from mocap.trackers.init_cache import RETRIEVAL_FIELDS, SilhouetteStart, settings_text

    plain = repr(InitSettings())
    assert settings_text(InitSettings()) == plain.split(", search='anneal'")[0] + ")"
    on = InitSettings(search="retrieval")
    assert all(f"{f}=" in settings_text(on) for f in RETRIEVAL_FIELDS)
    body, rig = mocap.load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 4, 4), bool), images=None, detections=None)
    start = SilhouetteStart(body, rig, InitSettings(), np.random.default_rng(0),
                            library=np.zeros((3, body.num_dofs)))
    assert start.cache_key(frame) == "1e2603d2cc617b856880"

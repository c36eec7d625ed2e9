"""The initialiser's faster search (issue 28): its pose searches score E_S on the energy mesh
and still find the known pose; hypotheses far behind after a round are dropped; the shape
search's compiled energy equals the numpy one; the new settings are checked."""

from __future__ import annotations

import numpy as np
import pytest

import mocap
import mocap.trackers.initialization as initialization
from mocap.eval.by_name import NameScorer
from mocap.settings import SettingError
from mocap.trackers.initialization import initialize_from_silhouettes
from mocap.trackers.tracker_settings import ENERGY_MESH_FACES, InitSettings


@pytest.fixture(scope="module")
def walk():
    body = mocap.load_body("paper22")
    return body, mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=1, seed=3)


def test_the_energy_mesh_pose_search_finds_the_known_pose(walk, monkeypatch):
    body, seq = walk
    evaluated = {}                                  # mesh vertices -> particles scored

    class Counted(initialization.SilhouetteEnergy):
        def __call__(self, chi, target):
            n = self.shaped.model.num_vertices if self.mesh is None else self.mesh.num_vertices
            evaluated[n] = evaluated.get(n, 0) + len(np.atleast_2d(chi))
            return super().__call__(chi, target)

    monkeypatch.setattr(initialization, "SilhouetteEnergy", Counted)
    settings = InitSettings(headings=8, hypotheses=1, keep=1, rounds=0, pose_particles=30, pose_layers=6,
                            select_resolution=256)
    assert settings.energy_mesh == ENERGY_MESH_FACES
    chi, alpha, diag = initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0),
                                                   settings)
    error = NameScorer(body, seq.gt).metrics(body.shaped(alpha), chi[None])["mpjpe_mm"]
    assert error < 60, error                        # the mean body, not refined: ~40 mm
    coarse = min(evaluated)
    assert coarse < body.num_vertices / 3 and set(evaluated) == {coarse, body.num_vertices}
    # the searches (2 headings x 6 partitioned searches x 30 x 6) ran on the energy mesh; the
    # heading scan and the hypotheses' ranking (full mesh) are a handful of poses
    assert evaluated[coarse] == 2 * 6 * 30 * 6 and evaluated[body.num_vertices] < 20


def test_a_hypothesis_far_behind_after_a_round_is_dropped(walk):
    body, seq = walk
    cheap = dict(headings=4, hypotheses=1, keep=2, rounds=2, pose_particles=12, pose_layers=3,
                 shape_particles=10, shape_layers=3, resolution=128, select_resolution=160,
                 partitioned=False, local_iterations=3)

    def run(margin):
        return initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0),
                                           InitSettings(prune_margin=margin, **cheap))

    chi_all, alpha_all, all_ = run(None)
    chi_one, alpha_one, one = run(0.0)
    kept_all = [h for h in all_["hypotheses"] if "final_energy" in h]
    kept_one = [h for h in one["hypotheses"] if "final_energy" in h]
    assert len(kept_all) == len(kept_one) == 2
    assert not any("pruned_after_round" in h for h in kept_all)
    assert all(len(h["shape_shift_m"]) == 2 for h in kept_all)          # both ran both rounds
    # margin 0: after round 1 only the best goes on, the other keeps its round-1 energy
    e1 = [h["round_energy"][0] for h in kept_one]
    loser = kept_one[int(np.argmax(e1))]
    winner = kept_one[int(np.argmin(e1))]
    assert loser["pruned_after_round"] == 1 and len(loser["shape_shift_m"]) == 1
    assert loser["final_energy"] == loser["round_energy"][0] and "pruned_after_round" not in winner
    assert len(winner["shape_shift_m"]) == 2 and one["margin"] == loser["lead_when_pruned"] > 0
    # round 1 is the same computation either way
    np.testing.assert_allclose(sorted(e1), sorted(h["round_energy"][0] for h in kept_all))


@pytest.mark.parametrize("field,value", [("energy_mesh", 2), ("prune_margin", -0.1)])
def test_bad_settings_name_the_setting(field, value):
    with pytest.raises(SettingError, match=f"setting {field} = "):
        InitSettings(**{field: value})


def test_the_compiled_shape_energy_equals_the_numpy_one():
    from mocap.trackers.shape_search import shape_energy
    from tests.trackers.test_initialization_shape import C, tall_subject

    body, rig, chi, target = tall_subject()
    rng = np.random.default_rng(2)
    x = np.c_[rng.normal(0, 1, (6, C)), rng.uniform(-0.1, 0.1, (6, 3))]
    slow = shape_energy(body, rig, chi, target, C, translate=True)(x)
    fast = shape_energy(body, rig, chi, target, C, translate=True, compiled=True)(x)
    assert np.ptp(slow) > 0.5                       # shapes far apart score differently
    np.testing.assert_allclose(fast, slow, rtol=1e-5)


def test_progress_is_reported_in_stages_with_increasing_fractions_ending_at_one(walk):
    body, seq = walk
    cheap = dict(headings=4, hypotheses=1, keep=2, rounds=2, pose_particles=8, pose_layers=2,
                 shape_particles=6, shape_layers=2, resolution=96, select_resolution=128,
                 local_iterations=2, partitioned=False)
    for margin in (None, 0.0):                      # 0.0: a hypothesis is dropped after round 1
        calls = []
        initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0),
                                    InitSettings(prune_margin=margin, **cheap),
                                    progress=lambda stage, f, out=calls: out.append((stage, f)))
        stages = [s for s, _ in calls]
        fractions = np.array([f for _, f in calls])
        assert calls[-1] == ("done", 1.0) and stages.count("done") == 1
        assert np.all(np.diff(fractions) >= 0) and np.all((fractions >= 0) & (fractions <= 1))
        assert fractions[:-1].max() < 1.0           # nothing claims to be finished before the end
        order = ["heading", "hypotheses", "refine", "done"]
        assert [order.index(s) for s in stages] == sorted(order.index(s) for s in stages)
        # one report per step: the heading scan, per heading (2) its searches, per kept
        # hypothesis and round its pose and shape searches, a final step per hypothesis still
        # alive, the end
        refine = 2 * 2 + 2 if margin is None else 2 + 1 + 1
        assert len(calls) == 1 + 2 + refine + 1


def test_the_progress_callback_does_not_change_the_result(walk):
    body, seq = walk
    cheap = InitSettings(headings=4, hypotheses=1, keep=1, rounds=1, pose_particles=8, pose_layers=2,
                         shape_particles=6, shape_layers=2, resolution=96, select_resolution=128,
                         local_iterations=2, partitioned=False)
    quiet = initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0), cheap)
    told = initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0), cheap,
                                       progress=lambda stage, f: None)
    np.testing.assert_array_equal(quiet[0], told[0])
    np.testing.assert_array_equal(quiet[1], told[1])


# -- the same start for less overhead (issue 38): the faster path gives the old numbers ------
def test_the_shape_search_poses_each_particle_as_the_body_model_does(walk, monkeypatch):
    import mocap.trackers.shape_search as shape_search
    from mocap.trackers.shape_search import posed_vertices

    body, _ = walk
    rng = np.random.default_rng(5)
    chis = np.zeros((9, body.num_dofs))
    chis[:, :6] = rng.normal(0, 0.3, (9, 6))
    chis[:, 6:] = rng.uniform(-0.4, 0.4, (9, body.num_dofs - 6))
    shapes = rng.normal(0, 1.0, (9, body.num_shape))
    got = posed_vertices(body, chis, shapes)
    np.testing.assert_array_equal(got, body.pose(chis, shapes).vertices)
    # one particle alone: its own shaped body posed, to float32 rounding
    one = body.shaped(shapes[3]).pose(chis[3]).vertices[0]
    np.testing.assert_allclose(got[3], one, atol=2e-5)
    # without numba: the body model's own skinning, the same numbers
    monkeypatch.setattr(shape_search, "HAVE_NUMBA", False)
    np.testing.assert_array_equal(shape_search.posed_vertices(body, chis, shapes), got)


def test_the_start_is_bit_identical_to_the_one_posed_by_the_body_model(walk, monkeypatch):
    import mocap.trackers.shape_search as shape_search

    body, seq = walk
    settings = InitSettings(headings=4, hypotheses=1, keep=2, rounds=2, pose_particles=12, pose_layers=3,
                            shape_particles=10, shape_layers=3, resolution=128, select_resolution=160,
                            partitioned=True, local_iterations=3)

    def start():
        return initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0), settings)

    chi, alpha, diag = start()
    monkeypatch.setattr(shape_search, "posed_vertices", lambda b, c, a: b.pose(c, a).vertices)
    chi_old, alpha_old, diag_old = start()
    np.testing.assert_array_equal(chi, chi_old)
    np.testing.assert_array_equal(alpha, alpha_old)
    assert [h["final_energy"] for h in diag["hypotheses"] if "final_energy" in h] == \
        [h["final_energy"] for h in diag_old["hypotheses"] if "final_energy" in h]
    assert np.any(alpha != 0)                     # the shape search ran


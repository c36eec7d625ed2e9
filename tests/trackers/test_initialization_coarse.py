"""Version 6 of the initialiser (issue 38): the pose searches' first ``coarse_layers`` layers on a
cheaper E_S (coarser masks, a coarser mesh). The staged energy answers the calls it should; the
cheaper energy ranks a rendered pose first among perturbed ones and agrees in rank with the
search's own; the searches run on it for exactly the layers the setting names and still find the
known pose; the settings are checked and in the cache key only when on."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import spearmanr

import mocap
import mocap.trackers.initialization as initialization
from mocap.body.energy_mesh import energy_mesh_for
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.eval.by_name import NameScorer
from mocap.settings import SettingError
from mocap.trackers.initialization import initialize_from_silhouettes, staged_energy
from mocap.trackers.tracker_settings import InitSettings


@pytest.fixture(scope="module")
def walk():
    body = mocap.load_body("paper22")
    return body, mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=1, seed=3)


def test_the_staged_energy_answers_the_first_layers_by_the_coarse_one_in_every_search():
    calls = []
    energy = staged_energy(lambda x: calls.append("coarse") or np.zeros(len(x)),
                           lambda x: calls.append("fine") or np.ones(len(x)), layers=4, coarse_layers=3)
    out = [energy(np.zeros((2, 3))) for _ in range(8)]          # two searches of 4 layers
    assert calls == ["coarse"] * 3 + ["fine"] + ["coarse"] * 3 + ["fine"]
    assert [float(o[0]) for o in out] == [0, 0, 0, 1, 0, 0, 0, 1]


def test_the_coarse_energy_ranks_the_rendered_pose_first_and_agrees_with_the_searchs(walk):
    body, seq = walk
    masks, rig, chi = seq.masks[0], seq.rig, seq.gt.chi[0]
    shaped = body.shaped(seq.gt.alpha) if getattr(seq.gt, "alpha", None) is not None else body.shaped()
    size = float(np.max(rig.sizes))

    def energy(px, faces):
        e = SilhouetteEnergy(shaped, rig, px / size, mesh=energy_mesh_for(body, faces))
        target = silhouette_target(masks, px / size)
        return lambda x: e(x, target)

    rng = np.random.default_rng(0)
    scales = np.repeat([0.02, 0.05, 0.1, 0.2, 0.4], 8)[:, None]
    poses = np.vstack([chi[None], chi + scales * rng.normal(size=(len(scales), body.num_dofs))])
    poses = np.clip(poses, body.limits[:, 0], body.limits[:, 1])
    coarse = energy(128, InitSettings().coarse_mesh)(poses)
    own = energy(256, InitSettings().energy_mesh)(poses)
    assert np.argmin(coarse) == 0 and np.argmin(own) == 0           # the rendered pose first
    assert spearmanr(coarse, own)[0] > 0.9                          # ranked alike


def test_the_searches_run_their_first_layers_on_the_coarse_energy_and_find_the_known_pose(walk, monkeypatch):
    body, seq = walk
    evaluated = {}                                   # (mesh vertices, internal width) -> particles

    class Counted(initialization.SilhouetteEnergy):
        def __call__(self, chi, target):
            n = self.shaped.model.num_vertices if self.mesh is None else self.mesh.num_vertices
            key = (n, self.size[1])
            evaluated[key] = evaluated.get(key, 0) + len(np.atleast_2d(chi))
            return super().__call__(chi, target)

    monkeypatch.setattr(initialization, "SilhouetteEnergy", Counted)
    settings = InitSettings(headings=8, hypotheses=1, keep=1, rounds=0, pose_particles=30, pose_layers=6,
                            select_resolution=256, coarse_layers=4, coarse_resolution=96)
    chi, alpha, diag = initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0),
                                                   settings)
    error = NameScorer(body, seq.gt).metrics(body.shaped(alpha), chi[None])["mpjpe_mm"]
    assert error < 60, error                         # as version 3's test: the mean body, ~40 mm
    cheap = energy_mesh_for(body, settings.coarse_mesh).num_vertices
    mesh = energy_mesh_for(body, settings.energy_mesh).num_vertices
    # 2 headings x 6 partitioned searches x 30 particles: 4 layers coarse, 2 on the search's own
    assert evaluated[(cheap, 96)] == 2 * 6 * 30 * 4
    assert evaluated[(mesh, 256)] == 2 * 6 * 30 * 2


def test_the_coarse_settings_are_checked():
    assert InitSettings().coarse_layers == 0 or InitSettings().coarse_layers < InitSettings().pose_layers
    for bad in ({"coarse_layers": -1}, {"coarse_layers": 10, "pose_layers": 10},
                {"coarse_resolution": 8}, {"coarse_mesh": 2}):
        with pytest.raises(SettingError, match=next(iter(bad))):          # the field named first
            InitSettings(**bad)


def test_the_coarse_settings_are_in_the_cache_key_only_when_on():
    from mocap.cameras import rig_from_config
    from mocap.trackers.base import Frame
    from mocap.trackers.init_cache import COARSE_FIELDS, SilhouetteStart, settings_text

    assert not any(f"{f}=" in settings_text(InitSettings(coarse_layers=0)) for f in COARSE_FIELDS)
    assert all(f"{f}=" in settings_text(InitSettings(coarse_layers=7)) for f in COARSE_FIELDS)
    body, rig = mocap.load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 4, 4), bool), images=None, detections=None)

    def key(settings):
        return SilhouetteStart(body, rig, settings, np.random.default_rng(0)).cache_key(frame)

    off = key(InitSettings(coarse_layers=0))
    assert key(InitSettings(coarse_layers=0, coarse_resolution=96)) == off     # off: not in the key
    assert key(InitSettings(coarse_layers=7)) != off
    assert key(InitSettings(coarse_layers=7, coarse_resolution=96)) != key(InitSettings(coarse_layers=7))


def test_the_shape_energy_on_a_coarse_mesh_equals_the_silhouette_energy_of_that_shape(walk):
    """Two paths: the shape search's energy (full-mesh posing of each shape, then the mesh) and
    :class:`SilhouetteEnergy` of the shaped body on the same mesh (its skinning basis)."""
    from mocap.trackers.shape_search import shape_energy

    body, seq = walk
    rig, chi, masks = seq.rig, seq.gt.chi[0], seq.masks[0]
    mesh = energy_mesh_for(body, 500)
    scale = 96 / float(np.max(rig.sizes))
    target = silhouette_target(masks, scale)
    alphas = np.random.default_rng(1).normal(0, 0.8, (3, body.num_shape))
    alphas[:, 4:] = 0.0
    e = shape_energy(body, rig.scaled(scale), chi, target, 4, compiled=True, mesh=mesh)(alphas[:, :4])
    want = [SilhouetteEnergy(body.shaped(a), rig, scale, mesh=mesh)(chi[None], target)[0] for a in alphas]
    np.testing.assert_allclose(e, want, rtol=1e-4)
    assert len(set(np.round(e, 6))) == 3                      # three shapes, three energies

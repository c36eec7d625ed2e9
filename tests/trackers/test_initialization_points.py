"""Version 7's try (issue 38): the pose and shape searches' first layers on the point chamfer
(mocap/energy/point_chamfer.py) instead of a coarser raster. The searches run exactly the layers
the settings name on it and still start a rendered walk near the truth; the setting is checked
and in the cache key when the coarse layers are on."""

from __future__ import annotations

import numpy as np
import pytest

import mocap
import mocap.trackers.initialization as initialization
from mocap.body.energy_mesh import energy_mesh_for
from mocap.eval.by_name import NameScorer
from mocap.settings import SettingError
from mocap.trackers.initialization import initialize_from_silhouettes
from mocap.trackers.tracker_settings import InitSettings

pytest.importorskip("numba")


def test_the_searches_run_their_first_layers_on_the_point_chamfer_and_find_the_known_pose(monkeypatch):
    body = mocap.load_body("paper22")
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=1, seed=3)
    evaluated = {"points": 0, "raster": 0}

    class CountedPoints(initialization.PointChamferEnergy):
        def __call__(self, chi, target):
            evaluated["points"] += len(np.atleast_2d(chi))
            return super().__call__(chi, target)

    class CountedRaster(initialization.SilhouetteEnergy):
        def __call__(self, chi, target):
            if self.mesh is not None and self.mesh.num_vertices == mesh_vertices:
                evaluated["raster"] += len(np.atleast_2d(chi))
            return super().__call__(chi, target)

    monkeypatch.setattr(initialization, "PointChamferEnergy", CountedPoints)
    monkeypatch.setattr(initialization, "SilhouetteEnergy", CountedRaster)
    settings = InitSettings(headings=8, hypotheses=1, keep=1, rounds=0, pose_particles=30, pose_layers=6,
                            select_resolution=256, coarse_layers=4, coarse_energy="points")
    mesh_vertices = energy_mesh_for(body, settings.energy_mesh).num_vertices
    chi, alpha, _ = initialize_from_silhouettes(body, seq.rig, seq.masks[0], np.random.default_rng(0),
                                                settings)
    error = NameScorer(body, seq.gt).metrics(body.shaped(alpha), chi[None])["mpjpe_mm"]
    assert error < 60, error                        # as version 3's and 6's tests: the mean body
    # 2 headings x 6 partitioned searches x 30 particles: 4 layers on the points, 2 on the search's own
    assert evaluated == {"points": 2 * 6 * 30 * 4, "raster": 2 * 6 * 30 * 2}


def test_the_point_settings_are_checked_and_in_the_cache_key_when_the_coarse_layers_are_on():
    from mocap.cameras import rig_from_config
    from mocap.trackers.base import Frame
    from mocap.trackers.init_cache import SilhouetteStart

    for bad in ({"coarse_energy": "dots"}, {"coarse_samples": 0}):
        with pytest.raises(SettingError, match=next(iter(bad))):
            InitSettings(**bad)
    body, rig = mocap.load_body("paper22"), rig_from_config("ring4_small")
    frame = Frame(index=0, masks=np.ones((len(rig.names), 4, 4), bool), images=None, detections=None)

    def key(**kw):
        return SilhouetteStart(body, rig, InitSettings(**kw), np.random.default_rng(0)).cache_key(frame)

    assert key(coarse_energy="points") == key()                      # off: version 3's key
    on = key(coarse_layers=7, coarse_energy="points")
    assert on != key(coarse_layers=7)
    assert on != key(coarse_layers=7, coarse_energy="points", coarse_samples=32)

"""The initialiser's shape search moves the body with its shape: a pose found with the mean
body has placed its root to make up for the wrong height, and a search over the shape alone,
holding that root, cannot grow the body without pushing its head out of the silhouette."""

from __future__ import annotations

import numpy as np

import mocap
from mocap.cameras import project, ring_rig
from mocap.energy.silhouette import silhouette_target
from mocap.render import get_rasterizer
from mocap.trackers.apf import run_apf
from mocap.trackers.shape_search import shape_energy, shifted
from mocap.trackers.tracker_settings import APFSettings

C = 8
PX = 128                                                      # image side: 2.3 cm a pixel at the body


def tall_subject():
    body = mocap.load_body("paper22")
    rig = ring_rig(4, 3.5, 1.5, PX, PX, fov_deg=45, look_at=(0, 0, 0.9))
    alpha = np.zeros(body.num_shape)
    alpha[0] = 2.5                                            # 1.935 m; the mean body is 1.693 m
    chi = np.zeros(body.num_dofs)
    px, depth = project(rig, body.pose(chi[None], alpha[None]).vertices[0], return_depth=True)
    masks = get_rasterizer(body.faces, body.num_vertices)(px, PX, PX, depth, near=0.05)
    return body, rig, chi, silhouette_target(masks, 1.0, view_names=tuple(rig.names))


def height(body, coefficients):
    alpha = np.zeros(body.num_shape)
    alpha[:C] = coefficients[:C]
    v = body.shaped(alpha).rest_vertices
    return float(v[:, 2].max() - v[:, 2].min())


def test_shifted_moves_the_posed_body_and_the_energy_reads_the_shift():
    body, rig, chi, target = tall_subject()
    shift = np.array([0.03, -0.02, 0.12])
    shaped = body.shaped()
    moved = shifted(chi, shift)
    np.testing.assert_allclose(shaped.joints(moved[None].astype(np.float32))[0],
                               shaped.joints(chi[None].astype(np.float32))[0] + shift, atol=1e-6)
    a = np.r_[0.7, np.zeros(C - 1)]
    e_shift = shape_energy(body, rig, chi, target, C, translate=True)(np.r_[a, shift][None])
    e_moved = shape_energy(body, rig, moved, target, C)(a[None])
    np.testing.assert_allclose(e_shift, e_moved, rtol=1e-5)


def test_the_shape_search_recovers_the_height_only_when_it_moves_the_body():
    body, rig, chi, target = tall_subject()
    start = shifted(chi, np.array([0.0, 0.0, 0.12]))          # the mean body lifted to fill the silhouette
    apf = APFSettings(particles=80, layers=10, diffusion=0.7, shrink=0.9)
    fixed, moving = [], []
    for seed in range(3):
        e = shape_energy(body, rig, start, target, C)
        c, _ = run_apf(e, np.zeros(C), np.full(C, 0.8), np.tile([-3.0, 3.0], (C, 1)), apf,
                       np.random.default_rng(seed))
        fixed.append(height(body, c))
        e = shape_energy(body, rig, start, target, C, translate=True)
        c, _ = run_apf(e, np.zeros(C + 3), np.r_[np.full(C, 0.8), np.full(3, 0.2 / 3)],
                       np.vstack([np.tile([-3.0, 3.0], (C, 1)), np.tile([-0.2, 0.2], (3, 1))]), apf,
                       np.random.default_rng(seed))
        moving.append(height(body, c))
    assert max(fixed) < 1.83, fixed                           # held at the root: 13 cm short or more
    assert min(moving) > 1.85 and np.mean(moving) > np.mean(fixed) + 0.07, moving

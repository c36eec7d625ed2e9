"""The fused compiled silhouette energy (mocap/energy/fused.py) against the numpy path and a
brute-force Eq. 11 (reference rasterizer + exact Euclidean transforms, whole image)."""

import warnings

import cv2
import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from mocap.cameras import project, ring_rig
from mocap.energy import fallback, fused
from mocap.energy.silhouette import SilhouetteEnergy, chamfer_energy, silhouette_target
from mocap.render.reference import rasterize_reference

pytestmark = pytest.mark.skipif(not fused.HAVE_NUMBA, reason="numba is not installed")


def scene(body, size=(160, 120), views=4, particles=6, seed=0):
    rig = ring_rig(views, 3.5, 1.5, size[0], size[1], fov_deg=50, look_at=(0, 0, 0.9))
    sb = body.shaped()
    rng = np.random.default_rng(seed)
    truth = body.zero_pose(1)
    numpy_energy = SilhouetteEnergy(sb, rig, scale=1.0, backend="numpy")
    observed = numpy_energy.model_masks(sb.pose(truth).vertices)[0]
    target = silhouette_target(observed, 1.0, margin=8)
    chi = np.repeat(truth, particles, axis=0)
    chi[:, :3] += rng.normal(0, 0.05, (particles, 3))
    chi[:, 6:] += rng.normal(0, 0.3, (particles, body.num_dofs - 6))
    chi[-1, 0] += 50.0                              # far outside every view: empty silhouettes
    return rig, sb, target, chi, numpy_energy


@pytest.mark.parametrize("dtype", ["body", "body64"])
def test_fused_equals_the_numpy_path(dtype, request):
    body = request.getfixturevalue(dtype)
    rig, sb, target, chi, numpy_energy = scene(body)
    compiled = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba")
    a, b = compiled.per_view(chi, target), numpy_energy.per_view(chi, target)
    assert compiled.backend == "numba" and numpy_energy.backend == "numpy"
    assert np.all(np.isfinite(a))
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-5)
    assert np.all(a[-1] == 2 * np.hypot(*target.size))       # empty: penalty for both terms


@pytest.mark.parametrize("dtype", ["body", "body64"])
def test_fused_equals_brute_force_eq11(dtype, request):
    """Eq. 11 literally, exact transforms over the whole image: the fused energy differs only by
    the 5x5 chamfer approximation of D^p (Borgefors, within ~2 %) and the box margin; float32
    and float64 bodies."""
    body = request.getfixturevalue(dtype)
    rig, sb, target, chi, _ = scene(body, particles=5)
    compiled = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba")
    got = compiled.per_view(chi[:-1], target)
    px, depth = project(rig, sb.pose(chi[:-1]).vertices, return_depth=True)
    h, w = target.size
    for p in range(len(chi) - 1):
        for c in range(len(rig)):
            keep = (depth[p, c][body.faces] > 0.05).all(axis=1)
            model = rasterize_reference(px[p, c], body.faces, h, w, keep)
            obs = target.masks[c]
            Dp, D = distance_transform_edt(~model), distance_transform_edt(~obs)
            ref = (np.abs(Dp - D)[model].sum() / model.sum() + np.abs(Dp - D)[obs].sum() / obs.sum())
            assert got[p, c] == pytest.approx(ref, rel=0.03, abs=0.05), (p, c)


def test_fused_distance_transform_is_opencvs_5x5_chamfer():
    """Term 2 alone: one observed pixel per row of a box, seeds anywhere -> the same sum as
    cv2.distanceTransform(DIST_L2, DIST_MASK_5) read at those pixels."""
    rng = np.random.default_rng(1)
    for _ in range(5):
        bh, bw = rng.integers(5, 40, 2)
        seeds = rng.random((bh, bw)) < 0.02
        seeds[rng.integers(bh), rng.integers(bw)] = True
        tmp = np.full((bh + 4, bw + 4), fused._INIT, np.int32)
        tmp[2:-2, 2:-2][seeds] = 0
        obs_r, obs_c = np.nonzero(rng.random((bh, bw)) < 0.3)
        got = fused._chamfer_term2(tmp, bh, bw, obs_r.astype(np.int64), obs_c.astype(np.int64))
        dt = cv2.distanceTransform((~seeds).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
        # equal up to the rounding of the weights (fixed point here, float in IPP builds)
        assert got == pytest.approx(float(dt[obs_r, obs_c].astype(np.float64).sum()), rel=1e-5)


def test_without_numba_the_energy_falls_back_to_numpy_and_says_so_once(body, monkeypatch):
    rig, sb, target, chi, numpy_energy = scene(body, particles=2)
    monkeypatch.setattr(fused, "HAVE_NUMBA", False)
    monkeypatch.setattr(fallback, "WARNED", set())
    with pytest.warns(RuntimeWarning, match="numba is not installed"):
        first = SilhouetteEnergy(sb, rig, scale=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        second = SilhouetteEnergy(sb, rig, scale=1.0)
    assert first.backend == second.backend == "numpy"
    np.testing.assert_array_equal(first.per_view(chi, target), numpy_energy.per_view(chi, target))
    with pytest.raises(RuntimeError, match="numba"):
        SilhouetteEnergy(sb, rig, scale=1.0, backend="numba")


def test_chamfer_energy_reference_is_unchanged_by_the_backend_switch(body):
    """The numpy path still computes chamfer_energy on the scanline masks."""
    rig, sb, target, chi, numpy_energy = scene(body, particles=2)
    masks = numpy_energy.model_masks(sb.pose(chi).vertices)
    np.testing.assert_array_equal(chamfer_energy(masks, target), numpy_energy.per_view(chi, target))

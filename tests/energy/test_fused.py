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


def _term2(seeds, obs_r, obs_c, i0=0, j0=0):
    """The kernel's term 2 on a (bh, bw) seed mask given as its runs per row -> (the sum at
    the observed pixels, the padded transform image)."""
    bh, bw = seeds.shape
    spans = []
    for i in range(bh):
        edges = np.flatnonzero(np.diff(np.r_[0, seeds[i].astype(np.int8), 0]))
        spans += [(i + 2, a + 2, b + 2) for a, b in zip(edges[::2], edges[1::2], strict=True)]
    spans = np.array(spans, np.int64).reshape(-1, 3)
    tmp = np.full((bh + 7, bw + 9), -1, np.int32)          # larger than needed, any contents
    fused._far_ring(tmp, bh, bw)
    total = fused._chamfer_term2(tmp, bh, bw, spans, len(spans), np.asarray(obs_r, np.int64),
                                 np.asarray(obs_c, np.int64), i0, j0)
    return total, tmp[:bh + 4, :bw + 4]


def test_fused_distance_transform_is_opencvs_5x5_chamfer():
    """Term 2 alone: one observed pixel per row of a box, seeds anywhere -> the same sum as
    cv2.distanceTransform(DIST_L2, DIST_MASK_5) read at those pixels."""
    rng = np.random.default_rng(1)
    for _ in range(5):
        bh, bw = rng.integers(5, 40, 2)
        seeds = rng.random((bh, bw)) < 0.02
        seeds[rng.integers(bh), rng.integers(bw)] = True
        obs_r, obs_c = np.nonzero(rng.random((bh, bw)) < 0.3)
        got, _ = _term2(seeds, obs_r, obs_c)
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


def _chamfer_one_loop(tmp, bh, bw):
    """OpenCV's distanceTransform_5x5 as written there (one loop per pass, in place): the
    reference for the split, vectorised passes of the kernel."""
    HV, DIAG, LONG = fused._HV, fused._DIAG, fused._LONG
    t = tmp.astype(np.int64)
    for i in range(2, bh + 2):
        for j in range(2, bw + 2):
            if t[i, j] != 0:
                t[i, j] = min(t[i - 2, j - 1] + LONG, t[i - 2, j + 1] + LONG, t[i - 1, j - 2] + LONG,
                              t[i - 1, j - 1] + DIAG, t[i - 1, j] + HV, t[i - 1, j + 1] + DIAG,
                              t[i - 1, j + 2] + LONG, t[i, j - 1] + HV)
    for i in range(bh + 1, 1, -1):
        for j in range(bw + 1, 1, -1):
            if t[i, j] > HV:
                t[i, j] = min(t[i, j], t[i + 2, j + 1] + LONG, t[i + 2, j - 1] + LONG,
                              t[i + 1, j + 2] + LONG, t[i + 1, j + 1] + DIAG, t[i + 1, j] + HV,
                              t[i + 1, j - 1] + DIAG, t[i + 1, j - 2] + LONG, t[i, j + 1] + HV)
    return t


def test_split_distance_transform_passes_equal_the_one_loop_algorithm_integer_for_integer():
    rng = np.random.default_rng(7)
    for density in (0.002, 0.02, 0.3):
        bh, bw = rng.integers(3, 45, 2)
        seeds = rng.random((bh, bw)) < density
        seeds[rng.integers(bh), rng.integers(bw)] = True
        want = _chamfer_one_loop(_seeded(seeds), bh, bw)
        obs_r, obs_c = np.nonzero(np.ones((bh, bw), bool))
        total, got = _term2(seeds, obs_r, obs_c)
        np.testing.assert_array_equal(got[2:-2, 2:-2], want[2:-2, 2:-2])
        assert total == pytest.approx(want[2:-2, 2:-2].sum() / 65536.0, rel=1e-6)


def _seeded(seeds):
    """The padded image of OpenCV's algorithm: 0 at the seeds, far elsewhere."""
    tmp = np.full((seeds.shape[0] + 4, seeds.shape[1] + 4), fused._INIT, np.int32)
    tmp[2:-2, 2:-2][seeds] = 0
    return tmp


def _blobs(rng, bh, bw):
    """Seeds like a projected body: a few filled ellipses, some reaching the edges."""
    yy, xx = np.mgrid[:bh, :bw]
    seeds = np.zeros((bh, bw), bool)
    for _ in range(rng.integers(1, 4)):
        cy, cx = rng.uniform(0, bh), rng.uniform(0, bw)
        ry, rx = rng.uniform(1, bh / 2), rng.uniform(1, bw / 3)
        seeds |= ((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 < 1
    seeds[rng.integers(bh), rng.integers(bw)] = True
    return seeds


def test_distance_transform_of_the_transposed_seeds_is_the_transposed_transform():
    """The kernel transforms term 2's window transposed (its seeds are runs down the model's
    columns): the 5x5 mask is symmetric under transposition (LONG for (1, 2) and (2, 1)), and
    the two passes give every pixel its shortest chamfer path, whatever the raster order, so
    the integers equal the one-loop algorithm's on the untransposed image."""
    rng = np.random.default_rng(11)
    for density in (0.002, 0.02, 0.3, None):
        bh, bw = rng.integers(3, 60, 2)
        if density is None:
            seeds = _blobs(rng, bh, bw)
        else:
            seeds = rng.random((bh, bw)) < density
            seeds[rng.integers(bh), rng.integers(bw)] = True
        want = _chamfer_one_loop(_seeded(seeds), bh, bw)[2:-2, 2:-2]
        obs_c, obs_r = np.nonzero(np.ones((bw, bh), bool))
        total, got = _term2(seeds.T, obs_c, obs_r)
        np.testing.assert_array_equal(got[2:-2, 2:-2].T, want)
        assert total == want.astype(np.float32).astype(np.float64).sum() / 65536.0


def test_distance_transform_on_the_window_of_seeds_and_observed_pixels_is_the_whole_boxs():
    """Term 2's window is the bounding box of the seeds and the observed pixels (a shortest
    chamfer path is monotone, so it stays in the box of its ends): read at the observed
    pixels, its transform equals the whole box's, integer for integer."""
    rng = np.random.default_rng(5)
    for _ in range(6):
        bh, bw = rng.integers(20, 60, 2)
        seeds = np.zeros((bh, bw), bool)
        seeds[rng.integers(bh // 4, bh // 2):rng.integers(bh // 2 + 1, bh),
              rng.integers(0, bw // 2):rng.integers(bw // 2 + 1, bw)] = True
        obs = np.zeros((bh, bw), bool)
        obs[rng.integers(0, bh // 2):rng.integers(bh // 2 + 1, bh - bh // 4),
            rng.integers(bw // 4, bw // 2):rng.integers(bw // 2 + 1, bw)] = True
        whole = _chamfer_one_loop(_seeded(seeds), bh, bw)[2:-2, 2:-2]
        both = seeds | obs
        rows, cols = np.flatnonzero(both.any(1)), np.flatnonzero(both.any(0))
        i0, i1, j0, j1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        assert (i1 - i0) * (j1 - j0) < bh * bw
        obs_r, obs_c = np.nonzero(obs)
        total, got = _term2(seeds[i0:i1, j0:j1], obs_r, obs_c, i0, j0)
        np.testing.assert_array_equal(got[obs_r - i0 + 2, obs_c - j0 + 2], whole[obs_r, obs_c])
        assert total == whole[obs_r, obs_c].astype(np.float32).astype(np.float64).sum() / 65536.0


def test_fused_equals_the_numpy_path_on_a_mesh_with_non_manifold_edges(body):
    """A duplicated face makes edges with two faces on one side (K = 2 in the edge table):
    the general-K branch of the contour flags must give the numpy path's energies."""
    from types import SimpleNamespace

    rig, sb, target, chi, _ = scene(body)
    faces = np.concatenate([body.faces, body.faces[:40]])
    sb2 = SimpleNamespace(model=SimpleNamespace(faces=faces, num_vertices=body.num_vertices),
                          pose=sb.pose, vertices=sb.vertices)
    a = SilhouetteEnergy(sb2, rig, scale=1.0, backend="numba")
    b = SilhouetteEnergy(sb2, rig, scale=1.0, backend="numpy")
    assert a.fused.edge_arrays[2].shape[1] == 2
    np.testing.assert_allclose(a.per_view(chi, target), b.per_view(chi, target), rtol=1e-5, atol=1e-5)


def _distorted_skewed(rig):
    """The rig with OpenCV distortion on every view and skew on one."""
    from mocap.cameras import Rig

    cams = []
    for i, cam in enumerate(rig):
        K = cam.K.copy()
        if i == 1:
            K[0, 1] = 0.8
        cams.append(cam.replace(K=K, dist=(-0.12, 0.03, 0.001, -0.002, 0.004)))
    return Rig(tuple(cams))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("distorted", [False, True])
def test_kernel_projection_gives_projects_pixels_bit_for_bit(dtype, distorted):
    """The kernel finishes the projection from camera_coordinates with project's own float
    operations: the same pixels, bit for bit, and the near-plane test on the same depths."""
    from mocap.cameras import camera_coordinates

    rig = ring_rig(3, 3.0, 1.5, 160, 120, fov_deg=60, look_at=(0, 0, 0.9))
    if distorted:
        rig = _distorted_skewed(rig)
    rng = np.random.default_rng(3)
    pts = rng.normal((0, 0, 0.9), 3.0, (2, 500, 3)).astype(dtype)   # some behind the near plane
    px, depth = project(rig, pts, return_depth=True)
    X = camera_coordinates(rig, pts)
    K = rig.K
    for p in range(2):
        for c in range(len(rig)):
            cam = np.array([K[c, 0, 0], K[c, 0, 1], K[c, 0, 2], K[c, 1, 1], K[c, 1, 2], 1, 2, 0.05],
                           dtype)
            xs, ys = np.empty(500, dtype), np.empty(500, dtype)
            vs = np.empty(500, bool)
            bad = fused.project_view(X[p, c], cam, rig.dist[c].astype(dtype), bool(np.any(rig.dist)),
                                     bool(np.any(K[:, 0, 1])), xs, ys, vs)
            front = depth[p, c] > 0.05
            assert bad == 0 and 0 < front.sum() < 500
            np.testing.assert_array_equal(vs, front)
            np.testing.assert_array_equal(xs[front], px[p, c, front, 0])
            np.testing.assert_array_equal(ys[front], px[p, c, front, 1])


@pytest.mark.parametrize("dtype", ["body", "body64"])
def test_fused_equals_the_numpy_path_through_a_distorted_skewed_rig(dtype, request):
    body = request.getfixturevalue(dtype)
    rig, sb, _, chi, _ = scene(body)
    rig = _distorted_skewed(rig)
    numpy_energy = SilhouetteEnergy(sb, rig, scale=1.0, backend="numpy")
    target = silhouette_target(numpy_energy.model_masks(sb.pose(body.zero_pose(1)).vertices)[0], 1.0,
                               margin=8)
    compiled = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba")
    np.testing.assert_allclose(compiled.per_view(chi, target), numpy_energy.per_view(chi, target),
                               rtol=1e-5, atol=1e-5)


def test_fused_refuses_camera_coordinates_of_the_wrong_shape(body):
    rig, sb, target, chi, _ = scene(body, particles=2)
    compiled = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba")
    from mocap.cameras import camera_coordinates

    X = camera_coordinates(rig, sb.pose(chi).vertices)
    with pytest.raises(ValueError, match="camera coordinates"):
        compiled.fused(X[:, :2], rig, target)
    with pytest.raises(ValueError, match="vertices"):
        compiled.fused(X[..., :-1], rig, target)


def test_fused_equals_the_numpy_path_where_the_model_overhangs_the_box_on_every_side(body):
    """An observed silhouette smaller than the model (a patch inside the body, another just
    outside it): the model's rows and columns run past the grown box on all four sides, so the row scan
    sums columns left of, in and right of the box and seeds term 2's window only inside it."""
    rig, sb, _, chi, numpy_energy = scene(body)
    masks = numpy_energy.model_masks(sb.pose(body.zero_pose(1)).vertices)[0]
    observed = np.zeros_like(masks)
    for c, m in enumerate(masks):
        rows, cols = np.nonzero(m)
        r, q = int(np.median(rows)), int(np.median(cols))
        observed[c, r - 3:r + 4, q - 2:q + 3] = True               # inside the body
        gap = q + int(np.argmin(m[r, q:]))                          # first background pixel
        observed[c, r:r + 2, gap:gap + 2] = True                    # right of the torso
    target = silhouette_target(observed, 1.0, margin=2)
    model = numpy_energy.model_masks(sb.pose(chi[:-1]).vertices)
    x0, y0, x1, y1 = target.boxes.T
    h, w = target.size
    cols, rows = model.any(axis=2), model.any(axis=3)
    overhang = ((cols.argmax(-1) < x0) & (w - cols[..., ::-1].argmax(-1) > x1)
                & (rows.argmax(-1) < y0) & (h - rows[..., ::-1].argmax(-1) > y1))
    assert overhang.mean() > 0.5, overhang.mean()          # most particle-views, every side
    compiled = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba")
    a, b = compiled.per_view(chi, target), numpy_energy.per_view(chi, target)
    assert np.all(np.isfinite(a))
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("dtype", ["body", "body64"])
def test_fused_energy_is_the_pixel_by_pixel_sum_bit_for_bit(dtype, request):
    """Term 1 from column prefix sums over the covered runs and term 2 on the transposed
    window are exact restructurings: the energies equal, bit for bit, Eq. 11 summed pixel by
    pixel from the scanline masks (term 1: dt under the model, in float64, exact in any order;
    term 2: the one-loop 5x5 chamfer of the model's pixels in the box, read at the observed
    pixels)."""
    body = request.getfixturevalue(dtype)
    rig, sb, target, chi, numpy_energy = scene(body, size=(96, 72), views=3, particles=4)
    got = SilhouetteEnergy(sb, rig, scale=1.0, backend="numba").per_view(chi, target)
    masks = numpy_energy.model_masks(sb.pose(chi).vertices)
    penalty = float(np.hypot(*target.size))
    seeded = 0
    for p in range(len(chi)):
        for c in range(len(rig)):
            model = masks[p, c]
            e1 = target.dt[c][model].astype(np.float64).sum() / model.sum() if model.any() else penalty
            x0, y0, x1, y1 = target.boxes[c]
            seeds = model[y0:y1, x0:x1]
            if seeds.any():
                seeded += 1
                d = _chamfer_one_loop(_seeded(seeds), y1 - y0, x1 - x0)[2:-2, 2:-2]
                vals = d[target.masks[c, y0:y1, x0:x1]].astype(np.float32) * np.float32(2.0**-16)
                e2 = vals.astype(np.float64).sum() / target.area[c]
            else:
                e2 = penalty
            assert got[p, c] == e1 + e2, (p, c)
    assert seeded >= 6


def test_column_prefix_sums_are_numpys_cumsum_in_float64_with_a_zero_first_row():
    rng = np.random.default_rng(2)
    dt = np.sqrt(rng.integers(0, 90**2, (3, 17, 11))).astype(np.float32)
    got = np.full((3, 18, 11), np.nan)
    fused._column_prefix_sums(dt, got)
    want = np.concatenate([np.zeros((3, 1, 11)), np.cumsum(dt.astype(np.float64), axis=1)], axis=1)
    np.testing.assert_array_equal(got, want)

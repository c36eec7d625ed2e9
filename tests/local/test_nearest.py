"""The bucket-grid nearest-neighbour index of the contour matcher against scipy's k-d tree."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from mocap.energy import fallback
from mocap.local import nearest
from mocap.local.nearest import NearestPoints


def _outline(rng, n):
    """Integer pixels along a few ellipses (like silhouette outlines), with repeats."""
    t = rng.uniform(0, 2 * np.pi, n)
    k = rng.integers(0, 3, n)
    cx, cy = np.array([300, 420, 350]), np.array([200, 500, 800])
    a, b = np.array([80, 40, 150]), np.array([60, 200, 90])
    return np.round(np.stack([cx[k] + a[k] * np.cos(t), cy[k] + b[k] * np.sin(t)], 1))


@pytest.mark.parametrize("case", ["outline", "uniform", "one point", "duplicates", "line"])
def test_equals_the_kd_tree(case):
    rng = np.random.default_rng(3)
    pts = {"outline": np.unique(_outline(rng, 2500), axis=0),
           "uniform": rng.uniform(-50, 900, (700, 2)),
           "one point": np.array([[10.0, 20.0]]),
           "duplicates": np.repeat(rng.uniform(0, 100, (20, 2)).round(), 5, axis=0) + 0.0,
           "line": np.stack([np.arange(300.0), np.full(300, 7.0)], 1)}[case]
    # queries inside, near and far outside the points' box, on the points themselves
    near = pts[:50] + rng.normal(0, 0.3, (min(50, len(pts)), 2))
    q = np.concatenate([rng.uniform(-300, 1300, (3000, 2)), near, pts[:20]])
    index = NearestPoints(pts)
    d, i = index.query(q)
    dk, ik = cKDTree(pts).query(q)
    assert index._tree is None              # far queries: the compiled brute force
    np.testing.assert_allclose(d, dk, rtol=1e-12, atol=1e-9)
    # the same point, or (ties, duplicates) another at the same distance
    same = (i == ik) | np.isclose(np.linalg.norm(pts[i] - q, axis=1), dk, rtol=1e-12, atol=1e-9)
    assert same.all()
    if case in ("outline", "uniform"):          # distinct points: no ties, the same index
        np.testing.assert_array_equal(i, ik)


def test_small_cells_and_bad_input():
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 50, (200, 2))
    q = rng.uniform(-20, 70, (500, 2))
    for cell, rings in ((0.5, 4), (3.0, 1), (3.0, 1000), (200.0, 4)):   # far: brute force
        d, _ = NearestPoints(pts, cell=cell, max_ring=rings).query(q)
        np.testing.assert_allclose(d, cKDTree(pts).query(q)[0], rtol=1e-12)
    with pytest.raises(ValueError, match="non-empty"):
        NearestPoints(np.zeros((0, 2)))
    with pytest.raises(ValueError, match="finite"):
        NearestPoints(pts).query(np.array([[np.nan, 1.0]]))


def test_without_numba_the_kd_tree_answers_and_says_so_once(monkeypatch):
    monkeypatch.setattr(nearest, "HAVE_NUMBA", False)
    monkeypatch.setattr(fallback, "WARNED", set())
    pts = np.random.default_rng(1).uniform(0, 10, (30, 2))
    with pytest.warns(RuntimeWarning, match="k-d tree"):
        a = NearestPoints(pts)
    b = NearestPoints(pts)
    assert not a.compiled and not b.compiled
    q = np.array([[1.0, 2.0], [20.0, -3.0]])
    np.testing.assert_array_equal(a.query(q)[1], cKDTree(pts).query(q)[1])


@pytest.mark.skipif(not nearest.HAVE_NUMBA, reason="numba is not installed")
def test_the_compiled_grid_is_the_stable_bucket_sort_of_its_points():
    """bucket_grid (one compiled call) = the numpy construction: cell, extent, bucket ids by the
    query's arithmetic, a stable argsort and the bucket offsets."""
    rng = np.random.default_rng(5)
    for pts, cell in ((rng.uniform(0, 300, (700, 2)), None), (rng.normal(50, 3, (40, 2)), None),
                      (np.repeat(rng.uniform(0, 9, (5, 2)), 3, axis=0), 2.5),
                      (np.array([[4.0, 4.0]]), None)):
        grid = nearest.NearestPoints(pts, cell=cell)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        extent = np.maximum(hi - lo, 1.0)
        want_cell = cell or max(2.0, float(np.sqrt(extent[0] * extent[1] / max(len(pts) / 2.0, 1.0))))
        nx, ny = int(extent[0] // want_cell) + 1, int(extent[1] // want_cell) + 1
        ix = np.clip(np.floor((pts[:, 0] - lo[0]) * (1.0 / want_cell)), 0, nx - 1).astype(np.int64)
        iy = np.clip(np.floor((pts[:, 1] - lo[1]) * (1.0 / want_cell)), 0, ny - 1).astype(np.int64)
        bucket = iy * nx + ix
        assert (grid.cell, grid.nx, grid.ny) == (want_cell, nx, ny)
        np.testing.assert_array_equal(grid.origin, lo)
        np.testing.assert_array_equal(grid.order, np.argsort(bucket, kind="stable"))
        np.testing.assert_array_equal(
            grid.start, np.concatenate([[0], np.cumsum(np.bincount(bucket, minlength=nx * ny))]))


def _brute_force(pts, q):
    """Nearest point by the grid's arithmetic, ties to the lower index."""
    d2 = (pts[None, :, 0] - q[:, None, 0]) ** 2 + (pts[None, :, 1] - q[:, None, 1]) ** 2
    return np.sqrt(d2.min(axis=1)), d2.argmin(axis=1)


@pytest.mark.skipif(not nearest.HAVE_NUMBA, reason="numba is not installed")
@pytest.mark.parametrize("cell", [None, 1.0, 2.5, 7.0])
def test_ties_and_bucket_edges_give_the_lowest_index(cell):
    """Integer points (an outline's pixels, shuffled) queried on the lattice, on half-pixels
    (exact ties between 2 or 4 points) and exactly on bucket edges: the exact nearest point,
    ties to the lowest index, whichever ring or bucket the scan met it in, or (beyond the
    rings) the brute force."""
    rng = np.random.default_rng(11)
    pts = np.unique(_outline(rng, 3000), axis=0)
    pts = pts[rng.permutation(len(pts))]
    index = NearestPoints(pts, cell=cell)
    lattice = np.stack(np.meshgrid(np.arange(200.0, 500.0, 7.0), np.arange(120.0, 900.0, 11.0)), -1)
    lattice = lattice.reshape(-1, 2)
    edges = index.origin + index.cell * rng.integers(0, 20, (400, 2))
    q = np.concatenate([lattice, lattice + 0.5, lattice + [0.5, 0.0], edges])
    want_d, want_i = _brute_force(pts, q)
    d, i = index.query(q)
    np.testing.assert_array_equal(d, want_d)
    np.testing.assert_array_equal(i, want_i)
    for rings in (0, 1):            # most queries left to the brute force
        d2, i2 = np.empty(len(q)), np.empty(len(q), np.int64)
        nearest.nearest_on_grid(index.xs, index.ys, index.order, index.start, float(index.origin[0]),
                                float(index.origin[1]), index.cell, index.nx, index.ny, rings, pts, q,
                                d2, i2)
        np.testing.assert_array_equal(d2, want_d)
        np.testing.assert_array_equal(i2, want_i)

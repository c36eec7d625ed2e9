"""Silhouette rasterizer: exact union of triangles, batching, culling, input checks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import trimesh

from mocap.render import (
    SilhouetteRasterizer,
    rasterize_silhouettes,
    scale_pixels,
    scaled_size,
)
from tests.render.pinhole import project


def covered(tri: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel centres strictly inside one triangle (3, 2): the test's own reference."""
    y, x = np.mgrid[:height, :width].astype(float)
    e = [(tri[(k + 1) % 3, 0] - tri[k, 0]) * (y - tri[k, 1])
         - (tri[(k + 1) % 3, 1] - tri[k, 1]) * (x - tri[k, 0]) for k in range(3)]
    return np.all(np.array(e) > 0, axis=0) | np.all(np.array(e) < 0, axis=0)


def union_of(pixels: np.ndarray, faces: np.ndarray, height: int, width: int) -> np.ndarray:
    out = np.zeros((height, width), dtype=bool)
    for f in faces:
        out |= covered(pixels[f], height, width)
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


TWO_TRIANGLES = np.array([[10.3, 10.2], [50.1, 12.7], [20.4, 45.6],
                          [25.2, 20.3], [60.7, 30.1], [30.9, 55.5]])


@pytest.mark.parametrize("faces", [[[0, 1, 2], [3, 4, 5]], [[0, 1, 2], [5, 4, 3]]],
                         ids=["same-orientation", "opposite-orientation"])
def test_overlapping_triangles_leave_no_hole(faces):
    faces = np.array(faces)
    expected = union_of(TWO_TRIANGLES, faces, 64, 64)
    overlap = covered(TWO_TRIANGLES[:3], 64, 64) & covered(TWO_TRIANGLES[3:], 64, 64)
    assert overlap.sum() > 100                       # the scene does overlap
    evenodd = np.zeros((64, 64), np.uint8)
    cv2.fillPoly(evenodd, list(np.round(TWO_TRIANGLES[faces] * 256).astype(np.int32)), 1,
                 shift=8)
    assert not evenodd[overlap].all()                # the failure this test guards against
    mask = rasterize_silhouettes(TWO_TRIANGLES[None], faces, 64, 64)[0]
    assert mask[overlap].all()
    np.testing.assert_array_equal(mask, expected)


def test_area_of_a_large_triangle_matches_the_analytic_area():
    tri = np.array([[3.3, 4.1], [190.2, 20.7], [40.6, 180.9]])
    (ax, ay), (bx, by) = tri[1] - tri[0], tri[2] - tri[0]
    area = 0.5 * abs(ax * by - ay * bx)
    mask = rasterize_silhouettes(tri[None], [[0, 1, 2]], 200, 200)[0]
    perimeter = sum(np.linalg.norm(tri[k] - tri[k - 1]) for k in range(3))
    assert abs(mask.sum() - area) < 0.1 * perimeter


def test_random_triangle_soup_equals_union_of_triangles():
    rng = np.random.default_rng(3)
    pixels = rng.uniform(-15.0, 95.0, (60, 2))
    faces = rng.permutation(60).reshape(20, 3)      # mixed orientations, overlaps, clipping
    mask = rasterize_silhouettes(pixels[None], faces, 80, 90)[0]
    np.testing.assert_array_equal(mask, union_of(pixels, faces, 80, 90))


def test_shared_mesh_edges_and_fans_fill_without_seams():
    # A disc as a fan of 32 triangles around a centre vertex, plus a duplicate fan on top.
    a = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    ring = np.stack([40.2 + 30 * np.cos(a), 39.7 + 30 * np.sin(a)], axis=1)
    pixels = np.concatenate([[[40.2, 39.7]], ring])
    faces = np.array([[0, 1 + k, 1 + (k + 1) % 32] for k in range(32)])
    faces = np.concatenate([faces, faces[:, ::-1]])
    mask = rasterize_silhouettes(pixels[None], faces, 80, 80)[0]
    np.testing.assert_array_equal(mask, covered_polygon(ring, 80, 80))


def covered_polygon(poly: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel centres strictly inside a convex polygon (n, 2) of either orientation."""
    y, x = np.mgrid[:height, :width].astype(float)
    pos = np.ones((height, width), dtype=bool)
    neg = np.ones((height, width), dtype=bool)
    for k in range(len(poly)):
        d = poly[(k + 1) % len(poly)] - poly[k]
        e = d[0] * (y - poly[k, 1]) - d[1] * (x - poly[k, 0])
        pos &= e > 0
        neg &= e < 0
    return pos | neg


def test_body_masks_equal_the_reference_method(body_views):
    px, faces = body_views["pixels"], body_views["faces"]
    fast = rasterize_silhouettes(px, faces, 500, 500, scale=0.5)
    ref = rasterize_silhouettes(px, faces, 500, 500, scale=0.5, method="reference")
    assert fast.shape == (3, 4, 250, 250)
    assert min(iou(a, b) for a, b in zip(fast.reshape(-1, 250, 250), ref.reshape(-1, 250, 250),
                                          strict=True)) >= 0.999
    assert (fast != ref).sum() <= 2


def test_body_masks_lie_inside_the_fatter_opencv_masks(body_views):
    px, faces = body_views["pixels"][1], body_views["faces"]
    fast = rasterize_silhouettes(px, faces, 500, 500)
    ocv = rasterize_silhouettes(px, faces, 500, 500, method="opencv")
    assert (fast & ~ocv).sum() <= 0.001 * fast.sum()
    assert 0.9 <= iou(fast, ocv) < 1.0


def test_closed_sphere_mesh_is_a_filled_disc():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    cam = [(np.array([[150.0, 0, 49.7], [0, 150, 50.2], [0, 0, 1]]), np.eye(3), np.zeros(3))]
    pixels, depth = project(sphere.vertices + [0.0, 0.0, 2.0], cam)
    mask = rasterize_silhouettes(pixels, sphere.faces, 100, 100, depth)[0]
    np.testing.assert_array_equal(mask, union_of(pixels[0], sphere.faces, 100, 100))
    assert count_holes(mask) == 0
    hull = cv2.convexHull(pixels[0, :, None].astype(np.float32))[:, 0]
    assert iou(mask, covered_polygon(hull, 100, 100)) > 0.99


def test_closed_body_mesh_has_no_holes(body_views):
    # Front and back views of the A-pose: the arms are clear of the body. (Side views have
    # genuine sub-pixel gaps between arm and torso, also in the reference rasterizers.)
    masks = rasterize_silhouettes(body_views["pixels"][0, 1::2], body_views["faces"], 500, 500)
    evenodd = np.zeros((500, 500), np.uint8)
    tris = np.round(body_views["pixels"][0, 0][body_views["faces"]] * 16).astype(np.int32)
    cv2.fillPoly(evenodd, list(tris), 1, shift=4)
    assert count_holes(evenodd.astype(bool)) > 0     # the check can see even-odd holes
    for mask in masks:
        assert mask.sum() > 10_000
        assert count_holes(mask) == 0


def count_holes(mask: np.ndarray) -> int:
    """Background pixels not reachable from the border (the mask must leave (0, 0) empty)."""
    assert not mask[0, 0]
    fill = mask.astype(np.uint8)
    flood = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)
    cv2.floodFill(fill, flood, (0, 0), 1)
    return int((fill == 0).sum())


def test_batch_equals_single_view_calls(body_views):
    px, faces = body_views["pixels"], body_views["faces"]
    batch = rasterize_silhouettes(px, faces, 500, 500, scale=0.5)
    for p in range(px.shape[0]):
        np.testing.assert_array_equal(
            rasterize_silhouettes(px[p], faces, 500, 500, scale=0.5), batch[p])
        for c in range(px.shape[1]):
            single = rasterize_silhouettes(px[p, c][None], faces, 500, 500, scale=0.5)[0]
            np.testing.assert_array_equal(single, batch[p, c])
    threaded = rasterize_silhouettes(px, faces, 500, 500, scale=0.5, threads=2)
    np.testing.assert_array_equal(threaded, batch)


def test_rasterizer_object_equals_function(body_views):
    px, faces = body_views["pixels"][:1], body_views["faces"]
    rast = SilhouetteRasterizer(faces, px.shape[-2])
    np.testing.assert_array_equal(rast(px, 500, 500, scale=0.5),
                                  rasterize_silhouettes(px, faces, 500, 500, scale=0.5))


@pytest.mark.parametrize("method", ["scanline", "reference"])
def test_triangles_behind_the_camera_are_culled(method):
    cam = [(np.array([[100.0, 0, 50], [0, 100, 50], [0, 0, 1]]), np.eye(3), np.zeros(3))]
    points = np.array([[-0.21, -0.23, 2.0], [0.33, -0.12, 2.1], [0.01, 0.32, 1.9],  # in front
                       [-0.31, 0.13, 1.1], [0.22, 0.19, 0.9], [0.11, -0.24, -1.0]])  # 1 behind
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    pixels, depth = project(points, cam)
    front_only = union_of(pixels[0], faces[:1], 100, 100)
    culled = rasterize_silhouettes(pixels, faces, 100, 100, depth, method=method)[0]
    np.testing.assert_array_equal(culled, front_only)
    wrapped = rasterize_silhouettes(pixels, faces, 100, 100, method=method)[0]
    assert (wrapped & ~front_only).any()            # without depth it wraps into view


def test_nonfinite_pixels_are_allowed_only_at_culled_vertices():
    pixels = np.array([[[10.3, 10.6], [40.2, 12.7], [20.4, 40.1], [np.nan, np.inf]]])
    faces = np.array([[0, 1, 2], [1, 2, 3]])
    depth = np.array([[1.0, 1.0, 1.0, 0.0]])
    mask = rasterize_silhouettes(pixels, faces, 50, 50, depth)[0]
    np.testing.assert_array_equal(mask, union_of(pixels[0], faces[:1], 50, 50))
    with pytest.raises(ValueError, match="NaN or inf"):
        rasterize_silhouettes(pixels, faces, 50, 50)


def test_everything_behind_the_camera_gives_an_empty_mask(body_views):
    px, faces = body_views["pixels"][0, :2], body_views["faces"]
    mask = rasterize_silhouettes(px, faces, 500, 500, -body_views["depth"][0, :2])
    assert mask.shape == (2, 500, 500) and not mask.any()


@pytest.mark.parametrize(("pixels", "faces", "kwargs", "match"), [
    (np.zeros((4, 2)), [[0, 1, 2]], {}, "pixels must have shape"),
    (np.zeros((1, 4, 3)), [[0, 1, 2]], {}, "pixels must have shape"),
    (np.zeros((1, 1, 1, 1, 4, 2)), [[0, 1, 2]], {}, "pixels must have shape"),
    (np.array([[[0.0, 0], [1, 0], [np.nan, 1]]]), [[0, 1, 2]], {}, "NaN or inf"),
    (np.zeros((1, 3, 2)), [[0, 1, 3]], {}, "out of range"),
    (np.zeros((1, 3, 2)), [[0, 1, -1]], {}, "out of range"),
    (np.zeros((1, 3, 2)), [[0, 1]], {}, r"faces must have shape \(F, 3\)"),
    (np.zeros((1, 3, 2)), [[0.0, 1.0, 2.0]], {}, "integer"),
    (np.zeros((1, 3, 2)), [[0, 1, 2]], {"depth": np.ones((1, 4))}, "depth must have shape"),
    (np.zeros((1, 3, 2)), [[0, 1, 2]], {"depth": np.full((1, 3), np.nan)}, "depth contains"),
    (np.zeros((1, 3, 2)), [[0, 1, 2]], {"method": "fillpoly"}, "method must be"),
    (np.zeros((1, 3, 2)), [[0, 1, 2]], {"scale": 0.0}, "scale must be"),
    (np.zeros((1, 3, 2)), [[0, 1, 2]], {"threads": 0}, "threads"),
])
def test_bad_input_raises_value_error_naming_the_problem(pixels, faces, kwargs, match):
    with pytest.raises(ValueError, match=match):
        rasterize_silhouettes(pixels, np.array(faces), 20, 20, **kwargs)


def test_bad_image_size_raises():
    with pytest.raises(ValueError, match="height and width"):
        rasterize_silhouettes(np.zeros((1, 3, 2)), np.array([[0, 1, 2]]), 0, 20)


def test_scaled_size_and_pixel_mapping_keep_the_image_extent():
    assert scaled_size(500, 500, 0.5) == (250, 250)
    assert scaled_size(480, 640, 0.25) == (120, 160)
    corners = np.array([[-0.5, -0.5], [639.5, 479.5]])
    scaled, size = scale_pixels(corners, 480, 640, 0.25)
    assert size == (120, 160)
    np.testing.assert_allclose(scaled, [[-0.5, -0.5], [159.5, 119.5]])
    same, _ = scale_pixels(corners, 480, 640, 1.0)
    assert same is corners


def test_downscaled_mask_equals_mask_of_scaled_pixels_and_tracks_full_resolution(body_views):
    px, faces = body_views["pixels"][2], body_views["faces"]
    small = rasterize_silhouettes(px, faces, 500, 500, scale=0.5)
    scaled, (h, w) = scale_pixels(px, 500, 500, 0.5)
    np.testing.assert_array_equal(small, rasterize_silhouettes(scaled, faces, h, w))
    full = rasterize_silhouettes(px, faces, 500, 500)
    for s, f in zip(small, full, strict=True):
        up = cv2.resize(s.view(np.uint8), (500, 500), interpolation=cv2.INTER_NEAREST)
        assert iou(up.astype(bool), f) > 0.9


def test_out_buffer_is_filled_in_place_and_checked(body_views):
    px, faces = body_views["pixels"][:1], body_views["faces"]
    out = np.ones((1, 4, 250, 250), dtype=bool)
    res = rasterize_silhouettes(px, faces, 500, 500, scale=0.5, out=out)
    assert res is out
    np.testing.assert_array_equal(out, rasterize_silhouettes(px, faces, 500, 500, scale=0.5))
    with pytest.raises(ValueError, match="out must be"):
        rasterize_silhouettes(px, faces, 500, 500, scale=0.5, out=np.ones((4, 250, 250), bool))


@pytest.mark.parametrize("offset", [(-180.0, 0.0), (0.0, 230.0), (200.0, -260.0)])
def test_body_partly_outside_the_image_is_clipped_exactly(body_views, offset):
    px = body_views["pixels"][1, :2] + np.array(offset, dtype=np.float32)
    fast = rasterize_silhouettes(px, body_views["faces"], 500, 500)
    ref = rasterize_silhouettes(px, body_views["faces"], 500, 500, method="reference")
    assert 0 < fast.sum() < rasterize_silhouettes(body_views["pixels"][1, :2],
                                                  body_views["faces"], 500, 500).sum()
    assert (fast != ref).sum() <= 2


def test_huge_coordinates_are_clipped_without_overflow():
    pixels = np.array([[[5.3, 4.2], [1e12, 30.7], [20.1, -3e11], [-7.7, 1e15]]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mask = rasterize_silhouettes(pixels, faces, 40, 50)[0]
    np.testing.assert_array_equal(
        mask, rasterize_silhouettes(pixels, faces, 40, 50, method="reference")[0])
    assert mask.any()


@pytest.mark.skipif(not __import__("mocap.compiled", fromlist=["HAVE_NUMBA"]).HAVE_NUMBA,
                    reason="numba is not installed")
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_compiled_scanline_equals_the_numpy_scanline_pixel_for_pixel(body_views, dtype):
    """The compiled kernel (mocap/render/_compiled.py) and the vectorised numpy scanline give
    the same masks: whole body, body partly outside the image, triangles culled behind the
    near plane, downscaled, a mesh with duplicated faces (K = 2 edge table), several threads."""
    px = body_views["pixels"].astype(dtype)
    depth = body_views["depth"]
    faces = body_views["faces"]
    shifted = px + np.array([260.0, -140.0], dtype)            # partly outside the image
    culled_depth = depth.copy()
    culled_depth[..., ::50] = 0.01                               # every 50th vertex behind near
    doubled = np.concatenate([faces, faces[:300]])
    cases = [(px, faces, None, 1.0, 1), (shifted, faces, None, 1.0, 1),
             (px, faces, culled_depth, 1.0, 1), (px, faces, depth, 0.37, 2),
             (px, doubled, None, 1.0, 3)]
    for pixels, f, d, scale, threads in cases:
        fast = SilhouetteRasterizer(f, pixels.shape[-2])
        slow = SilhouetteRasterizer(f, pixels.shape[-2])
        slow.compiled = False
        a = fast(pixels, 500, 500, d, near=0.05, scale=scale, threads=threads)
        b = slow(pixels, 500, 500, d, near=0.05, scale=scale, threads=threads)
        assert a.any()
        np.testing.assert_array_equal(a, b)

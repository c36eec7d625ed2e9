"""Distance transform: exact Euclidean distance to the silhouette, batched."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from mocap.render import distance_transform, rasterize_silhouettes


@pytest.fixture(scope="module")
def masks(body_views) -> np.ndarray:
    return rasterize_silhouettes(body_views["pixels"][:2], body_views["faces"], 500, 500,
                                 scale=0.5)


def test_distance_matches_scipy_edt_and_is_zero_inside(masks):
    dist = distance_transform(masks)
    assert dist.shape == masks.shape and dist.dtype == np.float32
    for m, d in zip(masks.reshape(-1, 250, 250), dist.reshape(-1, 250, 250), strict=True):
        np.testing.assert_allclose(d, distance_transform_edt(~m), atol=1e-3)
        assert (d[m] == 0).all() and (d[~m] >= 1).all()


def test_random_blobs_match_scipy_edt():
    rng = np.random.default_rng(1)
    mask = rng.random((3, 40, 70)) > 0.995
    mask[:, 0, 0] = True
    expected = np.stack([distance_transform_edt(~m) for m in mask])
    np.testing.assert_allclose(distance_transform(mask.astype(np.uint8)), expected, atol=1e-3)


def test_threads_give_the_same_result(masks):
    np.testing.assert_array_equal(distance_transform(masks, threads=2),
                                  distance_transform(masks))


def test_the_same_distances_on_any_opencv_thread_count_and_call(masks):
    """OpenCV hands the exact transform to Intel IPP on one OpenCV thread only, and IPP's
    distances differ from OpenCV's own and from call to call (by ~1e-5 px): not used."""
    ipp, previous = cv2.ipp.useIPP(), cv2.getNumThreads()
    try:
        first = distance_transform(masks)
        for n in (0, 1, 2, 0, 1, 2, 0, 0):
            cv2.setNumThreads(n)
            np.testing.assert_array_equal(distance_transform(masks), first, err_msg=f"{n} threads")
            assert cv2.ipp.useIPP() == ipp                 # left as it was
    finally:
        cv2.setNumThreads(previous)


def test_empty_mask_gives_the_empty_value():
    mask = np.zeros((2, 10, 12), dtype=bool)
    mask[1, 3, 4] = True
    d = distance_transform(mask)
    assert np.isinf(d[0]).all() and d[1, 3, 4] == 0
    assert (distance_transform(mask, empty_value=-1.0)[0] == -1).all()


@pytest.mark.parametrize(("mask", "match"), [
    (np.zeros(5, dtype=bool), "shape"),
    (np.zeros((3, 0), dtype=bool), "shape"),
    (np.zeros((4, 4), dtype=np.float32), "bool or integer"),
])
def test_bad_mask_raises_value_error(mask, match):
    with pytest.raises(ValueError, match=match):
        distance_transform(mask)


def test_out_buffer_is_filled_in_place_and_checked(masks):
    out = np.full(masks.shape, -1.0, dtype=np.float32)
    assert distance_transform(masks, out=out, threads=2) is out
    np.testing.assert_array_equal(out, distance_transform(masks))
    with pytest.raises(ValueError, match="out must be"):
        distance_transform(masks, out=np.empty(masks.shape, dtype=np.float64))

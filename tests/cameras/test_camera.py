"""Camera and Rig: validation, derived quantities, scaling, Rodrigues conversions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from mocap.cameras import (
    Camera,
    InvalidCameraError,
    Rig,
    project,
    rodrigues_from_rotation,
    rotation_from_rodrigues,
)

from .helpers import random_camera, random_rig

K0 = np.array([[500.0, 0.0, 320.0], [0.0, 510.0, 240.0], [0.0, 0.0, 1.0]])


def make_camera(**changes) -> Camera:
    values = dict(name="cam_a", K=K0, dist=None, R=np.eye(3), t=[0.1, -0.2, 3.0], width=640,
                  height=480)
    values.update(changes)
    return Camera(**values)


def test_center_is_the_point_mapped_to_the_camera_origin(rng):
    cam = random_camera(rng, "c")
    assert np.allclose(cam.R @ cam.center + cam.t, 0.0, atol=1e-12)


def test_projection_matrix_maps_world_points_like_K_R_t(rng):
    cam = random_camera(rng, "c", distortion=False)
    X = rng.normal(size=(10, 3))
    x_h = np.concatenate([X, np.ones((10, 1))], axis=1) @ cam.P.T
    expected = (X @ cam.R.T + cam.t) @ cam.K.T
    assert np.allclose(x_h, expected, rtol=1e-12, atol=1e-9)
    assert np.allclose(cam.P @ np.append(cam.center, 1.0), 0.0, atol=1e-9)


def test_short_distortion_is_zero_padded_to_five_coefficients():
    cam = make_camera(dist=[0.1, -0.02])
    assert cam.dist.shape == (5,)
    assert np.array_equal(cam.dist, [0.1, -0.02, 0.0, 0.0, 0.0])
    assert np.array_equal(make_camera(dist=None).dist, np.zeros(5))
    # eight coefficients are fine when the rational terms are zero
    assert make_camera(dist=[0.1, 0, 0, 0, 0.01, 0, 0, 0]).dist[4] == 0.01


def test_column_vector_translation_is_accepted():
    assert make_camera(t=[[0.1], [-0.2], [3.0]]).t.shape == (3,)


def test_parameter_arrays_are_read_only_float64():
    cam = make_camera(K=K0.astype(np.float32))
    assert cam.K.dtype == np.float64
    with pytest.raises(ValueError):
        cam.K[0, 0] = 1.0


@pytest.mark.parametrize(
    ("field", "changes"),
    [
        ("R", {"R": 1.01 * np.eye(3)}),                                  # not orthonormal
        ("R", {"R": np.diag([1.0, 1.0, -1.0])}),                         # reflection
        ("R", {"R": np.eye(3)[:2]}),                                     # wrong shape
        ("K", {"K": K0 * np.array([[-1.0], [1.0], [1.0]])}),             # negative fx
        ("K", {"K": np.eye(2)}),                                         # wrong shape
        ("K", {"K": K0 + np.array([[0, 0, 0], [0, 0, 0], [0, 0, 1.0]])}),  # K[2, 2] != 1
        ("t", {"t": [0.0, np.nan, 1.0]}),
        ("t", {"t": [0.0, 1.0]}),
        ("dist", {"dist": [0.1, 0.0, 0.0, 0.0, 0.0, 0.3]}),              # rational model
        ("dist", {"dist": [np.inf]}),
        ("width", {"width": 0}),
        ("height", {"height": -480}),
        ("height", {"height": 480.5}),
    ],
)
def test_invalid_parameters_raise_naming_camera_and_field(field, changes):
    with pytest.raises(InvalidCameraError, match=rf"camera 'cam_a': field '{field}'") as info:
        make_camera(**changes)
    assert isinstance(info.value, ValueError)
    assert info.value.field == field and info.value.camera == "cam_a"


def test_equality_is_exact_and_allclose_tolerates_rounding():
    a = make_camera()
    b = make_camera(t=np.array([0.1, -0.2, 3.0]) + 1e-15)
    assert a == make_camera()
    assert a != b
    assert a.allclose(b)
    assert not a.allclose(make_camera(name="other"))


def test_rig_stacks_camera_parameters(rig):
    assert len(rig) == 4
    assert rig.K.shape == (4, 3, 3) and rig.R.shape == (4, 3, 3)
    assert rig.t.shape == (4, 3) and rig.dist.shape == (4, 5) and rig.sizes.shape == (4, 2)
    assert rig.P.shape == (4, 3, 4) and rig.centers.shape == (4, 3)
    for i, cam in enumerate(rig):
        assert np.array_equal(rig.K[i], cam.K) and np.array_equal(rig.t[i], cam.t)
        assert tuple(rig.sizes[i]) == (cam.width, cam.height)
        assert np.array_equal(rig.centers[i], cam.center)
    assert rig.names == ("cam_00", "cam_01", "cam_02", "cam_03")


def test_rig_indexing_by_position_name_slice_and_list(rig):
    assert rig[1] is rig.cameras[1]
    assert rig["cam_02"] is rig.cameras[2]
    assert rig[1:3].names == ("cam_01", "cam_02")
    assert rig[[3, 0]].names == ("cam_03", "cam_00")
    assert rig.index("cam_03") == 3
    with pytest.raises(KeyError, match="cam_99"):
        rig["cam_99"]


def test_rig_rejects_duplicate_names_and_emptiness(rig):
    with pytest.raises(ValueError, match="duplicate"):
        Rig((rig[0], rig[0]))
    with pytest.raises(ValueError):
        Rig(())


def _blob_centroid(image: np.ndarray) -> np.ndarray:
    v, u = np.mgrid[: image.shape[0], : image.shape[1]]
    return np.array([(u * image).sum(), (v * image).sum()]) / image.sum()


@pytest.mark.parametrize("factor", [0.5, 0.25])
def test_scaled_camera_projects_where_the_downscaled_image_shows_the_point(factor):
    """Render a smooth blob where a 3D point projects, shrink the image with cv2.resize
    (INTER_AREA) and find the blob again: the scaled camera must predict its centroid."""
    cam = make_camera(K=np.array([[800.0, 0.0, 301.3], [0.0, 790.0, 257.8], [0, 0, 1]]))
    X = np.array([0.31, -0.17, 2.0])
    u, v = project(cam, X[None])[0]
    vv, uu = np.mgrid[: cam.height, : cam.width]
    image = np.exp(-((uu - u) ** 2 + (vv - v) ** 2) / (2 * 12.0**2))
    small_cam = cam.scaled(factor)
    small = cv2.resize(image, small_cam.size, interpolation=cv2.INTER_AREA)
    assert small.shape == (small_cam.height, small_cam.width)
    predicted = project(small_cam, X[None])[0]
    assert np.allclose(_blob_centroid(small), predicted, atol=0.01)
    # the naive K' = diag(s, s, 1) K is off by (1 - s) / 2 pixels in this convention
    naive = factor * np.array([u, v])
    assert np.all(np.abs(naive - _blob_centroid(small)) > 0.5 * (1 - factor) / 2)


def test_rig_scaled_rounds_image_sizes_and_keeps_extrinsics(rig):
    small = rig.scaled(0.3)
    assert np.array_equal(small.sizes, np.round(rig.sizes * 0.3))
    assert np.array_equal(small.R, rig.R) and np.array_equal(small.dist, rig.dist)
    assert np.all(small.K[:, 0, 0] < rig.K[:, 0, 0])


def test_rodrigues_conversions_match_opencv(rng):
    rvecs = [rng.normal(size=3) for _ in range(20)]
    rvecs += [np.array([1e-10, 0.0, 0.0]), np.zeros(3)]
    rvecs += [a / np.linalg.norm(a) * (np.pi - eps)
              for a, eps in zip(rng.normal(size=(5, 3)), [0.0, 1e-9, 1e-4, 0.1, 1.0],
                                strict=True)]
    for r in rvecs:
        R_cv = cv2.Rodrigues(r)[0]
        assert np.allclose(rotation_from_rodrigues(r), R_cv, atol=1e-12)
        back = rodrigues_from_rotation(R_cv)
        assert np.allclose(rotation_from_rodrigues(back), R_cv, atol=1e-12)
        if np.linalg.norm(r) < np.pi - 1e-6:
            assert np.allclose(back, cv2.Rodrigues(R_cv)[0].ravel(), atol=1e-9)
    # batched: one call equals per-vector calls
    stack = np.stack(rvecs)
    Rs = rotation_from_rodrigues(stack)
    assert Rs.shape == (len(rvecs), 3, 3)
    assert np.allclose(rotation_from_rodrigues(rodrigues_from_rotation(Rs)), Rs, atol=1e-12)


def test_random_rig_helper_is_deterministic():
    assert random_rig(3) == random_rig(3)

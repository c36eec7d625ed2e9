"""Synthetic ring rigs and the conf/cameras presets: geometry, framing, upright images."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hydra.utils import instantiate
from omegaconf import OmegaConf

from mocap.cameras import (
    Rig,
    intrinsics,
    look_at_rotation,
    project,
    rig_from_config,
    ring_rig,
    save_calibration,
)

CONF_DIR = Path(__file__).resolve().parents[2] / "mocap" / "presets" / "cameras"
PRESETS = {"humaneva": (4, 640, 480), "mpi08": (8, 1004, 1004), "ring4_small": (4, 320, 240)}


def standing_person(radius: float = 0.3) -> np.ndarray:
    """(N, 3) world points filling a 1.8 m tall cylinder of the given radius on the floor
    around the origin: where a standing person near the origin can be."""
    heights = np.linspace(0.0, 1.8, 19)
    angles = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    h, a = np.meshgrid(heights, angles)
    ring = np.stack([radius * np.cos(a).ravel(), radius * np.sin(a).ravel(), h.ravel()], -1)
    axis = np.stack([np.zeros(19), np.zeros(19), heights], -1)
    return np.concatenate([axis, ring])


def assert_sees_upright_person(rig: Rig, radius: float = 0.3,
                               look_at_xy: tuple[float, float] = (0.0, 0.0)) -> None:
    """All of a standing person inside every image with positive depth, head above feet, and
    the vertical through the look-at point drawn vertically."""
    pixels, depth = project(rig, standing_person(radius), return_depth=True)
    assert np.all(depth > 0)
    w, h = rig.sizes[:, 0, None], rig.sizes[:, 1, None]
    assert np.all((pixels[..., 0] >= 0) & (pixels[..., 0] <= w - 1)), "person leaves the image"
    assert np.all((pixels[..., 1] >= 0) & (pixels[..., 1] <= h - 1)), "person leaves the image"
    feet, head = project(rig, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.8]])).transpose(1, 0, 2)
    assert np.all(head[:, 1] < feet[:, 1]), "image is upside down"
    x, y = look_at_xy
    feet, head = project(rig, np.array([[x, y, 0.0], [x, y, 1.8]])).transpose(1, 0, 2)
    assert np.allclose(head[:, 0], feet[:, 0], atol=1e-6), "vertical is not vertical"


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_instantiates_with_hydra(name):
    rig = instantiate(OmegaConf.load(CONF_DIR / f"{name}.yaml"))
    num, width, height = PRESETS[name]
    assert isinstance(rig, Rig) and len(rig) == num
    assert np.all(rig.sizes == [width, height])
    assert rig_from_config(name) == rig
    assert rig_from_config(CONF_DIR / f"{name}.yaml") == rig


@pytest.mark.parametrize("name", sorted(PRESETS))
@pytest.mark.parametrize("radius", [0.0, 0.3, 0.8])
def test_preset_cameras_all_see_a_standing_person_upright(name, radius):
    assert_sees_upright_person(rig_from_config(name), radius)


def test_ring_rig_places_cameras_on_the_circle_looking_at_the_target():
    rig = ring_rig(5, radius=3.0, height=1.7, width=400, image_height=300, fov_deg=50.0,
                   look_at=(0.2, -0.1, 1.0))
    assert np.allclose(np.hypot(rig.centers[:, 0], rig.centers[:, 1]), 3.0)
    assert np.allclose(rig.centers[:, 2], 1.7)
    azimuths = np.sort(np.degrees(np.arctan2(rig.centers[:, 1], rig.centers[:, 0])) % 360)
    assert np.allclose(np.diff(azimuths), 72.0)
    target = project(rig, np.array([[0.2, -0.1, 1.0]]))[:, 0]
    assert np.allclose(target, [(400 - 1) / 2, (300 - 1) / 2])
    # camera y axis (image down) points down in the world: upright image
    assert np.all(rig.R[:, 1, 2] < 0)
    assert_sees_upright_person(rig, look_at_xy=(0.2, -0.1))


def test_ring_rig_default_look_at_and_names():
    rig = ring_rig(4, 3.5, 1.5, 320, 240, fov_deg=50.0)
    assert rig.names == ("cam_00", "cam_01", "cam_02", "cam_03")
    assert np.allclose(project(rig, np.array([[0.0, 0.0, 1.0]]))[:, 0], [159.5, 119.5])
    assert ring_rig(2, 3, 1, 64, 48, focal=50.0, names=["a", "b"]).names == ("a", "b")


def test_ring_rig_shares_distortion_across_cameras():
    rig = ring_rig(3, 3.0, 1.5, 320, 240, fov_deg=50.0, dist=[-0.1, 0.01])
    assert np.array_equal(rig.dist, np.tile([-0.1, 0.01, 0, 0, 0], (3, 1)))


def test_vertical_field_of_view_sets_the_focal_length():
    K = intrinsics(640, 480, fov_deg=60.0)
    assert np.isclose(2 * np.degrees(np.arctan(240 / K[1, 1])), 60.0)
    assert np.array_equal(intrinsics(640, 480, focal=500.0)[0], [500.0, 0.0, 319.5])
    with pytest.raises(ValueError, match="exactly one"):
        intrinsics(640, 480, fov_deg=60.0, focal=500.0)


def test_look_at_rotation_is_proper_and_rejects_looking_straight_down():
    R = look_at_rotation([3.0, 1.0, 2.0], [0.0, 0.0, 1.0])
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    with pytest.raises(ValueError, match="parallel"):
        look_at_rotation([0.0, 0.0, 3.0], [0.0, 0.0, 0.0])


def test_rig_from_config_loads_a_calibration_file(tmp_path):
    rig = rig_from_config("ring4_small")
    path = tmp_path / "rig.json"
    save_calibration(rig, path)
    assert rig_from_config(path) == rig
    assert rig_from_config({"calibration": str(path)}) == rig
    with pytest.raises(ValueError, match="no camera preset"):
        rig_from_config("no_such_rig")


def test_the_internal_scale_brings_the_longest_side_to_the_resolution_and_never_enlarges():
    rig = ring_rig(3, radius=3.0, height=1.5, width=1004, image_height=750, fov_deg=50.0)
    assert rig.scale_for(256) == pytest.approx(256 / 1004)
    small = rig.scaled(rig.scale_for(256))
    assert int(np.max(small.sizes)) == 256                       # cv2.resize's rounding of 1004 * s
    assert rig.scale_for(2000) == 1.0                            # an image already smaller stays
    with pytest.raises(ValueError, match="resolution must be positive, got 0"):
        rig.scale_for(0)

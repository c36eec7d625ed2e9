import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from mocap.cameras import ring_rig
from mocap.energy.silhouette import SilhouetteEnergy, chamfer_energy, silhouette_target


@pytest.fixture(scope="module")
def setup(body64):
    rig = ring_rig(4, 3.5, 1.5, 200, 200, fov_deg=50, look_at=(0, 0, 0.9))
    sb = body64.shaped()
    energy = SilhouetteEnergy(sb, rig, scale=1.0)
    chi = body64.zero_pose(1)
    chi[0, body64.dof_index("l_shoulder_abd")] = 0.3
    observed = energy.model_masks(sb.pose(chi).vertices)[0]
    return energy, silhouette_target(observed, 1.0, margin=200), chi


def test_energy_is_zero_when_the_model_matches_the_observation(setup):
    energy, target, chi = setup
    assert energy(chi, target)[0] == 0.0


def test_energy_grows_as_the_pose_is_perturbed(setup, body64):
    energy, target, chi = setup
    d = body64.dof_index("l_elbow_flex")
    chis = np.repeat(chi, 5, axis=0)
    chis[:, d] += np.deg2rad([0, 10, 20, 40, 80])
    e = energy(chis, target)
    assert e[0] == 0 and np.all(np.diff(e) > 0)
    shifted = np.repeat(chi, 4, axis=0)
    shifted[:, 0] += [0.0, 0.02, 0.05, 0.1]
    assert np.all(np.diff(energy(shifted, target)) > 0)


def brute_force_eq11(model: np.ndarray, observed: np.ndarray) -> float:
    """Eq. 11 literally: |D^p - D| summed over each silhouette, exact Euclidean transforms."""
    Dp = distance_transform_edt(~model)
    D = distance_transform_edt(~observed)
    return (np.abs(Dp - D)[model].sum() / model.sum()
            + np.abs(Dp - D)[observed].sum() / observed.sum())


def test_chamfer_matches_brute_force_eq11_on_small_images():
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[:40, :50]
    for _ in range(5):
        def blob():
            cx, cy, r = rng.uniform(15, 35), rng.uniform(12, 28), rng.uniform(5, 10)
            return (xx - cx) ** 2 + ((yy - cy) * rng.uniform(0.6, 1.4)) ** 2 < r**2
        obs, model = blob(), blob()
        target = silhouette_target(obs[None], 1.0, margin=50)
        ours = chamfer_energy(model[None, None], target)[0, 0]
        # the model side uses OpenCV's 5x5 chamfer mask: within a few percent of Euclidean
        assert ours == pytest.approx(brute_force_eq11(model, obs), rel=0.03, abs=1e-9)


def test_empty_observed_view_is_ignored_and_reported(setup):
    energy, target, chi = setup
    masks = target.masks.copy()
    masks[2] = False
    t2 = silhouette_target(masks, 1.0, view_names=("a", "b", "c", "d"))
    assert t2.ignored == ("c",) and not t2.valid[2]
    e = energy(np.repeat(chi, 2, axis=0), t2)
    assert np.all(np.isfinite(e))
    with pytest.raises(ValueError, match="every observed silhouette is empty"):
        silhouette_target(np.zeros_like(masks), 1.0)


def test_particle_outside_every_view_gets_a_finite_penalty(setup):
    energy, target, chi = setup
    far = chi.copy()
    far[0, 0] += 50.0
    e = energy(far, target)[0]
    assert np.isfinite(e) and e > 100


def test_downscaled_masks_follow_the_area_rule_for_bool_and_byte_masks():
    """A pixel of the downscaled mask is set when at least half of the area it covers is
    (OpenCV's INTER_AREA of the 0/255 image, >= 128), whatever the masks' type and layout."""
    import cv2

    from mocap.energy.silhouette import downscale_masks

    rng = np.random.default_rng(4)
    masks = rng.random((3, 301, 403)) < 0.5
    masks[:, 100:200, 150:300] = True
    want = np.stack([cv2.resize(m.astype(np.uint8) * 255, (103, 77), interpolation=cv2.INTER_AREA) >= 128
                     for m in masks])
    scale = 103 / 403
    for given in (masks, masks.astype(np.uint8) * 255, np.asfortranarray(masks)):
        got = downscale_masks(given, scale)
        assert got.shape == want.shape
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("sizes", [(1004, 1004, 251, 251), (1004, 1004, 256, 256),
                                   (500, 500, 128, 128), (480, 640, 120, 160),
                                   (1080, 1920, 256, 455), (1002, 1000, 300, 333)])
def test_block_cropped_area_resize_is_cv2s_whole_image_resize(sizes):
    """_resize_area resamples only whole blocks around the nonzero pixels: equal to
    cv2.resize(INTER_AREA) of the whole image, for integer, dyadic and other scales (the last
    two fall back to the whole image), a blob anywhere (edges included), scattered pixels,
    and an empty image; a 0 / 1 image with gain 255 as the 0 / 255 one."""
    import cv2

    from mocap.energy.silhouette import _resize_area

    H, W, h, w = sizes
    rng = np.random.default_rng(0)
    yy, xx = np.ogrid[:H, :W]
    for trial in range(8):
        m = np.zeros((H, W), np.uint8)
        cy, cx = rng.integers(0, H), rng.integers(0, W)
        ry, rx = rng.integers(1, H // 2), rng.integers(1, W // 3)
        m[((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 < 1] = 255
        if trial % 3 == 2:
            m[rng.random((H, W)) < 0.001] = 255
        want = cv2.resize(m, (w, h), interpolation=cv2.INTER_AREA)
        np.testing.assert_array_equal(_resize_area(m, w, h), want)
        # the 0 / 1 mask with the gain 255 applied to the crop only: the same image
        np.testing.assert_array_equal(_resize_area(m // 255, w, h, gain=255), want)
    np.testing.assert_array_equal(_resize_area(np.zeros((H, W), np.uint8), w, h), 0)


def test_target_boxes_are_the_observed_pixels_extent_grown_by_the_margin():
    """boxes: the min / max + 1 of the set pixels' coordinates, grown by the margin and clipped
    to the image; area: the set pixels' counts."""
    masks = np.zeros((3, 40, 50), bool)
    masks[0, 5:9, 7:30] = True
    masks[0, 20, 3] = True
    masks[1, 0, 49] = True
    masks[2, 30:40, 0:2] = True
    t = silhouette_target(masks, 1.0, margin=4)
    np.testing.assert_array_equal(t.boxes, [[0, 1, 34, 25], [45, 0, 50, 5], [0, 26, 6, 40]])
    np.testing.assert_array_equal(t.area, [4 * 23 + 1, 1, 20])

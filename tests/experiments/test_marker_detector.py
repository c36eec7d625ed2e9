"""The colour marker detector (experiments/tools/marker_detector.py)."""

import os

import cv2
import numpy as np
import pytest

from experiments.tools.marker_detector import ChromaModel, detect_markers, match_detections

GREEN = (40, 230, 40)


def scene(rng, centres, size=(240, 320)):
    """A noisy textured RGB image with green discs (radius 3 px) at centres (N, 2)."""
    img = rng.integers(60, 200, size=(*size, 3), dtype=np.uint8)
    img = cv2.GaussianBlur(img, (7, 7), 2.0)
    for x, y in centres:
        cv2.circle(img, (int(round(x)), int(round(y))), 3, GREEN, -1, lineType=cv2.LINE_AA)
    return img


def test_markers_learned_from_one_image_are_found_in_another():
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.arange(30, 300, 45.0), np.arange(30, 220, 45.0)), -1).reshape(-1, 2)
    train = grid[::3] + rng.uniform(-8, 8, grid[::3].shape)            # separated discs
    test = grid + rng.uniform(-8, 8, grid.shape)
    model = ChromaModel.fit([scene(rng, train)], [train])
    found, area = detect_markers(scene(rng, test), model, threshold=3.0)
    m = match_detections(found, test, np.ones(len(test), bool), radius_px=3.0)
    assert m["detection_rate"] == 1.0 and m["false_positive_rate"] == 0.0
    assert m["pixel_error_px"] < 0.6 and np.all(area >= 9)


def test_matching_counts_hits_misses_and_false_positives():
    truth = np.array([[10.0, 10.0], [50.0, 50.0], [90.0, 90.0]])
    visible = np.array([True, True, False])
    det = np.array([[11.0, 10.0], [200.0, 200.0], [90.0, 90.0]])        # one hit, two false
    m = match_detections(det, truth, visible, radius_px=5.0)
    assert (m["matched"], m["false_positives"], m["visible"]) == (1, 2, 2)
    assert m["detection_rate"] == 0.5 and m["false_positive_rate"] == 1.0 and m["pixel_error_px"] == 1.0


def egl_available() -> bool:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        from mocap.render.pyrender_rgb import RGBRenderer

        RGBRenderer(32, 32).close()
        return True
    except Exception:                                                   # noqa: BLE001 - any failure: no EGL
        return False


@pytest.mark.skipif(not egl_available(), reason="EGL rendering (pyrender) unavailable")
def test_green_marker_spheres_are_detected_in_rendered_images(body):
    from mocap.cameras import project, ring_rig
    from mocap.data.generate import make_synthetic
    from mocap.data.synthetic import marker_visibility

    rig = ring_rig(2, 3.0, 1.5, 400, 300, fov_deg=50, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="gestures", frames=2, fps=25, seed=0, masks=False, images=True,
                         marker_spheres=True)
    px = project(rig, seq.gt.markers)
    shaped = body.shaped(seq.gt.alpha)
    vis = [marker_visibility(shaped.pose(seq.gt.chi[f]).vertices[0], body.faces, seq.gt.markers[f], rig)
           for f in range(2)]
    model = ChromaModel.fit(list(seq.images[0]), [px[0, c][vis[0][c]] for c in range(2)])
    rates = [match_detections(detect_markers(seq.images[1, c], model)[0], px[1, c], vis[1][c])
             for c in range(2)]
    assert np.mean([r["detection_rate"] for r in rates]) > 0.7
    assert np.mean([r["pixel_error_px"] for r in rates]) < 2.0

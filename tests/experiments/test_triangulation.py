"""The robust per-frame triangulation baseline (experiments/tools/triangulation.py)."""

import numpy as np

from experiments.tools.triangulation import robust_triangulation
from mocap.cameras import project, rig_from_config
from mocap.data.sequence import Detections

NAMES = ("a", "b", "c")


def _detections(rig, points, swap_view=None, extra=None):
    """Exact projections of points (F, L, 3) in every view as Detections; ``swap_view``: in
    that view keypoints a and b change labels; ``extra``: (frame, view, label, x, y) rows."""
    rows = []
    F, L = points.shape[:2]
    for f in range(F):
        px = project(rig, points[f])                                   # (C, L, 2)
        for c in range(len(rig)):
            for j in range(L):
                lab = {0: 1, 1: 0}.get(j, j) if c == swap_view else j
                rows.append((f, c, lab, *px[c, j], 0.9))
    rows += [(*r, 0.95) for r in (extra or [])]
    a = np.array(rows, np.float64)
    return Detections(NAMES, a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2].astype(int), a[:, 3:5],
                      a[:, 5])


def test_exact_projections_give_the_exact_points():
    rig = rig_from_config("humaneva")
    X = np.array([[[0.1, -0.2, 1.0], [0.3, 0.1, 1.5], [-0.2, 0.0, 0.4]],
                  [[0.0, 0.0, 1.1], [0.2, 0.2, 1.2], [0.5, -0.3, 0.2]]])
    got, inl = robust_triangulation(rig, _detections(rig, X), NAMES, 2, gate_px=10.0)
    np.testing.assert_allclose(got, X, atol=1e-6)
    assert np.all(inl == len(rig))


def test_an_outlier_view_is_rejected():
    """One view swaps the labels of a and b (0.4 m apart): a plain DLT over all views is pulled
    off by centimetres, the robust one leaves that view out and is exact."""
    from mocap.cameras import triangulate

    rig = rig_from_config("humaneva")
    X = np.array([[[0.0, 0.0, 1.0], [0.4, 0.0, 1.0], [0.0, 0.3, 0.5]]])
    det = _detections(rig, X, swap_view=2)
    got, inl = robust_triangulation(rig, det, NAMES, 1, gate_px=10.0)
    np.testing.assert_allclose(got[0], X[0], atol=1e-6)
    assert inl[0, 0] == inl[0, 1] == len(rig) - 1 and inl[0, 2] == len(rig)
    px = np.full((len(rig), 1, 2), np.nan)
    px[det.view[det.label == 0], 0] = det.xy[det.label == 0]
    naive = triangulate(rig, px)[0]
    assert np.linalg.norm(naive - X[0, 0]) > 0.02


def test_a_false_candidate_does_not_move_the_point_and_misses_hold_the_last_value():
    rig = rig_from_config("humaneva")
    X = np.array([[[0.0, 0.0, 1.0], [0.4, 0.0, 1.0], [0.0, 0.3, 0.5]]] * 2)
    det = _detections(rig, X, extra=[(0, 0, 0, 100.0, 100.0), (0, 1, 0, 200.0, 150.0)])
    keep = ~((det.frame == 1) & (det.label == 2) & (det.view > 0))       # c seen in one view only
    det = Detections(NAMES, det.frame[keep], det.view[keep], det.label[keep], det.xy[keep],
                     det.confidence[keep])
    got, inl = robust_triangulation(rig, det, NAMES, 2, gate_px=10.0)
    np.testing.assert_allclose(got[0], X[0], atol=1e-6)
    assert inl[1, 2] == 0
    np.testing.assert_allclose(got[1, 2], X[0, 2], atol=1e-6)           # held from frame 0
    got, _ = robust_triangulation(rig, det, NAMES, 2, gate_px=10.0, hold=False)
    assert np.all(np.isnan(got[1, 2]))

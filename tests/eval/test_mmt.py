"""MMTA / MMTP (Canton-Ferrer et al. 2010) on hand-computed cases."""

import numpy as np
import pytest

from mocap.eval.metrics import mmta_mmtp


def test_mmta_mmtp_on_a_hand_computed_case():
    truth = np.zeros((2, 3, 3))
    est = truth.copy()
    est[0, 0, 0] = 0.030          # 30 mm: matched
    est[0, 1, 1] = 0.150          # 150 mm: matched
    est[0, 2, 2] = 0.250          # 250 mm: missed at 200 mm
    est[1, 0] = [0.0, 0.3, 0.4]   # 500 mm: missed
    est[1, 1] = [0.06, 0.08, 0.0]  # 100 mm: matched
    # est[1, 2] exact: 0 mm, matched
    m = mmta_mmtp(est, truth, threshold_mm=200.0)
    assert m["mmta"] == pytest.approx(4 / 6)
    assert m["mmtp_mm"] == pytest.approx((30 + 150 + 100 + 0) / 4)
    assert m["mmt_threshold_mm"] == 200.0
    # a tighter threshold: only 30 mm and 0 mm are matched
    m = mmta_mmtp(est, truth, threshold_mm=50.0)
    assert m["mmta"] == pytest.approx(2 / 6) and m["mmtp_mm"] == pytest.approx(15.0)


def test_mmta_counts_the_threshold_itself_and_nothing_matched_is_nan():
    truth = np.zeros((1, 2, 3))
    est = np.array([[[0.2, 0.0, 0.0], [0.0, 0.0, 0.2000001]]])
    m = mmta_mmtp(est, truth, threshold_mm=200.0)
    assert m["mmta"] == 0.5 and m["mmtp_mm"] == pytest.approx(200.0)
    m = mmta_mmtp(est + 1.0, truth)
    assert m["mmta"] == 0.0 and np.isnan(m["mmtp_mm"])

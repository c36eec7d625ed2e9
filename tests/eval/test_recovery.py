"""recovery_figures against hand-computed cases."""

import pytest

from mocap.eval.recovery import recovery_figures


def test_frames_to_recover_counts_from_the_failure_frame():
    errors = [5, 10, 10, 10, 100, 60, 30, 15, 10]
    f = recovery_figures(errors, 4, window=3)
    assert f == {"at_frame": 4, "error_before_mm": 10.0, "error_at_mm": 100.0,
                 "frames_to_recover": 3, "recovered_at_frame": 7}


def test_skipped_frames_are_left_out_of_the_level_and_the_count():
    # frames 3 and 4 were never seen: the level before frame 5 is frames 1, 2 (window 2)
    errors = [8, 10, 12, 999, 999, 50, 15, 30]
    f = recovery_figures(errors, 5, excluded={3, 4}, window=2)
    assert f["error_before_mm"] == 11.0 and f["frames_to_recover"] == 1 and f["recovered_at_frame"] == 6


def test_not_recovered_is_none():
    f = recovery_figures([10, 10, 100, 90, 80], 2, window=2)
    assert f["frames_to_recover"] is None and f["recovered_at_frame"] is None


def test_failure_outside_the_run_is_refused():
    with pytest.raises(ValueError):
        recovery_figures([10, 10], 5)

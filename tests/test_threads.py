"""Thread budget (mocap/threads.py): the limits threadpoolctl, OpenCV and numba report inside
a tracker run are the configured ones (BLAS: always one), and the defaults come back afterwards;
a long BLAS sum gives the same bits on any budget."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from threadpoolctl import threadpool_info

from mocap import threads
from mocap.threads import thread_budget
from mocap.trackers.base import Estimate
from mocap.trackers.contract import OnePerson
from mocap.trackers.run import track_sequence


def blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


class ProbeTracker(OnePerson):
    """Records the thread limits seen while stepping."""

    name = "probe"

    def __init__(self):
        self.seen = []

    def initialize(self, chi, alpha):
        pass

    def step(self, frame):
        numba = pytest.importorskip("numba")
        self.seen.append((blas_threads(), cv2.getNumThreads(), numba.get_num_threads()))
        return Estimate(chi=np.zeros(3), alpha=np.zeros(1), diagnostics={})


def test_a_tracker_run_sees_the_configured_thread_limits(monkeypatch):
    numba = pytest.importorskip("numba")
    if not blas_threads():
        pytest.skip("no BLAS thread pool visible to threadpoolctl")
    seq = SimpleNamespace(num_frames=3, masks=np.zeros((3, 1, 2, 2), bool), images=None, detections=None)
    tracker = ProbeTracker()
    before = (blas_threads(), cv2.getNumThreads(), numba.get_num_threads())
    track_sequence(tracker, seq, np.zeros(3), np.zeros(1), threads=1)
    assert len(tracker.seen) == 2
    for blas, cv, nb in tracker.seen:
        assert blas and all(n == 1 for n in blas)
        assert cv == 1 and nb == 1
    assert (blas_threads(), cv2.getNumThreads(), numba.get_num_threads()) == before
    tracker = ProbeTracker()
    track_sequence(tracker, seq, np.zeros(3), np.zeros(1), threads=2)
    for blas, cv, nb in tracker.seen:
        assert blas and all(n == 1 for n in blas)              # BLAS: one thread on any budget
        assert cv == 2 and nb == min(2, numba.config.NUMBA_NUM_THREADS)
    assert (blas_threads(), cv2.getNumThreads(), numba.get_num_threads()) == before
    # None: the libraries' defaults inside the run
    tracker = ProbeTracker()
    track_sequence(tracker, seq, np.zeros(3), np.zeros(1), threads=None)
    assert tracker.seen[0] == before


def test_auto_budget_is_cores_per_parallel_job(monkeypatch):
    monkeypatch.setattr(threads, "available_cores", lambda: 8)
    assert threads.resolve_threads("auto", 1) == 8
    assert threads.resolve_threads("auto", 2) == 4
    assert threads.resolve_threads("auto", 3) == 2
    assert threads.resolve_threads("auto", -1) == 1          # joblib n_jobs=-1: one per core
    assert threads.resolve_threads("auto", 16) == 1
    assert threads.resolve_threads(3) == 3
    assert threads.resolve_threads("3") == 3 and threads.resolve_threads(None) is None
    for bad in ("many", -2, -1, 0, "0", 1.5, True, ""):
        with pytest.raises(ValueError, match=r"^setting threads = .* is out of range: allowed 'auto'"):
            threads.resolve_threads(bad)
    with pytest.raises(ValueError) as bad:
        threads.resolve_threads(0)
    assert str(bad.value) == ("setting threads = 0 is out of range: allowed 'auto' (cores / parallel jobs), "
                              "an integer >= 1, or null (the libraries' defaults)")


def test_long_blas_sums_are_the_same_on_any_budget():
    """OpenBLAS splits a long matrix-vector product's sum over its threads (1e-4 apart for this
    one on 1 and 2 threads): the budget keeps BLAS on one thread."""
    if threads.available_cores() < 2 or not blas_threads():
        pytest.skip("needs 2 cores and a BLAS thread pool")
    rng = np.random.default_rng(0)
    a = rng.standard_normal((100, 49152)).astype(np.float32)
    x = rng.standard_normal(49152).astype(np.float32)
    with thread_budget(1):
        one = a @ x
    for n in (2, threads.available_cores()):
        with thread_budget(n):
            np.testing.assert_array_equal(a @ x, one, err_msg=f"{n} threads")

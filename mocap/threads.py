"""The thread budget of a tracker process: BLAS / OpenMP (threadpoolctl), numba and OpenCV.

numpy's OpenBLAS starts one thread per core in every process; a Hydra joblib sweep runs one
process per core, so on 2 cores 2 processes x 2 BLAS threads fight over 2 cores (measured:
``apf_prior`` 2.7x and ``local`` 7.8x slower than with one BLAS thread). Every tracker therefore
runs inside :func:`thread_budget`, with ``threads: auto`` = cores divided by the number of jobs
running in parallel (1 in a single run); ``mocap track`` records the budget in metrics.json.

What is reproducible (tests/trackers/test_thread_independence.py,
benchmarks/bench_threads.py): with the same seed, data and settings, a track is bit-identical
on 1 and 2 threads, in one process or in another, with a cold or a warm numba cache, for the
local, APF, hybrid and marker trackers (measured on an AMD EPYC with AVX-512, OpenBLAS 0.3.31
SkylakeX kernels, numba 0.68, OpenCV 5.0). Why: the compiled kernels give each particle-view
(:mod:`mocap.energy.fused`) or image (the rasterizer) to one thread, which sums in a fixed
order; BLAS runs on one thread (:func:`thread_budget`: OpenBLAS splits long sums); the distance
transforms leave Intel IPP out (:mod:`mocap.render.distance`: IPP ran on one OpenCV thread
only, and its distances changed from call to call by ~1e-5 px). Measured with
``bench_threads.py --folder data/mismatch/box --frames 20 --runs hybrid`` (self-initialised,
seed 0): before, two 1-thread runs and a 2-thread run parted from frame 0 (up to 1.0 rad
apart); without IPP but with BLAS on 2 threads, 1 and 2 threads parted at frame 10 (4e-3 rad);
now all three tracks are equal.
Not promised: the same track on another CPU type or with other library builds (OpenBLAS picks
its kernels per CPU, numba compiles for the host CPU, numpy dispatches SIMD per CPU: rounding
differs, and an annealed search can turn rounding into another track), nor more than 2
threads, which this was not measured on.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

import cv2
from threadpoolctl import threadpool_limits


def available_cores() -> int:
    """Cores this process may run on (the affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


#: what ``threads`` may be set to, as the error for another value says it
THREADS_ALLOWED = "'auto' (cores / parallel jobs), an integer >= 1, or null (the libraries' defaults)"


def resolve_threads(setting: int | str | None, parallel_jobs: int = 1) -> int | None:
    """The thread budget from a config value.

    setting: ``"auto"`` (cores // parallel_jobs, at least 1), an int >= 1, or None (no limit:
    the libraries' defaults). Anything else (0, a negative number, another word) raises
    ValueError naming the setting, its value and what is allowed. parallel_jobs: processes
    running at the same time (a joblib sweep's n_jobs; -1 means one per core, as joblib reads it).
    """
    if setting is None or setting == "none":
        return None
    if setting == "auto":
        cores = available_cores()
        jobs = cores if parallel_jobs is None or parallel_jobs < 0 else max(1, int(parallel_jobs))
        return max(1, cores // min(jobs, cores))
    n = None
    if not isinstance(setting, bool | float):
        try:
            n = int(setting)
        except (TypeError, ValueError):
            pass
    if n is None or n < 1:
        raise ValueError(f"setting threads = {setting!r} is out of range: allowed {THREADS_ALLOWED}")
    return n


def _numba_threads(n: int | None) -> int | None:
    """Set numba's thread count (when numba is imported); returns the previous one."""
    import sys

    numba = sys.modules.get("numba")
    if numba is None or n is None:
        return None
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    return previous


@contextmanager
def thread_budget(threads: int | None) -> Iterator[int | None]:
    """Run the body with at most ``threads`` threads in OpenMP pools (threadpoolctl), in OpenCV
    (``cv2.setNumThreads``) and in numba's parallel loops (when numba is loaded), and with one
    BLAS thread whatever ``threads``: OpenBLAS splits a long dot product or matrix-vector
    product's sum over its threads (1 vs 2 threads: 4e-12 apart for a float64 dot of 1e6, 1e-4
    for a float32 (100, 49152) @ (49152,)), so BLAS on more threads would make results depend on
    the budget; the parallel work is numba's (particle-views) and OpenCV's. None: leave the
    libraries' defaults. Restores the previous settings on exit."""
    if threads is None:
        yield None
        return
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads}")
    cv_previous = cv2.getNumThreads()
    # cv2.setNumThreads(1) would still use 1 worker + the caller; 0 runs everything inline
    cv2.setNumThreads(0 if threads == 1 else threads)
    numba_previous = _numba_threads(threads)
    try:
        with threadpool_limits(limits={"blas": 1, "openmp": threads}):
            yield threads
    finally:
        cv2.setNumThreads(cv_previous)
        if numba_previous is not None:
            _numba_threads(numba_previous)

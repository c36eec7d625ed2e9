"""numba, optional: the compiled kernels use it when installed, numpy fallbacks otherwise.

One import for every module with a kernel (``from mocap.compiled import HAVE_NUMBA, njit``);
each module keeps its own ``HAVE_NUMBA`` name, so a test can switch one module's kernels off
by monkeypatching it there.
"""

from __future__ import annotations

try:
    import numba
    from numba import njit, prange
except ImportError:                 # pragma: no cover - numba is a dependency; tests monkeypatch HAVE_NUMBA
    numba = njit = prange = None

HAVE_NUMBA = numba is not None

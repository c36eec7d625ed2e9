"""The numpy fallback of the compiled (numba) kernels: one warning per kernel family, once per
process, when numba is missing and the slower numpy path runs instead (same results)."""

from __future__ import annotations

import warnings

WARNED: set[str] = set()


def warn_once(kernel: str, detail: str) -> None:
    """Warn that ``kernel`` runs on numpy (``detail`` says what that means), the first time only."""
    if kernel not in WARNED:
        warnings.warn(f"numba is not installed: {detail}", RuntimeWarning, stacklevel=4)
        WARNED.add(kernel)

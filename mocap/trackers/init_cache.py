"""Self-initialisation of a tracker, timed, with an optional on-disk cache.

Initialising from silhouettes (:mod:`mocap.trackers.initialization`) costs tens of seconds and
is the same computation for every silhouette tracker of a comparison: the same body, frame,
rig, settings and random state give the same result. ``initial_estimate(..., cache=DIR)``
keys a result by exactly those (a SHA-1 of the body's name and DOFs, the frame's masks, the
calibration, the tracker's ``init_settings``, the state of its ``init_rng`` and the
initialiser's ``INITIALIZER_VERSION``, raised when its algorithm changes; a tracker
without ``init_settings``, such as the marker tracker, is never cached), stores it in
``DIR/<key>.npz`` (written atomically) and reuses it; on a hit the random state is advanced to
where the computation would have left it, so tracking continues identically. Parallel runs
of one sweep wanting the same key wait for the first (an advisory file lock, POSIX only).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import time
from pathlib import Path

try:
    import fcntl
except ImportError:             # not POSIX: no waiting, at worst the work is done twice
    fcntl = None

import numpy as np

from mocap.cameras.calibration_io import rig_to_dict
from mocap.trackers.base import Frame
from mocap.trackers.initialization import INITIALIZER_VERSION


def _key(tracker, frame: Frame) -> str:
    h = hashlib.sha1()
    body = tracker.body
    h.update(json.dumps([body.name, list(body.dof_names), body.num_shape]).encode())
    h.update(np.ascontiguousarray(frame.masks, dtype=bool).tobytes())
    h.update(json.dumps(rig_to_dict(tracker.rig), sort_keys=True, default=str).encode())
    h.update(repr(tracker.init_settings).encode())
    h.update(f"initializer-v{INITIALIZER_VERSION}".encode())
    rng = getattr(tracker, "init_rng", None)
    h.update(json.dumps(rng.bit_generator.state if rng is not None else None, sort_keys=True,
                        default=str).encode())
    return h.hexdigest()[:20]


def initial_estimate(tracker, frame: Frame, cache: str | os.PathLike | None = None
                     ) -> tuple[np.ndarray, np.ndarray, dict]:
    """(chi (D,), alpha (K,), info) from ``tracker.initial_estimate(frame)``. info: seconds (of
    the computation, also on a cache hit), cached (bool), initializer_version (trackers with the
    silhouette initialiser: the ``INITIALIZER_VERSION`` that made the pose, cached or not), and the
    initialiser's hypotheses and margin where it reports them. A tracker with
    ``refine_initial(frame, chi, alpha) -> (chi, alpha, report)`` (the two-cue hybrid) refines the
    pose (and shape) afterwards, outside the cache (whose key describes the initialiser only); a
    non-empty report joins info with its seconds."""
    chi, alpha, info = _cached_estimate(tracker, frame, cache)
    if getattr(tracker, "init_settings", None) is not None:     # the silhouette initialiser's version
        info = {**info, "initializer_version": INITIALIZER_VERSION}
    refine = getattr(tracker, "refine_initial", None)
    if refine is not None:
        t = time.perf_counter()
        chi, alpha, report = refine(frame, chi, alpha)
        if report:
            info = {**info, **report, "refine_seconds": time.perf_counter() - t}
    return chi, alpha, info


def _cached_estimate(tracker, frame: Frame, cache) -> tuple[np.ndarray, np.ndarray, dict]:
    if cache is None or frame.masks is None or getattr(tracker, "init_settings", None) is None:
        return _compute(tracker, frame, None)       # only what the key describes is cached
    path = Path(cache) / f"{_key(tracker, frame)}.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    with _locked(path.with_suffix(".lock")):
        if path.is_file():
            with np.load(path, allow_pickle=False) as z:
                info = json.loads(str(z["info"]))
                if "rng_state" in info and getattr(tracker, "init_rng", None) is not None:
                    tracker.init_rng.bit_generator.state = info.pop("rng_state")
                return z["chi"].copy(), z["alpha"].copy(), {**info, "cached": True}
        return _compute(tracker, frame, path)


@contextlib.contextmanager
def _locked(path: Path):
    if fcntl is None:
        yield
        return
    with open(path, "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _compute(tracker, frame: Frame, path: Path | None) -> tuple[np.ndarray, np.ndarray, dict]:
    t = time.perf_counter()
    chi, alpha = tracker.initial_estimate(frame)
    diag = getattr(tracker, "init_diagnostics", None) or {}
    info = {"seconds": time.perf_counter() - t,
            **{k: v for k, v in diag.items() if k in ("hypotheses", "margin")}}
    if path is not None:
        stored = dict(info)
        rng = getattr(tracker, "init_rng", None)
        if rng is not None:
            stored["rng_state"] = rng.bit_generator.state
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
        np.savez(tmp, chi=chi, alpha=alpha, info=json.dumps(stored, default=float))
        os.replace(tmp, path)
    return chi, alpha, {**info, "cached": False}

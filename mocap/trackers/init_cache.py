"""Self-initialisation as an object (:class:`mocap.trackers.contract.Initializer`), timed, with an
optional on-disk cache.

:class:`SilhouetteStart` is the silhouette trackers' start (:mod:`mocap.trackers.initialization`);
:class:`Refined` composes a start with a refinement run after it (the two-cue hybrid's keypoint
search), outside the cache; :class:`Cached` keeps a start's results on disk.

Initialising from silhouettes costs tens of seconds and is the same computation for every
silhouette tracker of a comparison: the same body, frame, rig, settings and random state give
the same result. ``Cached(start, DIR)`` keys a result by exactly what the start's ``cache_key``
names (for :class:`SilhouetteStart`: a SHA-1 of the body's name and DOFs, the frame's masks,
the calibration, the initialiser's settings, the state of its generator and the
initialiser's ``INITIALIZER_VERSION``, raised when its algorithm changes; a start whose key is
None, such as the marker tracker's, is never cached), stores it in ``DIR/<key>.npz`` (written
atomically) and reuses it; on a hit the random state is advanced to where the computation would
have left it, so tracking continues identically. Parallel runs of one sweep wanting the same
key wait for the first (an advisory file lock, POSIX only).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

try:
    import fcntl
except ImportError:             # not POSIX: no waiting, at worst the work is done twice
    fcntl = None

import numpy as np

from mocap.cameras.calibration_io import rig_to_dict
from mocap.safe_files import write_npz_atomic
from mocap.trackers import init_retrieval, initialization
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.contract import Initializer, initial_estimate_of
from mocap.trackers.tracker_settings import InitSettings


class ProgressLine:
    """A progress callback ``(stage, fraction)`` shown as one line on stderr (a tqdm bar in
    percent with the stage beside it, as a run's frame bar); :meth:`close` ends the line."""

    def __init__(self, desc: str):
        from tqdm import tqdm

        self.bar = tqdm(total=100, desc=desc, unit="%", bar_format="{l_bar}{bar}| {elapsed}{postfix}")

    def __call__(self, stage: str, fraction: float) -> None:
        n = int(round(100 * min(max(fraction, 0.0), 1.0)))
        self.bar.set_postfix_str(stage, refresh=False)
        self.bar.update(max(n - self.bar.n, 0))

    def close(self) -> None:
        self.bar.close()


#: the retrieval start's settings (``InitSettings.search`` "retrieval"), left out of the cache key
#: of an annealed start: its key stays the one computed before they existed
RETRIEVAL_FIELDS = ("search", "retrieval_resolution", "retrieval_headings", "retrieval_keep",
                    "retrieval_samples", "retrieval_sweeps", "retrieval_draws")
#: the shape-and-pose step's settings (:mod:`mocap.trackers.start_shape`), left out of the cache
#: key while it is off (``shape_pose_searches`` 0): the starts computed without it keep their keys
SHAPE_POSE_FIELDS = ("shape_pose_searches", "shape_pose_particles", "shape_pose_layers",
                     "shape_pose_pose_scale", "shape_pose_shape_std")

#: version 6's cheaper early layers, left out of the cache key while off (``coarse_layers`` and
#: ``coarse_shape_layers`` 0): version 3's starts keep their keys
COARSE_FIELDS = ("coarse_layers", "coarse_resolution", "coarse_mesh", "coarse_shape_layers", "coarse_energy",
                 "coarse_samples")


def settings_text(settings) -> str:
    """``repr(settings)``, less the fields of the optional steps that are off: those of
    :data:`RETRIEVAL_FIELDS` where ``settings.search`` is "anneal" and those of
    :data:`SHAPE_POSE_FIELDS` where ``settings.shape_pose_searches`` is 0 and those of
    :data:`COARSE_FIELDS` where ``coarse_layers`` and ``coarse_shape_layers`` are 0 (the dataclass's own
    format, so a start's key is the one computed before those fields existed)."""
    if not dataclasses.is_dataclass(settings):
        return repr(settings)
    off = set(RETRIEVAL_FIELDS) if getattr(settings, "search", None) == "anneal" else set()
    if getattr(settings, "shape_pose_searches", None) == 0:
        off |= set(SHAPE_POSE_FIELDS)
    if getattr(settings, "coarse_layers", None) == 0 and getattr(settings, "coarse_shape_layers", 0) == 0:
        off |= set(COARSE_FIELDS)
    kept = (f"{f.name}={getattr(settings, f.name)!r}" for f in dataclasses.fields(settings)
            if f.repr and f.name not in off)
    return f"{type(settings).__qualname__}({', '.join(kept)})"


class SilhouetteStart:
    """Shape and pose from one frame's silhouettes (:func:`initialize_from_silhouettes`, or with
    ``settings.search`` "retrieval" :func:`~mocap.trackers.init_retrieval.initialize_by_retrieval`) of
    ``body`` seen by ``rig``, with ``settings`` (:class:`InitSettings`) drawing from ``rng``;
    ``library``: poses (T, D) its limb hypotheses draw from (the hybrid's motion library).
    info: seconds, the hypotheses and margin, ``initializer_version``.
    progress: called as ``progress(stage, fraction)`` while it runs (fractions non-decreasing,
    ending at ("done", 1.0)); None: a :class:`ProgressLine` on stderr. Settable after
    construction (``tracker.initializer(cache).start.progress = ...``)."""

    def __init__(self, body, rig, settings: InitSettings | None, rng: np.random.Generator,
                 progress: Callable[[str, float], None] | None = None, library: np.ndarray | None = None):
        self.body, self.rig, self.settings, self.rng = body, rig, settings, rng
        self.progress, self.library = progress, library
        #: the start by retrieval (``settings.search`` "retrieval"); otherwise (no settings: the
        #: defaults) the annealed start
        self.by_retrieval = isinstance(settings, InitSettings) and settings.search == "retrieval"

    def __call__(self, frame: Frame) -> tuple[dict[int, Estimate], dict]:
        t = time.perf_counter()
        line = ProgressLine("silhouette start-up") if self.progress is None else None
        try:
            compute = (init_retrieval.initialize_by_retrieval if self.by_retrieval
                       else initialization.initialize_from_silhouettes)
            chi, alpha, diag = compute(self.body, self.rig, frame.masks, self.rng, self.settings,
                                       progress=self.progress or line, library=self.library)
        finally:
            if line is not None:
                line.close()
        info = {"seconds": time.perf_counter() - t,
                **{k: v for k, v in diag.items() if k in ("hypotheses", "margin", "limbs_changed_at_end")},
                "initializer_version": initialization.INITIALIZER_VERSION}
        return {0: initial_estimate_of(chi, alpha)}, info

    def cache_key(self, frame: Frame) -> str | None:
        if frame.masks is None:
            return None
        h = hashlib.sha1()
        body = self.body
        h.update(json.dumps([body.name, list(body.dof_names), body.num_shape]).encode())
        h.update(np.ascontiguousarray(frame.masks, dtype=bool).tobytes())
        h.update(json.dumps(rig_to_dict(self.rig), sort_keys=True, default=str).encode())
        h.update(settings_text(self.settings).encode())
        h.update(f"initializer-v{initialization.INITIALIZER_VERSION}".encode())
        reads_library = (getattr(self.settings, "limb_hypotheses", 0) or self.by_retrieval)
        if reads_library and self.library is not None:
            h.update(np.ascontiguousarray(self.library, dtype=np.float64).tobytes())
        h.update(json.dumps(self.rng.bit_generator.state, sort_keys=True, default=str).encode())
        return h.hexdigest()[:20]

    def random_state(self) -> dict | None:
        return self.rng.bit_generator.state

    def set_random_state(self, state: dict | None) -> None:
        if state is not None:
            self.rng.bit_generator.state = state


class Refined:
    """``start``, then ``refine(frame, chi, alpha) -> (chi, alpha, report)`` on person 0 (outside
    any cache: its key describes ``start`` only); a non-empty report joins info with its
    seconds."""

    def __init__(self, start: Initializer, refine: Callable):
        self.start, self.refine = start, refine

    def __call__(self, frame: Frame) -> tuple[dict[int, Estimate], dict]:
        est, info = self.start(frame)
        t = time.perf_counter()
        chi, alpha, report = self.refine(frame, est[0].chi, est[0].alpha)
        if report:
            info = {**info, **report, "refine_seconds": time.perf_counter() - t}
        return {0: initial_estimate_of(chi, alpha)}, info

    def cache_key(self, frame: Frame) -> str | None:
        return None

    def random_state(self) -> dict | None:
        return self.start.random_state()

    def set_random_state(self, state: dict | None) -> None:
        self.start.set_random_state(state)


class Cached:
    """``start`` with its results kept in the folder ``cache`` (see the module docstring);
    info gains ``cached`` (bool)."""

    def __init__(self, start: Initializer, cache: str | os.PathLike | None):
        self.start, self.cache = start, cache

    def __call__(self, frame: Frame) -> tuple[dict[int, Estimate], dict]:
        key = self.start.cache_key(frame) if self.cache is not None else None
        if key is None:
            est, info = self.start(frame)
            return est, {**info, "cached": False}
        path = Path(self.cache) / f"{key}.npz"
        path.parent.mkdir(parents=True, exist_ok=True)
        with _locked(path.with_suffix(".lock")):
            if path.is_file():
                with np.load(path, allow_pickle=False) as z:
                    info = json.loads(str(z["info"]))
                    self.start.set_random_state(info.pop("rng_state", None))
                    est = {0: initial_estimate_of(z["chi"].copy(), z["alpha"].copy())}
                    return est, {**info, "cached": True}
            est, info = self.start(frame)
            stored = dict(info)
            state = self.start.random_state()
            if state is not None:
                stored["rng_state"] = state
            write_npz_atomic(path, dict(chi=est[0].chi, alpha=est[0].alpha,
                                        info=json.dumps(stored, default=float)), compress=False)
            return est, {**info, "cached": False}

    def cache_key(self, frame: Frame) -> str | None:
        return self.start.cache_key(frame)

    def random_state(self) -> dict | None:
        return self.start.random_state()

    def set_random_state(self, state: dict | None) -> None:
        self.start.set_random_state(state)


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


def initial_estimate(tracker, frame: Frame, cache: str | os.PathLike | None = None
                     ) -> tuple[np.ndarray, np.ndarray, dict]:
    """(chi (D,), alpha (K,), info) of a single-person tracker's self-initialisation on ``frame``
    (its :meth:`initializer` with ``cache``); a ValueError when it has none."""
    start = tracker.initializer(cache)
    if start is None:
        raise ValueError(f"tracker {tracker.name!r} cannot initialise itself")
    est, info = start(frame)
    return est[0].chi, est[0].alpha, info


class SilhouetteInitialisation:
    """Mixin of the silhouette trackers: their self-initialisation from a frame's masks
    (``initializer``: :class:`SilhouetteStart`) and the validation of
    an initial pose. Needs ``body``, ``rig``, ``init_rng``, ``init_settings``; ``library``
    (below) is the motion library its start draws limb hypotheses from, ``start_body`` the body
    it fits."""

    #: poses (T, D) (NaN: no value) the start's limb hypotheses draw from
    #: (:class:`SilhouetteStart`'s ``library``); None: uniform draws within the joint limits.
    #: A tracker with a motion library sets it (the hybrid: its restarts' library).
    library: np.ndarray | None = None
    #: the body the start fits; None: the tracker's ``body``. A tracker that tracks with its own
    #: joint limits sets it to the body it was given (the hybrid's ``joint_limits``): the start's
    #: cache key holds no limits, so a start is the same whatever limits the tracking has.
    start_body = None

    def initializer(self, cache=None):
        """Shape and pose from a frame's silhouettes alone (Sec. 3.1), cached in the folder
        ``cache`` (None: not cached)."""
        return Cached(self.silhouette_start(self.init_rng), cache)

    def silhouette_start(self, rng: np.random.Generator, progress=None) -> SilhouetteStart:
        """The tracker's start (its ``start_body``, rig, ``init_settings`` and ``library``) drawing
        from ``rng`` (:meth:`initializer`'s: ``init_rng``); ``progress`` as
        :class:`SilhouetteStart`'s."""
        body = self.body if self.start_body is None else self.start_body
        return SilhouetteStart(body, self.rig, self.init_settings, rng, progress=progress,
                               library=self.library)

    def initial_estimate(self, frame) -> tuple[np.ndarray, np.ndarray]:
        """Shape and pose from this frame's silhouettes alone (Sec. 3.1)."""
        est, _ = self.initializer()(frame)
        return est[0].chi, est[0].alpha

    def checked_pose(self, chi: np.ndarray) -> np.ndarray:
        chi = np.asarray(chi, np.float64)
        if chi.shape != (self.body.num_dofs,) or not np.all(np.isfinite(chi)):
            raise ValueError(f"initial pose must be a finite ({self.body.num_dofs},) vector")
        return chi

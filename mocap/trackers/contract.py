"""The contract between a tracker and the run (:func:`mocap.trackers.run.run_frames`, which
serves ``mocap track``, the other tracking commands and :func:`mocap.track` alike).

A tracker declares what it needs from a sequence (:class:`Needs`), the budget of its global
search (:class:`SearchBudget`, reported in metrics.json), checks a sequence before any work
(``check_sequence``), hands out its self-initialisation as an object (``initializer``: an
:class:`Initializer`, with its own cache key), begins from an initial estimate (``begin``) and
answers each later frame (``track``) with a :data:`FrameEstimate`: person id -> estimate. A
single-person tracker answers for person 0 (:class:`OnePerson` gives it ``begin`` and
``track`` from its ``initialize`` / ``step``); a several-people tracker for every person live
in the frame, and says so (``several_people``), so the run writes the several-people motion
file and metrics. A tracker whose ``final_tracks`` revise the answers its frames were given (a
smoothed track) says so (``revises_tracks``), so the run records the frames from the final
tracks once tracking ends. Everything the run asks of a tracker is written here: the run probes no
attribute.

A tracker of one's own implements :class:`Tracker` (usually: subclass :class:`OnePerson`, write
``initialize`` and ``step``), and a factory ``make(*, body, rig, rng, keep_particles, **settings)``
returns it. Then, with nothing registered in the package:

- ``mocap track --config-dir MY_CONF tracker=mine``: ``MY_CONF/tracker/mine.yaml`` names the
  factory in ``_target_`` with its settings (Hydra's ``--config-dir`` adds a config folder to
  the search path, for every Hydra command: ``mocap recovery``, sweeps with ``--multirun``);
- ``mocap.track(seq, make, ...)`` in Python.

``tests/own_tracker/`` is such a tracker, for one person and for several.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

from mocap.trackers.base import Estimate, Frame

#: one frame's answer: person id -> that person's estimate (a single-person tracker: {0: ...})
FrameEstimate = Mapping[int, Estimate]
#: a run's tracks: person id -> {frame: estimate}
Tracks = Mapping[int, Mapping[int, Estimate]]


@dataclass(frozen=True)
class Needs:
    """What a tracker cannot do without in each frame: silhouette masks, camera images, 2D
    detections (what it merely uses when present, such as the local tracker's images for SIFT,
    is not a need). The run checks the sequence has them before any work (:meth:`check`)."""

    masks: bool = False
    images: bool = False
    detections: bool = False

    def check(self, seq, tracker: str) -> None:
        """A one-line ValueError naming the tracker, the sequence and what it lacks."""
        det = seq.detections
        for name, needed, present in (("silhouette masks", self.masks, seq.masks is not None),
                                      ("images", self.images, seq.images is not None),
                                      ("2D detections", self.detections, det is not None and len(det) > 0)):
            if needed and not present:
                raise ValueError(f"tracker {tracker!r} needs {name}, but sequence {seq.name!r} has none")


@dataclass(frozen=True)
class SearchBudget:
    """Particles, annealing layers and energy terms of a tracker's global search (zeros: none)."""

    particles: int = 0
    layers: int = 0
    energy_terms: tuple[str, ...] = ()

    def as_metrics(self) -> dict:
        """The metrics.json keys ``particles``, ``layers``, ``energy_terms``."""
        return {"particles": int(self.particles), "layers": int(self.layers),
                "energy_terms": list(self.energy_terms)}


class Initializer(Protocol):
    """A start on a frame: ``__call__(frame) -> (estimate, info)``, the initial
    :data:`FrameEstimate` and what to report of it (metrics.json's ``init``: seconds, ...).
    ``cache_key(frame)``: what the result depends on, as a hex string (None: never cached);
    ``random_state`` / ``set_random_state``: the state of the generator the computation
    draws from, stored with a cached result and restored on a hit
    (:class:`mocap.trackers.init_cache.Cached`)."""

    def __call__(self, frame: Frame) -> tuple[dict[int, Estimate], dict]: ...

    def cache_key(self, frame: Frame) -> str | None: ...

    def random_state(self) -> dict | None: ...

    def set_random_state(self, state: dict | None) -> None: ...


class Uncached:
    """Mixin of an :class:`Initializer` that is never cached: no cache key, no random state to
    store or restore; the class writes only ``__call__``."""

    def cache_key(self, frame: Frame) -> str | None:
        return None

    def random_state(self) -> dict | None:
        return None

    def set_random_state(self, state: dict | None) -> None:
        pass


class Tracker(Protocol):
    """Every tracker, as the run sees it (see the module docstring)."""

    name: str
    needs: Needs
    several_people: bool
    revises_tracks: bool
    start_up_flags: Sequence[str]

    @property
    def budget(self) -> SearchBudget: ...

    def check_sequence(self, seq) -> None: ...

    def initializer(self, cache=None) -> Initializer | None: ...

    def begin(self, frame: Frame, initial: FrameEstimate) -> FrameEstimate: ...

    def track(self, frame: Frame) -> FrameEstimate: ...

    def final_tracks(self, tracks: Tracks) -> Tracks: ...


def initial_estimate_of(chi: np.ndarray, alpha: np.ndarray) -> Estimate:
    """The estimate of a start: pose chi (D,) and shape alpha (K,), marked initial."""
    from mocap.trackers.diagnostics import StepDiagnostics

    return Estimate(chi=np.asarray(chi, np.float64), alpha=np.asarray(alpha),
                    diagnostics=StepDiagnostics(initial=True))


class OnePerson:
    """The contract's run side for a tracker of one person with ``initialize(chi, alpha)`` and
    ``step(frame) -> Estimate``: person 0. Defaults: no needs checked, no search, no
    self-initialisation (``initializer`` returns None), no start-up flags; a tracker overrides
    what it has."""

    several_people: ClassVar[bool] = False
    revises_tracks: bool = False        # final_tracks returns the tracks as answered
    needs: Needs = Needs()
    start_up_flags: Sequence[str] = ()

    @property
    def budget(self) -> SearchBudget:
        return SearchBudget()

    def check_sequence(self, seq) -> None:
        """Raise a one-line ValueError when ``seq`` cannot be tracked (default: what ``needs``
        says is missing)."""
        self.needs.check(seq, self.name)

    def initializer(self, cache=None) -> Initializer | None:
        return None

    def begin(self, frame: Frame, initial: FrameEstimate) -> FrameEstimate:
        if set(initial) != {0}:
            raise ValueError(f"tracker {self.name!r} tracks one person, given an initial estimate of "
                             f"people {sorted(initial)}")
        self.initialize(initial[0].chi, initial[0].alpha)
        return initial

    def track(self, frame: Frame) -> FrameEstimate:
        return {0: self.step(frame)}

    def final_tracks(self, tracks: Tracks) -> Tracks:
        return tracks

"""What a tracker step reports, as frozen dataclasses (plain data, no rerun, no I/O).

:class:`StepDiagnostics` is ``Estimate.diagnostics``: energies per term, the annealed
search (:class:`mocap.trackers.apf.AnnealTrace`, one :class:`LayerTrace` per layer), the
local optimisation (:class:`LocalTrace`), decisions (:class:`Misalignment`: misaligned
limbs, APF called), a shape refinement (:class:`ShapeUpdate`), the marker tracker's
landmarks (:class:`LandmarkReport`), a failure injected by an experiment
(:class:`Injection`), timings.

Consumers (the recording sink, the run metrics) read the typed fields; :meth:`StepDiagnostics.scalars`
flattens every numeric field of every report into ``{"group/name": value}``, so a field a
tracker adds is plotted without the sink knowing its name. ``d["key"]`` / ``d.get`` give
the old dictionary view (:meth:`StepDiagnostics.as_dict`) for code written against it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from numbers import Number

import numpy as np

from mocap.trackers.apf import AnnealTrace, LayerTrace  # noqa: F401  (LayerTrace re-exported)


@dataclass(frozen=True)
class LocalTrace:
    """One local optimisation (:func:`mocap.local.optimize.optimize_pose`): iterations run,
    correspondences and RMS point-line error (m) per iteration, skipped updates and why,
    SIFT information (matches per view, notes) and views without an observed contour."""

    iterations: int = 0
    correspondences: tuple[int, ...] = ()
    rms_m: tuple[float, ...] = ()
    skipped: tuple[str, ...] = ()
    sift: Mapping | str | None = None
    views_without_contour: tuple[str, ...] = ()
    stopped: str = ""

    @classmethod
    def from_optimizer(cls, opt: Mapping, sift: Mapping | str | None = None) -> LocalTrace:
        last = opt["per_iteration"][-1] if opt.get("per_iteration") else {}
        return cls(iterations=int(opt.get("iterations", 0)),
                   correspondences=tuple(int(c) for c in opt.get("correspondences", ())),
                   rms_m=tuple(float(r) for r in opt.get("rms_m", ())),
                   skipped=tuple(opt.get("skipped", ())), sift=sift,
                   views_without_contour=tuple(last.get("views_without_contour", ())),
                   stopped=str(opt.get("stopped", "")))


@dataclass(frozen=True)
class Misalignment:
    """The misalignment check after local optimisation: flagged limbs, each limb's error
    (share of its vertices outside the observed silhouettes); for the hybrid tracker,
    whether the APF ran (None: the tracker has no APF fallback), over which DOFs, and whether
    its result was kept (it is only where it lowers the frame's silhouette energy). With the
    two-sided check, each limb chain's share of the observed area left unexplained
    (``unexplained``, by chain root) and the share above which it was flagged
    (``unexplained_limit``). ``patrol``: the APF searched a limb chain though none was flagged
    (the hybrid's ``patrol``)."""

    limbs: tuple[str, ...] = ()
    limb_errors: Mapping[str, float] = field(default_factory=dict)
    apf_called: bool | None = None
    free_dofs: tuple[str, ...] = ()
    apf_accepted: bool | None = None
    unexplained: Mapping[str, float] = field(default_factory=dict)
    unexplained_limit: Mapping[str, float] = field(default_factory=dict)
    patrol: bool = False

    @classmethod
    def of(cls, check, **decision) -> Misalignment:
        """The report of a :class:`mocap.local.misalignment.LimbCheck`, plus the tracker's
        ``decision`` fields (apf_called, ...)."""
        return cls(tuple(check.names), dict(check.errors), unexplained=dict(check.unexplained),
                   unexplained_limit=dict(check.unexplained_limit), **decision)


@dataclass(frozen=True)
class LandmarkReport:
    """The marker tracker's landmarks: names (L,), estimated points (L, 3) world metres,
    views with a detection near each, the weak ones (temporal coherence), and the median
    reprojection error (px)."""

    names: tuple[str, ...]
    points: np.ndarray
    views: Mapping[str, int]
    weak: tuple[str, ...]
    reprojection_px: float


@dataclass(frozen=True)
class RefineTrace:
    """The marker tracker's final Gauss-Newton refinement on the reprojection error:
    iterations run, median reprojection residual (px) before and after."""

    iterations: int = 0
    residual_px_before: float = float("nan")
    residual_px_after: float = float("nan")


@dataclass(frozen=True)
class Injection:
    """A failure an experiment injected at this frame (:mod:`mocap.trackers.failures`):
    ``skipped``: the frame never reached the tracker (the estimate is the last one held);
    ``perturbed``: the tracker was restarted from a perturbed pose before this frame."""

    skipped: bool = False
    perturbed: bool = False


@dataclass(frozen=True)
class ShapeUpdate:
    """A shape refinement while tracking (:func:`mocap.trackers.shape_search.refine_shape`):
    E_S of the keyframes with the shape held so far and with the one found, whether it was
    kept, the shared shift that came with it (m), and the keyframes' indices."""

    energy_before: float
    energy_after: float
    accepted: bool
    shift_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    keyframes: tuple[int, ...] = ()


@dataclass(frozen=True)
class StepDiagnostics:
    """Everything one step reports. ``initial``: the estimate is the initial pose."""

    energy_terms: Mapping[str, float] = field(default_factory=dict)
    anneal: AnnealTrace | None = None
    local: LocalTrace | None = None
    refine: LocalTrace | None = None
    misalignment: Misalignment | None = None
    landmarks: LandmarkReport | None = None
    marker_refine: RefineTrace | None = None
    timings: Mapping[str, float] = field(default_factory=dict)
    ignored_views: tuple[str, ...] = ()
    injection: Injection | None = None
    shape: ShapeUpdate | None = None
    initial: bool = False
    #: the start chosen over frames, on the frame it was chosen (the hybrid's ``start_frames``):
    #: {"frames": n, "hypotheses": [names], "energy": [summed E_S], "chosen": name}
    start_choice: Mapping | None = None

    @property
    def energy(self) -> float | None:
        return float(sum(self.energy_terms.values())) if self.energy_terms else None

    @property
    def energy_evaluations(self) -> int:
        return self.anneal.evaluations if self.anneal is not None else 0

    @property
    def particles(self) -> list[np.ndarray]:
        """Particles (P, D) of the layers that kept them (empty otherwise)."""
        return self.anneal.particles if self.anneal is not None else []

    @property
    def apf_called(self) -> bool | None:
        return None if self.misalignment is None else self.misalignment.apf_called

    def scalars(self) -> dict[str, float]:
        """Every numeric field, flattened: ``energy/<term>``, ``energy/total``,
        ``timing/<stage>``, ``misalignment/limb_errors/<limb>``, ``local/iterations``, ...
        (per-layer annealing values are in ``anneal``; arrays and text are left out)."""
        left = ("anneal", "energy_terms", "timings", "initial", "start_choice")
        out = flatten_scalars("", {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                                   if f.name not in left})
        out.update({f"energy/{k}": float(v) for k, v in self.energy_terms.items()})
        if self.energy_terms:
            out["energy/total"] = self.energy
        out.update({f"timing/{k}": float(v) for k, v in self.timings.items()})
        if self.misalignment is not None:
            out["misalignment/count"] = float(len(self.misalignment.limbs))
        return out

    def as_dict(self) -> dict:
        """The old dictionary form of the diagnostics (keys as the trackers wrote them)."""
        d: dict = {"timings": dict(self.timings)}
        if self.initial:
            d["initial"] = True
        if self.energy_terms:
            d.update(energy_terms=dict(self.energy_terms), energy=self.energy)
        if self.anneal is not None:
            a = self.anneal
            d.update(layers={k: getattr(a, k) for k in ("energy_min", "energy_mean", "beta", "survival",
                                                        "ess", "spread")},
                     particles=a.particles or None, energy_evaluations=a.evaluations)
        if self.ignored_views or self.anneal is not None:
            d["ignored_views"] = list(self.ignored_views)
        if self.local is not None:
            loc = self.local
            d["local"] = {"iterations": loc.iterations, "skipped": list(loc.skipped),
                          "correspondences": list(loc.correspondences), "rms_m": list(loc.rms_m)}
            d["views_without_contour"] = list(loc.views_without_contour)
            if loc.sift is not None:
                d["sift"] = loc.sift
        if self.refine is not None:
            d["refine"] = {"iterations": self.refine.iterations, "rms_m": list(self.refine.rms_m)}
        if self.misalignment is not None:
            m = self.misalignment
            d.update(misaligned_limbs=list(m.limbs), limb_errors=dict(m.limb_errors))
            if m.unexplained:
                d.update(unexplained=dict(m.unexplained), unexplained_limit=dict(m.unexplained_limit))
            if m.apf_called is not None:
                d["apf_called"] = int(m.apf_called)
                if m.apf_called:
                    d["apf_free_dofs"] = list(m.free_dofs)
                if m.patrol:
                    d["patrol"] = True
        if self.landmarks is not None:
            lm = self.landmarks
            d.update(landmarks=lm.points, landmark_names=list(lm.names),
                     views_per_landmark=dict(lm.views), weak_landmarks=list(lm.weak),
                     reprojection_px=lm.reprojection_px)
        if self.marker_refine is not None:
            d["refinement"] = dataclasses.asdict(self.marker_refine)
        if self.injection is not None:
            d["injection"] = dataclasses.asdict(self.injection)
        if self.shape is not None:
            d["shape_update"] = dataclasses.asdict(self.shape)
        if self.start_choice is not None:
            d["start_choice"] = dict(self.start_choice)
        return d

    # read-only mapping access to the old dictionary form
    def __getitem__(self, key: str):
        return self.as_dict()[key]

    def __contains__(self, key: str) -> bool:
        return key in self.as_dict()

    def get(self, key: str, default=None):
        return self.as_dict().get(key, default)


def flatten_scalars(prefix: str, value) -> dict[str, float]:
    """Numbers (bools included) of nested dataclasses / mappings as {"a/b/c": float}."""
    if isinstance(value, bool | Number) and not isinstance(value, np.ndarray):
        return {prefix: float(value)}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        out: dict[str, float] = {}
        for k, v in value.items():
            out.update(flatten_scalars(f"{prefix}/{k}" if prefix else str(k), v))
        return out
    return {}

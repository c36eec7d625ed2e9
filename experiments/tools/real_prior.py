"""The pose prior trained on real motion capture (the study experiments/prior_heldout.py):
clips of the motion types a split trains on (:mod:`mocap.clips.split`), retargeted onto the
body by :mod:`mocap.clips`; a held-out type raises before any work.
"""

from __future__ import annotations

import csv
import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial
from pathlib import Path

import numpy as np

from mocap.body.model import BodyModel
from mocap.clips.split import MotionSplit, check_training_types, read_split
from mocap.energy.prior import ParzenPrior, PriorProvenance
from mocap.safe_files import write_npz_atomic

#: licence and attribution of a prior trained on the Bandai Namco Research Motion Dataset
BANDAI_NAMCO_LICENCE = (
    "CC BY-NC 4.0 — adapted from the Bandai-Namco-Research-Motiondataset (c) 2022 Bandai Namco "
    "Research Inc., https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset; "
    "non-commercial use only")
SELECTIONS = ("uniform", "farthest")
#: sigma of the real prior: "paper" = max nearest-neighbour distance (Zhang et al. 2013);
#: "loto" = the isotropic width with the best leave-one-motion-type-out likelihood
SIGMA_RULES = ("paper", "loto")
LOTO_SIGMAS = np.geomspace(0.05, 2.0, 33)


@dataclass(frozen=True)
class ClipEntry:
    """One clip of a motion-capture folder: its path, motion type and file SHA-256."""

    path: Path
    motion: str
    sha256: str


def clip_entries(clips_folder: str | Path, types: tuple[str, ...] | list[str]) -> list[ClipEntry]:
    """The clips of the given motion types listed in ``clips_folder/index.csv`` (columns
    ``file``, ``motion``), sorted by path, with their SHA-256."""
    folder = Path(clips_folder)
    index = folder / "index.csv"
    if not index.is_file():
        raise ValueError(f"clips folder {folder}: no index.csv (columns file, motion) to list its clips")
    with index.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["motion"] in set(types)]
    out = []
    for r in sorted(rows, key=lambda r: r["file"]):
        path = folder / r["file"]
        if not path.is_file():
            raise ValueError(f"{index} lists {r['file']}, which is not in {folder}")
        out.append(ClipEntry(path, r["motion"], hashlib.sha256(path.read_bytes()).hexdigest()))
    return out


def clips_sha256(entries: list[ClipEntry]) -> str:
    """SHA-256 of the sorted ``name sha256`` lines of the clips (the clip list's identity)."""
    lines = sorted(f"{e.path.name} {e.sha256}" for e in entries)
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


@cache
def retarget_version() -> str:
    """The retargeting's version: ``mocap.clips.retarget.RETARGET_VERSION`` if it has one, else a
    hash of the sources it depends on (retarget, fit, bvh, names and the name maps: any change
    re-retargets). Computed once per process, when the retargeting is imported, so that files
    edited while a process runs cannot label results of the code it loaded."""
    import importlib

    rt = importlib.import_module("mocap.clips.retarget")      # the module (the package exports its function)

    version = getattr(rt, "RETARGET_VERSION", None)
    if version is not None:
        return str(version)
    folder = Path(rt.__file__).parent
    h = hashlib.sha256()
    for f in sorted([*folder.glob("*.py"), *folder.glob("maps/*.yaml")]):
        if f.name in ("retarget.py", "fit.py", "bvh.py", "names.py") or f.suffix == ".yaml":
            h.update(f.name.encode() + f.read_bytes())
    return "src" + h.hexdigest()[:10]


def _retarget_clip(path: Path, body: BodyModel, step: int = 1) -> np.ndarray:
    """χ (F, D) of ``body`` following every ``step``-th frame of the clip (mocap.clips's reader
    and retargeting)."""
    from mocap.clips import read_bvh
    from mocap.clips.retarget import retarget

    return np.asarray(retarget(read_bvh(path), body, step=step).chi, np.float64)


def retargeted_chi(entry: ClipEntry, body: BodyModel, cache_dir: str | Path | None, step: int = 1,
                   retarget_fn: Callable[[Path, BodyModel], np.ndarray] | None = None) -> np.ndarray:
    """χ (F, D) of a clip retargeted onto ``body`` (every ``step``-th frame), cached in
    ``cache_dir`` as ``<body><dofs hash>-<clip sha256[:16]>-<version>-s<step>.npz`` (None: no
    cache). retarget_fn(path, body) -> χ replaces mocap.clips's retargeting (tests)."""
    if retarget_fn is None:
        version = retarget_version()
        fn = partial(_retarget_clip, step=step)
    else:
        version, fn = "custom", retarget_fn
    key = hashlib.sha256(",".join(body.dof_names).encode()).hexdigest()[:8]
    cache = None if cache_dir is None else (
        Path(cache_dir) / f"{body.name}{key}-{entry.sha256[:16]}-{version}-s{step}.npz")
    if cache is not None and cache.is_file():
        with np.load(cache) as z:
            return z["chi"]
    chi = np.asarray(fn(entry.path, body), np.float64)
    if chi.ndim != 2 or chi.shape[1] != body.num_dofs:
        raise ValueError(f"retargeting {entry.path} gave χ of shape {chi.shape}, "
                         f"expected (F, {body.num_dofs})")
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        write_npz_atomic(cache, dict(chi=chi, clip=str(entry.path.name), sha256=entry.sha256,
                                     version=version, step=step), compress=False)
    return chi


def real_poses(entries: list[ClipEntry], body: BodyModel, cache_dir: str | Path | None = None,
               step: int = 1, retarget_fn: Callable[[Path, BodyModel], np.ndarray] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles of every ``step``-th frame of the clips: poses (N, D - 6), clip id per pose
    (N,) (the index into ``entries``)."""
    poses, groups = [], []
    for i, e in enumerate(entries):
        chi = retargeted_chi(e, body, cache_dir, step, retarget_fn)
        poses.append(chi[:, 6:])
        groups.append(np.full(len(chi), i))
    return np.concatenate(poses), np.concatenate(groups)


def observed_dofs(body: BodyModel, point_names: tuple[str, ...] | list[str], poses: int = 8,
                  seed: int = 0, delta: float = 0.1) -> tuple[str, ...]:
    """The joint-angle DOFs that move at least one of the named points (joints or catalogue
    landmarks; the points a name map fits): a clip cannot tell the others (e.g. the wrists when
    no hand end is mapped), so retargeting leaves them arbitrary and a prior must not learn them.
    Checked at the rest pose and ``poses`` random poses within the limits."""
    from mocap.clips.fit import PointFunction

    fn = PointFunction(body, list(point_names))
    lo, hi = np.asarray(body.limits, np.float64)[6:].T
    chi = np.zeros((poses + 1, body.num_dofs))
    chi[1:, 6:] = np.random.default_rng(seed).uniform(lo, hi, (poses, len(lo)))
    alpha = np.zeros(body.num_shape)
    base = fn(alpha, chi)
    keep = []
    for d in range(6, body.num_dofs):
        moved = chi.copy()
        moved[:, d] += np.where(moved[:, d] + delta <= hi[d - 6], delta, -delta)
        if np.abs(fn(alpha, moved) - base).max() > 1e-6:
            keep.append(body.dof_names[d])
    return tuple(keep)


def select_samples(poses: np.ndarray, samples: int, selection: str = "uniform") -> np.ndarray:
    """Indices of ``samples`` of the pool (N, n): ``uniform`` evenly spaced in the pool's order
    (its time order), ``farthest`` by farthest-point sampling from the first pose."""
    if selection not in SELECTIONS:
        raise ValueError(f"selection={selection!r}: allowed {', '.join(SELECTIONS)}")
    N = len(poses)
    if samples >= N:
        return np.arange(N)
    if selection == "uniform":
        return np.unique(np.linspace(0, N - 1, samples).round().astype(int))
    pick = [0]
    d2 = ((poses - poses[0]) ** 2).sum(axis=1)
    for _ in range(samples - 1):
        pick.append(int(d2.argmax()))
        d2 = np.minimum(d2, ((poses - poses[pick[-1]]) ** 2).sum(axis=1))
    return np.array(sorted(pick))


def train_real_prior(clips_folder: str | Path, body: BodyModel, split: MotionSplit | None = None,
                     samples: int = 2000, *, types: tuple[str, ...] | None = None,
                     selection: str = "uniform", step: int = 1, sigma: str = "paper",
                     dofs: tuple[str, ...] | None = None, cache_dir: str | Path | None = None,
                     retarget_fn: Callable[[Path, BodyModel], np.ndarray] | None = None,
                     licence: str = BANDAI_NAMCO_LICENCE) -> ParzenPrior:
    """The Parzen prior (Eq. 15-16, sigma = max nearest-neighbour distance) on ``samples`` poses
    of real motion: every frame of the clips of the split's train types (or ``types``, which
    must be train types: a held-out type raises before any work), retargeted onto ``body``
    (every ``step``-th frame, cached per clip in ``cache_dir``), then ``samples`` of them chosen
    by ``selection``. ``sigma``: "paper" (max nearest-neighbour distance) or "loto" (the width
    of ``LOTO_SIGMAS`` under which each training motion type is most probable given the others'
    samples: the prior is for motion types it has not seen). ``dofs``: the joint angles the prior
    covers (None: all; see :func:`observed_dofs`)."""
    split = split or read_split()
    types = tuple(types) if types is not None else split.train
    check_training_types(types, split)
    if selection not in SELECTIONS:
        raise ValueError(f"selection={selection!r}: allowed {', '.join(SELECTIONS)}")
    if sigma not in SIGMA_RULES:
        raise ValueError(f"sigma={sigma!r}: allowed {', '.join(SIGMA_RULES)}")
    entries = clip_entries(clips_folder, types)
    if not entries:
        raise ValueError(f"clips folder {clips_folder}: no clip of the motion types {', '.join(types)}")
    check_training_types(sorted({e.motion for e in entries}), split)
    names = tuple(body.dof_names[6:]) if dofs is None else tuple(dofs)
    unknown = [d for d in names if d not in body.dof_names[6:]]
    if unknown:
        raise ValueError(f"dofs {', '.join(unknown)} are not joint angles of body {body.name!r}")
    pool, groups = real_poses(entries, body, cache_dir, step, retarget_fn)
    pool = pool[:, [body.dof_names.index(d) - 6 for d in names]]
    pick = select_samples(pool, samples, selection)
    prior = ParzenPrior.fit(pool[pick], names)
    rule = ""
    if sigma == "loto":
        from mocap.energy.prior_eval import select_bandwidth_scale

        motion = np.array([entries[g].motion for g in groups[pick]])
        best, _ = select_bandwidth_scale(prior.samples, motion, 1.0, LOTO_SIGMAS)
        rule = (f"leave-one-motion-type-out likelihood over {len(LOTO_SIGMAS)} widths "
                f"{LOTO_SIGMAS[0]:g}-{LOTO_SIGMAS[-1]:g} rad (the paper's rule: {prior.sigma:.3f} rad)")
        prior = ParzenPrior(prior.samples, prior.dof_names, best)
    version = (retarget_version() if retarget_fn is None else "custom") + f", every {step} frame(s)"
    prov = PriorProvenance(licence=licence, motion_types=tuple(sorted({e.motion for e in entries})),
                           held_out_types=split.held_out, clips=len(entries),
                           clips_sha256=clips_sha256(entries), pool=len(pool),
                           selection=f"{selection} ({len(pick)} of {len(pool)} frames)",
                           retarget=version, body=body.name, sigma_rule=rule)
    source = (f"{len(pick)} poses of {len(entries)} real motion-capture clips "
              f"({split.dataset or Path(clips_folder).name}; types {', '.join(prov.motion_types)}) "
              f"retargeted onto body '{body.name}'; sigma by the {sigma} rule")
    return ParzenPrior(prior.samples, prior.dof_names, prior.sigma, source, prov)

"""Ablation tables from a sweep's run directories (their metrics.json, never logs); their
figures are :mod:`mocap.run_folder.sweep_plots`."""

from __future__ import annotations

import csv
import itertools
import json
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from mocap.run_folder.manifest import manifest_problem


@dataclass(frozen=True)
class Collected:
    runs: list[dict]                  # metrics.json contents, with "_dir"
    problems: list[tuple[str, str]]   # (run dir or job, what is wrong)


def _sweep_values(value: str) -> int:
    """How many values a comma sweep lists; commas inside [], {}, () or quotes do not split."""
    depth, quote, n = 0, None, 1
    for ch in value:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        elif ch == "," and depth == 0:
            n += 1
    return n


def expected_jobs(sweep_dir: Path) -> int | None:
    """Number of jobs a Hydra sweep launched, from its multirun.yaml: the sweeper's params (a
    config such as conf/sweep/*) overridden by the command line's (simple comma sweeps)."""
    path = sweep_dir / "multirun.yaml"
    if not path.is_file():
        return None
    hydra = (yaml.safe_load(path.read_text()) or {}).get("hydra", {}) or {}
    params = {str(k): str(v) for k, v in ((hydra.get("sweeper", {}) or {}).get("params", {}) or {}).items()}
    for o in (hydra.get("overrides", {}) or {}).get("task", []) or []:
        if "=" in str(o):
            k, v = str(o).split("=", 1)
            params[k.lstrip("+~")] = v
    sizes = [_sweep_values(v) for v in params.values()]
    return int(np.prod(sizes)) if sizes else 1


NO_GT_METRICS = (("reprojection_median_px", "reprojection (px)"),
                 ("bone_length_std_mm", "bone-length std (mm)"),
                 ("jitter_mm", "jitter (mm)"))


def _overrides(run_dir: Path) -> list[str]:
    path = run_dir / ".hydra" / "overrides.yaml"
    if not path.is_file():
        return []
    return [str(o) for o in (yaml.safe_load(path.read_text()) or [])]


def _motion_metrics(run_dir: Path) -> dict:
    """Bone-length stability and jitter of a run's landmarks, from its motion.npz (runs with
    neither ground truth nor detections report no accuracy of their own)."""
    from mocap.eval.keypoint_metrics import bone_lengths, jitter_mm
    from mocap.export.motion import MotionFileError, load_motion

    try:
        m = load_motion(run_dir / "motion.npz")
    except MotionFileError:
        return {}
    X = m.landmarks.astype(np.float64)
    bones = bone_lengths(X, m.landmark_names)
    return {"bone_length_std_mm": float(1e3 * np.mean([np.nanstd(v) for v in bones.values()]))
            if bones else float("nan"), "jitter_mm": jitter_mm(X)}


def collect(sweep_dir: str | Path, require_manifest: bool = True) -> Collected:
    """Every run under ``sweep_dir`` (a directory holding .hydra/). Reported as problems, never
    dropped silently or averaged: runs that are not complete (no valid manifest.json,
    :mod:`mocap.run_folder.manifest`; with ``require_manifest=False`` kept in the table and
    listed as UNVERIFIED), runs without a readable metrics.json, runs whose joint error is NaN.
    Runs without ground truth keep their own metrics (reprojection, bone-length stability,
    jitter; the last two from motion.npz when metrics.json lacks them). Runs are labelled
    from the configuration that ran (metrics.json's ``"config"``); a row holding runs of
    different configurations or one seed twice (a sweep folder that mixes configs) is
    reported too (:func:`mixed_rows`)."""

    sweep_dir = Path(sweep_dir)
    if not sweep_dir.is_dir():
        raise FileNotFoundError(f"sweep directory not found: {sweep_dir}")
    runs, problems = [], []
    run_dirs = sorted({p.parent for p in sweep_dir.rglob(".hydra")})
    for d in run_dirs:
        m = d / "metrics.json"
        if not m.is_file():
            failed = (d / "recording.failed.rrd").is_file()
            problems.append((str(d), "failed (recording.failed.rrd, no metrics.json)" if failed
                             else "incomplete or failed: no metrics.json"))
            continue
        try:
            data = json.loads(m.read_text())
            data["_dir"] = str(d)
            for key in ("tracker", "sec_per_frame"):
                if key not in data:
                    raise KeyError(key)
        except (json.JSONDecodeError, KeyError) as exc:
            problems.append((str(d), f"unreadable metrics.json ({exc!r})"))
            continue
        problem = manifest_problem(d)
        if problem is not None and require_manifest:
            problems.append((str(d), f"not a complete run ({problem}); not in the table"))
            continue
        if problem is not None:         # accepted unverified (runs written before manifests): said so
            problems.append((str(d), f"UNVERIFIED, in the table ({problem})"))
        if "mpjpe_mm" in data and not np.isfinite(data["mpjpe_mm"]):
            problems.append((str(d), f"joint error is {data['mpjpe_mm']} (not averaged)"))
            continue
        if "mpjpe_mm" not in data and "jitter_mm" not in data:
            data.update(_motion_metrics(d))
        data["_overrides"] = _overrides(d)
        if data.get("dropped_nonfinite"):       # data.nonfinite=drop: in the table, and said so
            problems.append((str(d), "in the table, but its data had NaN/Inf values left out: "
                             + ", ".join(f"{n} {k}" for k, n in data["dropped_nonfinite"].items())))
        runs.append(data)
    expected = expected_jobs(sweep_dir)
    if expected is not None and expected > len(run_dirs):
        problems.append((str(sweep_dir), f"{expected - len(run_dirs)} of {expected} jobs have no "
                                         "run directory (never started)"))
    problems += mixed_rows(runs)
    return Collected(runs, problems)


#: config keys that do not make two runs of one row different (bookkeeping, output, seed)
SAME_RUN_KEYS = ("seed", "skip_complete", "resume_on_change", "recording", "motion", "threads", "hydra",
                 "oracle")


def _flat(config, prefix: str = "") -> dict:
    if isinstance(config, dict):
        out = {}
        for k, v in config.items():
            out.update(_flat(v, f"{prefix}{k}."))
        return out
    return {prefix.rstrip("."): config}


def _seed(run: dict):
    """The seed a run ran with (metrics.json, its config, else its seed= override; None)."""
    if "seed" in run:
        return run["seed"]
    if "seed" in (run.get("config") or {}):
        return run["config"]["seed"]
    kv = dict(o.split("=", 1) for o in run.get("_overrides", []) if "=" in o)
    return kv.get("seed")


def seed_count(rs: list[dict]) -> int:
    """Seeds of a row: distinct seeds of its runs (a run of unknown seed counts as one)."""
    seeds = [_seed(r) for r in rs]
    return len({str(s) for s in seeds if s is not None}) + sum(s is None for s in seeds)


def mixed_rows(runs: list[dict]) -> list[tuple[str, str]]:
    """Rows of the table whose runs are not seeds of one configuration: configs that differ
    in keys other than the seed and bookkeeping, or one seed twice."""
    problems = []
    for key, rs in group_runs(runs).items():
        label = " ".join(str(k) for k in key)
        seeds = [_seed(r) for r in rs]
        repeated = sorted({str(s) for s in seeds if s is not None and seeds.count(s) > 1})
        if repeated:
            problems.append((label, f"this row holds seed(s) {', '.join(repeated)} more than once: "
                                    "the sweep folder mixes configs (counted once each)"))
        flats = [_flat({k: v for k, v in r["config"].items() if k not in SAME_RUN_KEYS})
                 for r in rs if isinstance(r.get("config"), dict)]
        flats = [{k: v for k, v in f.items() if k.rsplit(".", 1)[-1] != "seed"} for f in flats]  # data.seed
        differ = sorted({k for f in flats for k in set(f) | set(flats[0]) if f.get(k) != flats[0].get(k)})
        if differ:
            problems.append((label, f"this row's runs have different configs (differ in: "
                                    f"{', '.join(differ[:6])}{' ...' if len(differ) > 6 else ''}): "
                                    "the sweep folder mixes configs"))
    return problems


IGNORED_OVERRIDES = ("seed", "hydra.", "skip_complete", "recording.")


def varying_overrides(runs: list[dict]) -> list[str]:
    """Override keys whose value differs between runs (seeds and bookkeeping excluded)."""
    values: dict[str, set] = defaultdict(set)
    for r in runs:
        kv = dict(o.split("=", 1) for o in r.get("_overrides", []) if "=" in o)
        for k in {k for rr in runs for o in rr.get("_overrides", []) if "=" in o
                  for k in [o.split("=", 1)[0]]}:
            values[k].add(kv.get(k))
    return sorted(k for k, v in values.items() if len(v) > 1
                  and not any(k == p or k.startswith(p) for p in IGNORED_OVERRIDES))


def _value(run: dict, key: str, kv: dict) -> str:
    """The value of an override key in the config that ran (metrics.json's "config"), else the
    override as written (a refused re-run may have left another value in overrides.yaml)."""
    flat = _flat(run.get("config")) if isinstance(run.get("config"), dict) else {}
    if key.lstrip("+~") in flat:
        v = flat[key.lstrip("+~")]
        return "null" if v is None else str(v).lower() if isinstance(v, bool) else str(v)
    return kv.get(key, "-")


def _key(run: dict, varying: list[str]) -> tuple:
    P, L = run.get("particles", 0), run.get("layers", 0)
    budget = f"{P}x{L}" if P else "-"
    kv = dict(o.split("=", 1) for o in run.get("_overrides", []) if "=" in o)
    extra = " ".join(f"{k}={_value(run, k, kv)}" for k in varying if k not in ("tracker", "data"))
    return (run["tracker"], run.get("data", ""), extra or "-", budget,
            "+".join(run.get("energy_terms", [])) or "-")


def group_runs(runs: list[dict]) -> dict[tuple, list[dict]]:
    """Runs grouped as the table's rows, in its order: (tracker, data, varying overrides
    "k=v k2=v2" or "-", particles x layers "25x10" or "-", energy terms "a+b" or "-") -> runs."""
    varying = varying_overrides(runs)
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in runs:
        groups[_key(r, varying)].append(r)
    return dict(sorted(groups.items()))


def _mean_std(values: list[float]) -> tuple[float, float | None]:
    a = np.asarray(values, float)
    return float(a.mean()), (float(a.std(ddof=1)) if len(a) > 1 else None)


def table_rows(runs: list[dict]) -> list[dict]:
    """One row per tracker, data, varying overrides (a parameter sweep: one row per value),
    budget and energy terms; means (± std over seeds when there are several)."""
    rows = []
    for (tracker, data, overrides, budget, terms), rs in group_runs(runs).items():
        row = {"tracker": tracker, "data": data, "overrides": overrides, "particles_x_layers": budget,
               "energy_terms": terms, "seeds": seed_count(rs),
               "sec_per_frame": float(np.mean([r["sec_per_frame"] for r in rs])),
               "energy_evals_per_frame": float(np.mean([r.get("energy_evals_per_frame", 0) for r in rs]))}
        if all("mpjpe_mm" in r for r in rs):
            row["mpjpe_mean_mm"], row["mpjpe_std_mm"] = _mean_std([r["mpjpe_mm"] for r in rs])
        for extra in ("pcp", "mmta", "mmtp_mm", "apf_calls_per_frame", *(k for k, _ in NO_GT_METRICS)):
            if all(extra in r for r in rs):
                row[extra] = float(np.mean([r[extra] for r in rs]))
        _mismatch_cells(row, rs)
        rows.append(row)
    return rows


# columns of data our model did not generate (metrics.json "mismatch" / "oracle", see
# mocap.eval.mismatch): key -> (label, value of one run or None)
MISMATCH_METRICS = {
    "offset_removed_mm": ("offset-removed (mm)", lambda r: r.get("mismatch", {}).get("offset_removed_mm")),
    "limbs_mm": ("limb joints (mm)", lambda r: r.get("mismatch", {}).get("limbs_mm")),
    "oracle_mm": ("oracle (mm)", lambda r: r.get("oracle", {}).get("raw_mm")),
    "x_oracle": ("× oracle", lambda r: (r["mpjpe_mm"] / r["oracle"]["raw_mm"]
                                        if "oracle" in r and r["oracle"].get("raw_mm") else None)),
    "frames_lost": ("frames lost", lambda r: r.get("frames_lost")),
    "init_mm": ("init error (mm)", lambda r: (r["per_frame_mm"][0] if "init" in r and r.get("per_frame_mm")
                                              else None)),
    "init_seconds": ("init (s)", lambda r: r.get("init", {}).get("seconds")),
}


# columns of data with a true surface (metrics.json, mocap.eval.surface): key -> (label, value of
# one run or None, decimals)
SURFACE_METRICS = {
    "surface_to_mesh_mm": ("surface → tracked (mm)", lambda r: r.get("surface_to_mesh_mm"), 1),
    "surface_to_mesh_p90_mm": ("surface → tracked p90 (mm)", lambda r: r.get("surface_to_mesh_p90_mm"), 1),
    "mesh_to_surface_mm": ("tracked → surface (mm)", lambda r: r.get("mesh_to_surface_mm"), 1),
    "surface_oracle_mm": ("surface oracle (mm)", lambda r: r.get("surface_oracle_mm"), 1),
    "x_surface_oracle": ("× surface oracle", lambda r: (r["surface_to_mesh_mm"] / r["surface_oracle_mm"]
                                                       if r.get("surface_oracle_mm") else None), 2),
    "silhouette_iou": ("silhouette IoU", lambda r: r.get("silhouette_iou"), 3),
}


def _perturbation(r: dict) -> dict | None:
    return (r.get("recovery") or {}).get("perturbation")


# columns of recovery runs (mocap recovery: metrics.json "recovery", mocap.eval.recovery): key ->
# (label, value of one run or None, decimals)
RECOVERY_METRICS = {
    "recovered": ("recovered", lambda r: (None if _perturbation(r) is None else
                                          float(_perturbation(r)["frames_to_recover"] is not None)), 2),
    "error_at_failure_mm": ("error at the failure (mm)",
                            lambda r: (_perturbation(r) or {}).get("error_at_mm"), 1),
}


def _mismatch_cells(row: dict, rs: list[dict]) -> None:
    getters = [*((k, get) for k, (_, get) in MISMATCH_METRICS.items()),
               *((k, get) for k, (_, get, _) in SURFACE_METRICS.items()),
               *((k, get) for k, (_, get, _) in RECOVERY_METRICS.items())]
    for key, get in getters:
        vals = [get(r) for r in rs]
        if vals and all(v is not None for v in vals):
            row[key], row[key + "_std"] = _mean_std(vals)


def _pm(mean: float, std: float | None, decimals: int = 1) -> str:
    return f"{mean:.{decimals}f}" if std is None else f"{mean:.{decimals}f} ± {std:.{decimals}f}"


def markdown(rows: list[dict], problems: list[tuple[str, str]], title: str) -> str:
    extras = [(k, label) for k, label in (("pcp", "PCP"), ("apf_calls_per_frame", "APF calls / frame"),
                                          ("mmta", "MMTA"), ("mmtp_mm", "MMTP (mm)"), *NO_GT_METRICS)
              if any(k in r for r in rows)]
    mism = [(k, label, 1) for k, (label, _) in MISMATCH_METRICS.items() if any(k in r for r in rows)]
    mism += [(k, label, d) for k, (label, _, d) in SURFACE_METRICS.items() if any(k in r for r in rows)]
    mism += [(k, label, d) for k, (label, _, d) in RECOVERY_METRICS.items() if any(k in r for r in rows)]
    show_over = any(r.get("overrides", "-") != "-" for r in rows)
    head = ["tracker", "data", *(["overrides"] if show_over else []), "particles x layers", "energy terms",
            "seeds", "joint error (mm)", "s / frame", "energy evals / frame", *(label for _, label in extras),
            *(label for _, label, _ in mism)]
    out = [f"# {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        err = _pm(r["mpjpe_mean_mm"], r["mpjpe_std_mm"]) if "mpjpe_mean_mm" in r else "-"
        cells = [r["tracker"], r["data"], *([r["overrides"]] if show_over else []), r["particles_x_layers"],
                 r["energy_terms"], str(r["seeds"]), err, f"{r['sec_per_frame']:.2f}",
                 f"{r['energy_evals_per_frame']:.0f}",
                 *(f"{r[k]:.2f}" if k in r else "-" for k, _ in extras),
                 *(_pm(r[k], r[k + "_std"], d) if k in r else "-" for k, _, d in mism)]
        out.append("| " + " | ".join(cells) + " |")
    if problems:
        out += ["", "## Runs that failed or are missing", ""]
        out += [f"- `{d}`: {why}" for d, why in problems]
    return "\n".join(out) + "\n"


def write_csv(rows: list[dict], path: Path) -> None:
    keys = list(dict.fromkeys(itertools.chain.from_iterable(r.keys() for r in rows)))
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)

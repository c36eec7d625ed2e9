"""Ablation tables from a sweep's run directories (their metrics.json, never logs)."""

from __future__ import annotations

import csv
import itertools
import json
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml


@dataclass(frozen=True)
class Collected:
    runs: list[dict]                  # metrics.json contents, with "_dir"
    problems: list[tuple[str, str]]   # (run dir or job, what is wrong)


def expected_jobs(sweep_dir: Path) -> int | None:
    """Number of jobs a Hydra sweep launched, from its multirun.yaml (simple comma sweeps)."""
    path = sweep_dir / "multirun.yaml"
    if not path.is_file():
        return None
    cfg = yaml.safe_load(path.read_text())
    overrides = ((cfg or {}).get("hydra", {}).get("overrides", {}) or {}).get("task", []) or []
    sizes = [len(str(o).split("=", 1)[1].split(",")) for o in overrides if "=" in str(o)]
    return int(np.prod(sizes)) if sizes else 1


def collect(sweep_dir: str | Path) -> Collected:
    """Every run under ``sweep_dir`` (a directory holding .hydra/); runs without a readable
    metrics.json are reported as problems, never dropped silently."""
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
            for key in ("tracker", "mpjpe_mm", "sec_per_frame"):
                if key not in data:
                    raise KeyError(key)
            runs.append(data)
        except (json.JSONDecodeError, KeyError) as exc:
            problems.append((str(d), f"unreadable metrics.json ({exc!r})"))
    expected = expected_jobs(sweep_dir)
    if expected is not None and expected > len(run_dirs):
        problems.append((str(sweep_dir), f"{expected - len(run_dirs)} of {expected} jobs have no "
                                         "run directory (never started)"))
    return Collected(runs, problems)


def _key(run: dict) -> tuple:
    P, L = run.get("particles", 0), run.get("layers", 0)
    budget = f"{P}x{L}" if P else "-"
    return (run["tracker"], run.get("data", ""), budget, "+".join(run.get("energy_terms", [])) or "-")


def table_rows(runs: list[dict]) -> list[dict]:
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in runs:
        groups[_key(r)].append(r)
    rows = []
    for (tracker, data, budget, terms), rs in sorted(groups.items()):
        err = np.array([r["mpjpe_mm"] for r in rs])
        row = {"tracker": tracker, "data": data, "particles_x_layers": budget, "energy_terms": terms,
               "seeds": len(rs), "mpjpe_mean_mm": float(err.mean()),
               "mpjpe_std_mm": float(err.std(ddof=1)) if len(rs) > 1 else 0.0,
               "sec_per_frame": float(np.mean([r["sec_per_frame"] for r in rs])),
               "energy_evals_per_frame": float(np.mean([r.get("energy_evals_per_frame", 0) for r in rs]))}
        for extra in ("mmta", "mmtp_mm", "apf_calls_per_frame"):
            if all(extra in r for r in rs):
                row[extra] = float(np.mean([r[extra] for r in rs]))
        rows.append(row)
    return rows


def markdown(rows: list[dict], problems: list[tuple[str, str]], title: str) -> str:
    extras = [(k, label) for k, label in (("apf_calls_per_frame", "APF calls / frame"),
                                          ("mmta", "MMTA"), ("mmtp_mm", "MMTP (mm)"))
              if any(k in r for r in rows)]
    out = [f"# {title}", "",
           "| tracker | data | particles x layers | energy terms | seeds | joint error (mm) "
           "| s / frame | energy evals / frame |" + "".join(f" {label} |" for _, label in extras),
           "|---|---|---|---|---|---|---|---|" + "---|" * len(extras)]
    for r in rows:
        cells = "".join(f" {r[k]:.2f} |" if k in r else " - |" for k, _ in extras)
        out.append(f"| {r['tracker']} | {r['data']} | {r['particles_x_layers']} | {r['energy_terms']} | "
                   f"{r['seeds']} | {r['mpjpe_mean_mm']:.1f} ± {r['mpjpe_std_mm']:.1f} | "
                   f"{r['sec_per_frame']:.2f} | {r['energy_evals_per_frame']:.0f} |{cells}")
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


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for r in rows:
        ax.errorbar(r["sec_per_frame"], r["mpjpe_mean_mm"], yerr=r["mpjpe_std_mm"], fmt="o", capsize=3)
        ax.annotate(f"{r['tracker']} {r['particles_x_layers']}\n{r['data']}",
                    (r["sec_per_frame"], r["mpjpe_mean_mm"]), fontsize=7,
                    xytext=(4, 4), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("time per frame (s, log)")
    ax.set_ylabel("mean joint error (mm)")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)

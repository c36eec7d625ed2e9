"""Question: how does the marker tracker's error grow with missed detections, false
positives, pixel noise and fewer annealing layers (Canton-Ferrer et al. 2010, Fig. 6)?

The corruption study of Canton-Ferrer et al. 2010 (Sec. 4.1, Fig. 6) from sweep folders.

    mocap track --multirun +sweep=marker_miss hydra.sweep.dir=multirun/marker_miss
    (... marker_fp, marker_noise, marker_layers)
    python experiments/marker_corruption.py multirun/marker_miss multirun/marker_fp \
        multirun/marker_noise multirun/marker_layers [--out DIR]

Each sweep varies one factor (conf/sweep/marker_*.yaml); the factor is read from the runs'
configs (the one of miss rate, false-positive rate, noise and layers that takes several
values). Writes marker_corruption.md / .csv (mean joint error, MMTA, MMTP over seeds per
value) and marker_corruption.png (error against each factor: the paper's Figure 6).
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from mocap.run_folder.sweep import collect

FACTORS = {
    "miss rate": lambda c: round(1.0 - float(c["data"]["detections"]["detection_rate"]), 6),
    "false-positive rate": lambda c: float(c["data"]["detections"]["false_positive_rate"]),
    "noise sigma (px)": lambda c: float(c["data"]["detections"]["noise_px"]),
    "annealing layers": lambda c: int(c["tracker"]["layers"]),
}


def factor_of(runs: list[dict]) -> str:
    varying = [name for name, get in FACTORS.items() if len({get(r["config"]) for r in runs}) > 1]
    if len(varying) != 1:
        raise ValueError(f"expected one varying factor, found {varying or 'none'}")
    return varying[0]


def summarise(runs: list[dict], factor: str) -> list[dict]:
    groups: dict[float, list[dict]] = defaultdict(list)
    for r in runs:
        groups[FACTORS[factor](r["config"])].append(r)
    rows = []
    for value, rs in sorted(groups.items()):
        err = np.array([r["mpjpe_mm"] for r in rs])
        rows.append({"factor": factor, "value": value, "seeds": len(rs), "mpjpe_mm": float(err.mean()),
                     "mpjpe_std_mm": float(err.std(ddof=1)) if len(rs) > 1 else 0.0,
                     "mmta": float(np.mean([r.get("mmta", np.nan) for r in rs])),
                     "mmtp_mm": float(np.mean([r.get("mmtp_mm", np.nan) for r in rs])),
                     "sec_per_frame": float(np.mean([r["sec_per_frame"] for r in rs]))})
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep_dirs", type=Path, nargs="+")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: the first sweep's parent)")
    args = p.parse_args(argv)
    rows, problems = [], []
    for d in args.sweep_dirs:
        got = collect(d)
        problems += got.problems
        runs = [r for r in got.runs if "mpjpe_mm" in r]      # collect() also keeps runs without ground truth
        problems += [(r["_dir"], "no ground truth (no mpjpe_mm)") for r in got.runs if "mpjpe_mm" not in r]
        if runs:
            rows += summarise(runs, factor_of(runs))
    if not rows:
        print("no runs found", file=sys.stderr)
        return 1
    out = args.out or args.sweep_dirs[0].parent
    out.mkdir(parents=True, exist_ok=True)
    md = ["# Corruption study (Canton-Ferrer et al. 2010, Fig. 6): marker_apf on synthetic walking", "",
          "| factor | value | seeds | joint error (mm) | MMTA | MMTP (mm) | s / frame |",
          "|---|---|---|---|---|---|---|"]
    md += [f"| {r['factor']} | {r['value']:g} | {r['seeds']} | {r['mpjpe_mm']:.1f} ± {r['mpjpe_std_mm']:.1f} "
           f"| {r['mmta']:.3f} | {r['mmtp_mm']:.1f} | {r['sec_per_frame']:.3f} |" for r in rows]
    if problems:
        md += ["", "## Runs that failed or are missing", ""] + [f"- `{d}`: {why}" for d, why in problems]
    (out / "marker_corruption.md").write_text("\n".join(md) + "\n")
    with (out / "marker_corruption.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, out / "marker_corruption.png")
    print("\n".join(md))
    print(f"wrote {out}/marker_corruption.md, .csv, .png")
    return 0


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    factors = list(dict.fromkeys(r["factor"] for r in rows))
    fig, axes = plt.subplots(1, len(factors), figsize=(3.2 * len(factors), 3.0), dpi=100, squeeze=False)
    for ax, f in zip(axes[0], factors, strict=True):
        rs = [r for r in rows if r["factor"] == f]
        ax.errorbar([r["value"] for r in rs], [r["mpjpe_mm"] for r in rs],
                    yerr=[r["mpjpe_std_mm"] for r in rs], fmt="o-", capsize=3)
        ax.set_xlabel(f)
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("mean joint error (mm)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())

"""``mocap ablate``: collect a sweep's metrics.json files into ablation.md, ablation.csv,
ablation.png (error against time per frame, per dataset, the oracle as a line) and
ablation_frames.png (each run's error per frame).

    mocap ablate multirun/<sweep dir> [--out DIR] [--title TEXT]

Groups runs by tracker, data, the overrides that vary in the sweep (a parameter sweep makes
one row per value), particles x layers and energy terms; reports the joint error over seeds
(mean ± std; a single seed shows the value alone), PCP, time per frame and energy evaluations
per frame. Runs without ground truth get their own columns (reprojection, bone-length
stability, jitter; from motion.npz when metrics.json lacks them). Lists the runs that failed,
are missing, are not complete (no valid manifest.json: never a row, unless
--accept-unverified) or have a NaN joint error (never averaged in), and rows whose runs mix
configs.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mocap_cli.errors import ArgumentParser


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap ablate", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep_dir", type=Path)
    p.add_argument("--out", type=Path, default=None, help="output folder (default: the sweep dir)")
    p.add_argument("--title", default="Ablation")
    p.add_argument("--strict", action="store_true", help="exit 1 when any run failed or is missing")
    p.add_argument("--accept-unverified", action="store_true",
                   help="keep runs without a valid manifest.json (written before manifests) in the table, "
                        "each listed as UNVERIFIED")
    args = p.parse_args(argv)
    if not args.sweep_dir.is_dir():                 # before the numeric stack is imported
        raise FileNotFoundError(f"sweep directory not found: {args.sweep_dir}")
    from mocap.run_folder.sweep import collect, markdown, table_rows, write_csv
    from mocap.run_folder.sweep_plots import plot

    got = collect(args.sweep_dir, require_manifest=not args.accept_unverified)
    out = args.out or args.sweep_dir
    out.mkdir(parents=True, exist_ok=True)
    rows = table_rows(got.runs)
    md = markdown(rows, got.problems, args.title)
    (out / "ablation.md").write_text(md)
    write_csv(rows, out / "ablation.csv")
    if rows:
        plot(rows, out / "ablation.png", runs=got.runs)
    print(md)
    print(f"wrote {out / 'ablation.md'}, ablation.csv"
          + (", ablation.png (error against time), ablation_frames.png (error per frame)" if rows else ""))
    if not rows or (args.strict and got.problems):
        return 1
    return 0


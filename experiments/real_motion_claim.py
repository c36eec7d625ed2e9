"""The paper's question on real motion: does a learned pose prior let an APF with 25 particles x
10 layers do the work of 100 x 15? Reads a finished sweep of the real-motion benchmark (every
tracker, every sequence, several seeds) and prints the table of docs/results/real_motion.md:
per tracker and sequence the joint error (mean over seeds) and its ratio to the oracle (our body
fitted to the true joints), frames lost and time per frame; then the ratios the issue asks for.

    mocap track --multirun +sweep=real_motion_test hydra.sweep.dir=multirun/real_motion_test
    python experiments/real_motion_claim.py multirun/real_motion_test [--out table.md]

Runs without a manifest.json (written by code before issue 27) are refused unless
``--accept-unverified`` is given; they are then counted under the table.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from mocap.run_folder.sweep import collect

#: the trackers of the claim in the order of the table (others found are appended)
ORDER = ("local", "hybrid", "hybrid_prior", "hybrid_prior_real", "hybrid_kp", "apf_25x10", "apf_prior",
         "apf_prior_real", "apf", "marker_apf")
LABELS = {"local": "local", "hybrid": "hybrid (no prior)", "hybrid_prior": "hybrid + procedural prior",
          "hybrid_prior_real": "hybrid + real prior", "hybrid_kp": "two-cue hybrid (+ 2D detections)",
          "apf_25x10": "APF 25x10, no prior",
          "apf_prior": "APF 25x10 + procedural prior", "apf_prior_real": "APF 25x10 + real prior",
          "apf": "APF 100x15, no prior", "marker_apf": "marker tracker (2D detections only)"}


def gather(sweep: Path, accept_unverified: bool = False) -> tuple[dict, dict, list]:
    """-> cells {(tracker, data): {mm: [...], lost: [...], spf: [...], seeds: [...]}},
    oracle {data: mm}, problems."""
    got = collect(sweep, require_manifest=not accept_unverified)
    cells: dict = defaultdict(lambda: defaultdict(list))
    oracle: dict = {}
    for r in got.runs:
        c = cells[(r["tracker"], r["data"])]
        c["mm"].append(float(r["mpjpe_mm"]))
        c["lost"].append(int(r.get("frames_lost", 0)))
        c["spf"].append(float(r["sec_per_frame"]))
        c["seeds"].append(int(r["seed"]))
        c["evals"].append(float(r.get("energy_evals_per_frame", 0.0)))
        if r.get("oracle"):
            oracle[r["data"]] = float(r["oracle"]["raw_mm"])
    return cells, oracle, got.problems


def per_data(cells: dict, tracker: str, data: list[str], key: str) -> dict[str, float]:
    """{data: mean over seeds of ``key``} for one tracker."""
    return {d: float(np.mean(cells[(tracker, d)][key])) for d in data if (tracker, d) in cells}


def table(cells: dict, oracle: dict) -> tuple[list[str], dict]:
    data = sorted({d for _, d in cells})
    trackers = [t for t in ORDER if any((t, d) in cells for d in data)]
    trackers += sorted({t for t, _ in cells} - set(trackers))
    short = [d.removeprefix("real_") for d in data]
    lines = ["| tracker | " + " | ".join(short) + " | median × oracle | max × oracle | frames lost | "
             "s / frame | seeds |",
             "|---" * (len(data) + 6) + "|",
             "| oracle | " + " | ".join(f"{oracle.get(d, float('nan')):.1f}" for d in data)
             + " | 1.0 | 1.0 | - | - | - |"]
    summary = {}
    for t in trackers:
        ratios, cols, lost, spf, seeds, evals = [], [], 0, [], [], []
        for d in data:
            c = cells.get((t, d))
            if not c:
                cols.append("-")
                continue
            mm = float(np.mean(c["mm"]))
            sd = float(np.std(c["mm"]))
            ratio = mm / oracle[d]
            ratios.append(ratio)
            lost += sum(c["lost"])
            spf += c["spf"]
            evals += c["evals"]
            seeds.append(len(set(c["seeds"])))
            cols.append(f"{mm:.1f} ± {sd:.1f} ({ratio:.1f}×)")
        summary[t] = {"median_ratio": float(np.median(ratios)), "max_ratio": float(np.max(ratios)),
                      "lost": lost, "spf": float(np.mean(spf)), "evals": float(np.mean(evals)),
                      "spf_by_data": per_data(cells, t, data, "spf"), "mm": per_data(cells, t, data, "mm")}
        n_seeds = f"{min(seeds)}" if min(seeds) == max(seeds) else f"{min(seeds)}–{max(seeds)}"
        lines.append(f"| {LABELS.get(t, t)} | " + " | ".join(cols)
                     + f" | {summary[t]['median_ratio']:.1f} | {summary[t]['max_ratio']:.1f} | {lost} | "
                     f"{summary[t]['spf']:.2f} | {n_seeds} |")
    return lines, summary


def claim_lines(summary: dict) -> list[str]:
    out = []
    for t in ("hybrid", "hybrid_kp", "marker_apf"):
        if t in summary:
            h = summary[t]
            out.append(f"- {LABELS[t]}: {h['median_ratio']:.1f}× the oracle on the median sequence (target "
                       f"≤ 2.0), {h['max_ratio']:.1f}× on the worst (target ≤ 3.0), {h['lost']} frames lost.")
    if "apf" in summary:
        ref = summary["apf"]
        for t in ("apf_prior_real", "apf_prior", "apf_25x10"):
            if t not in summary:
                continue
            common = sorted(set(ref["mm"]) & set(summary[t]["mm"]))
            r = [summary[t]["mm"][d] / ref["mm"][d] for d in common]
            time = [summary[t]["spf_by_data"][d] / ref["spf_by_data"][d] for d in common]
            out.append(f"- {LABELS[t]}: error {np.median(r):.2f}× APF 100x15's on the median sequence "
                       f"({min(r):.2f}–{max(r):.2f}; target ≤ 1.2); time per frame {np.median(time):.2f}× "
                       f"on the median sequence, energy evaluations "
                       f"{summary[t]['evals'] / ref['evals']:.2f}× (target ≤ 0.2).")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", type=Path)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--accept-unverified", action="store_true",
                   help="keep runs without a manifest.json (code before issue 27) and count them")
    args = p.parse_args(argv)
    cells, oracle, problems = gather(args.sweep, args.accept_unverified)
    if not cells:
        print(f"{args.sweep}: no finished runs", file=sys.stderr)
        return 1
    lines, summary = table(cells, oracle)
    lines += ["", *claim_lines(summary)]
    unverified = [a for a, b in problems if b.startswith("UNVERIFIED")]
    problems = [(a, b) for a, b in problems if not b.startswith("UNVERIFIED")]
    if unverified:
        lines += ["", f"{len(unverified)} runs without a manifest.json (written before manifests "
                      "existed) are in the table (--accept-unverified)."]
    if problems:
        lines += ["", "Runs missing or failed:", *[f"- `{a}`: {b}" for a, b in problems]]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

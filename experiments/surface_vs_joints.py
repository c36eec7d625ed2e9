"""Do the joints and the body's surface tell the same story? Reads finished runs on data with a
true surface (the real-motion benchmark's gt.npz ``surface``) and prints, per tracker and sequence,
the joint error and its ratio to the joint oracle beside the surface error both ways (true surface ->
tracked mesh, tracked mesh -> true surface), its ratio to the surface oracle (our body fitted to the
true surface) and the silhouette overlap; then the figures of docs/results/surface.md: the two-cue
hybrid's surface error against the marker tracker's per sequence, and each tracker's median and worst
ratio to the oracles.

    mocap track --multirun +sweep=real_motion_test tracker=hybrid_kp,marker_apf,hybrid seed=0 \\
        hydra.sweep.dir=multirun/surface_test
    python -m experiments.surface_vs_joints multirun/surface_test

Runs scored before the surface metric existed are re-scored with ``mocap rescore DIR`` first.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

ORDER = ("hybrid_kp", "marker_apf", "hybrid", "hybrid_100x15", "hybrid_prior", "hybrid_prior_real", "local")


def read_runs(folder: Path) -> dict[tuple[str, str], list[dict]]:
    """(tracker, data) -> metrics of the complete runs (a manifest.json) under ``folder``."""
    runs: dict = defaultdict(list)
    for manifest in sorted(folder.rglob("manifest.json")):
        m = json.loads((manifest.parent / "metrics.json").read_text())
        runs[(m["tracker"], m["data"])].append(m)
    return runs


def mean(ms: list[dict], get) -> float | None:
    vals = [get(m) for m in ms]
    return float(np.mean(vals)) if vals and all(v is not None for v in vals) else None


def cells(ms: list[dict]) -> dict:
    return {
        "joints": mean(ms, lambda m: m.get("mpjpe_mm")),
        "x_oracle": mean(ms, lambda m: m["mpjpe_mm"] / m["oracle"]["raw_mm"] if "oracle" in m else None),
        "surface": mean(ms, lambda m: m.get("surface_to_mesh_mm")),
        "back": mean(ms, lambda m: m.get("mesh_to_surface_mm")),
        "x_surface_oracle": mean(ms, lambda m: (m["surface_to_mesh_mm"] / m["surface_oracle_mm"]
                                                if m.get("surface_oracle_mm") else None)),
        "iou": mean(ms, lambda m: m.get("silhouette_iou")),
        "lost": sum(m.get("frames_lost", 0) for m in ms),
        "seeds": len(ms),
    }


def fmt(v: float | None, digits: int = 1) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def report(folder: Path) -> str:
    runs = read_runs(folder)
    trackers = sorted({t for t, _ in runs}, key=lambda t: (ORDER.index(t) if t in ORDER else 99, t))
    seqs = sorted({d for _, d in runs})
    table = {(t, d): cells(ms) for (t, d), ms in runs.items()}
    lines = ["| tracker | sequence | seeds | joints (mm) | x oracle | true -> tracked surface (mm) | "
             "tracked -> true (mm) | x surface oracle | IoU | frames lost |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for t in trackers:
        for d in seqs:
            c = table.get((t, d))
            if c is None:
                continue
            lines.append(f"| {t} | {d.removeprefix('real_')} | {c['seeds']} | {fmt(c['joints'])} | "
                         f"{fmt(c['x_oracle'], 2)} | {fmt(c['surface'])} | {fmt(c['back'])} | "
                         f"{fmt(c['x_surface_oracle'], 2)} | {fmt(c['iou'], 3)} | {c['lost']} |")
    lines += ["", "| tracker | joints x oracle (median, worst) | surface x surface oracle (median, worst) | "
              "frames lost |", "|---|---|---|---|"]
    for t in trackers:
        jo = [table[(t, d)]["x_oracle"] for d in seqs if (t, d) in table and table[(t, d)]["x_oracle"]]
        so = [table[(t, d)]["x_surface_oracle"] for d in seqs
              if (t, d) in table and table[(t, d)]["x_surface_oracle"]]
        lost = sum(table[(t, d)]["lost"] for d in seqs if (t, d) in table)
        lines.append(f"| {t} | " + (f"{np.median(jo):.2f}, {max(jo):.2f}" if jo else "-") + " | "
                     + (f"{np.median(so):.2f}, {max(so):.2f}" if so else "-") + f" | {lost} |")
    pairs = [(d, table[("hybrid_kp", d)]["surface"], table[("marker_apf", d)]["surface"]) for d in seqs
             if ("hybrid_kp", d) in table and ("marker_apf", d) in table
             and table[("hybrid_kp", d)]["surface"] and table[("marker_apf", d)]["surface"]]
    if pairs:
        lines += ["", "Two-cue hybrid's surface error / the marker tracker's, per sequence: "
                  + ", ".join(f"{d.removeprefix('real_')} {a / b:.2f}" for d, a, b in pairs)]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, help="a folder of finished runs (searched recursively)")
    print(report(ap.parse_args(argv).runs))


if __name__ == "__main__":
    main()

"""Does the pose prior let the hybrid's limb-repair APF work with 25 particles x 10 layers where
100 x 15 are needed without it?  Zhang et al. (Sec. 4.2, Fig. 9) use the prior-constrained APF
only to repair what the local optimiser got wrong; this study asks the question there.

Reads two folders of finished runs (``conf/sweep/recovery_test.yaml``): clean runs and runs with a
perturbation injected (``mocap recovery``), pairs them by tracker (the hybrid and its APF's budget
and prior), sequence and seed from their metrics.json, and prints the tables of
docs/results/recovery.md:

- natural misalignments (clean runs): joint error, x the oracle, surface error where the run
  was scored on a surface, frames lost, APF calls, energy evaluations and time per frame;
- injected failures: a perturbation (mocap/trackers/failures.py) before frame ``at``; the
  injected run is compared with its clean twin frame by frame: recovered at the first frame
  from ``at`` on whose joint error is within ``max(tol_mm, tol_ratio x clean)`` of the clean
  run's, and stays so for ``hold`` frames; the excess error after the failure (injected - clean,
  mean over frames at..end), the same for the surface where both runs have it.

    python -m experiments.recovery_in_hybrid multirun/recovery_test_clean multirun/recovery_test
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

VARIANTS = {
    "hybrid_100x15": "APF 100x15, no prior",
    "hybrid": "APF 25x10, no prior",
    "hybrid_prior_real": "APF 25x10 + real prior",
    "hybrid_prior": "APF 25x10 + procedural prior",
}
def variant(m: dict) -> str:
    """The row of a run: its tracker's name, or hybrid_100x15 for the hybrid given that budget."""
    if m["tracker"] == "hybrid" and (m.get("particles"), m.get("layers")) == (100, 15):
        return "hybrid_100x15"
    return m["tracker"]


def read_runs(folder: Path) -> dict[tuple[str, str, int], dict]:
    """Complete runs (a manifest.json beside metrics.json) under ``folder``, keyed by (variant,
    sequence, seed)."""
    runs = {}
    for manifest in sorted(folder.rglob("manifest.json")):
        m = json.loads((manifest.parent / "metrics.json").read_text())
        runs[(variant(m), m["data"], int(m["seed"]))] = m
    return runs


def recovery(inj: list[float], clean: list[float], at: int, tol_mm: float, tol_ratio: float,
             hold: int) -> int | None:
    """Frames from ``at`` until the injected run is back within tolerance of its clean twin (and
    stays so ``hold`` frames, or to the end); None: not by the end."""
    inj, clean = np.asarray(inj), np.asarray(clean)
    ok = inj - clean <= np.maximum(tol_mm, tol_ratio * clean)
    for f in range(at, len(inj)):
        if ok[f:f + hold].all():
            return f - at
    return None


def surface(m: dict) -> float | None:
    s = m.get("surface") or {}
    v = s.get("surface_to_mesh_mm", m.get("surface_to_mesh_mm"))
    return None if v is None else float(v)


def tables(clean_dir: Path, injected_dir: Path, tol_mm: float, tol_ratio: float, hold: int) -> str:
    clean, inj = read_runs(clean_dir), read_runs(injected_dir)
    inj = {k: m for k, m in inj.items() if (m.get("recovery") or {}).get("perturbation")}
    lines = []
    natural = defaultdict(list)
    for (v, s, seed), m in clean.items():
        natural[v].append((s, seed, m))
    lines += ["### Natural misalignments (no injection)", "",
              "| APF inside the hybrid | runs | joint error (mm) | x oracle (median seq) | surface (mm) | "
              "frames lost | APF calls / frame | energy evals / frame | s / frame |",
              "|---|---|---|---|---|---|---|---|---|"]
    for v, label in VARIANTS.items():
        rs = natural.get(v, [])
        if not rs:
            continue
        by_seq = defaultdict(list)
        for s, _, m in rs:
            by_seq[s].append(m["mpjpe_mm"] / m["oracle"]["raw_mm"])
        ratio = float(np.median([np.mean(x) for x in by_seq.values()]))
        surf = [surface(m) for _, _, m in rs if surface(m) is not None]
        lines.append(
            f"| {label} | {len(rs)} | {np.mean([m['mpjpe_mm'] for *_, m in rs]):.1f} | {ratio:.2f} | "
            f"{np.mean(surf):.1f} |" if surf else
            f"| {label} | {len(rs)} | {np.mean([m['mpjpe_mm'] for *_, m in rs]):.1f} | {ratio:.2f} | - |")
        lines[-1] += (f" {sum(m['frames_lost'] for *_, m in rs)} | "
                      f"{np.mean([m.get('apf_calls_per_frame', 0) for *_, m in rs]):.2f} | "
                      f"{np.mean([m['energy_evals_per_frame'] for *_, m in rs]):.0f} | "
                      f"{np.mean([m['sec_per_frame'] for *_, m in rs]):.2f} |")
    seqs = sorted({s for (_, s, _) in clean})
    lines += ["", "Joint error per sequence (mm, mean over seeds; x the oracle in brackets):", "",
              "| APF inside the hybrid | " + " | ".join(s.removeprefix("real_") for s in seqs) + " |",
              "|---|" + "---|" * len(seqs)]
    for v, label in VARIANTS.items():
        cells = []
        for s in seqs:
            ms = [m for (vv, ss, _), m in clean.items() if vv == v and ss == s]
            ratio = np.mean([m["mpjpe_mm"] / m["oracle"]["raw_mm"] for m in ms]) if ms else 0.0
            cells.append(f"{np.mean([m['mpjpe_mm'] for m in ms]):.1f} ({ratio:.1f})" if ms else "-")
        if any(c != "-" for c in cells):
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += ["", "### Injected failures (perturbation before frame "
              f"{next(iter(inj.values()))['recovery']['perturbation']['at_frame'] if inj else '?'})", "",
              f"Recovered: the joint error back within max({tol_mm:g} mm, {tol_ratio:g} x) of the clean "
              f"twin's for {hold} frames.", "",
              "| APF inside the hybrid | pairs | recovered | frames to recover (median, max) | "
              "excess at the failure (mm) | excess after (mm, mean) | surface excess after (mm) | "
              "energy evals / frame | s / frame |",
              "|---|---|---|---|---|---|---|---|---|"]
    for v, label in VARIANTS.items():
        pairs = [(k, inj[k], clean[k]) for k in inj if k[0] == v and k in clean]
        if not pairs:
            continue
        rec, exc_at, exc_after, sexc = [], [], [], []
        for _, mi, mc in pairs:
            at = mi["recovery"]["perturbation"]["at_frame"]
            pi, pc = mi["per_frame_mm"], mc["per_frame_mm"]
            rec.append(recovery(pi, pc, at, tol_mm, tol_ratio, hold))
            exc_at.append(pi[at] - pc[at])
            exc_after.append(float(np.mean(np.subtract(pi[at:], pc[at:]))))
            if surface(mi) is not None and surface(mc) is not None:
                sexc.append(surface(mi) - surface(mc))
        done = [r for r in rec if r is not None]
        lines.append(
            f"| {label} | {len(pairs)} | {len(done)}/{len(rec)} | "
            + (f"{np.median(done):.0f}, {max(done)} | " if done else "- | ")
            + f"{np.mean(exc_at):.1f} | {np.mean(exc_after):.1f} | "
            + (f"{np.mean(sexc):.1f} | " if sexc else "- | ")
            + f"{np.mean([mi['energy_evals_per_frame'] for _, mi, _ in pairs]):.0f} | "
            f"{np.mean([mi['sec_per_frame'] for _, mi, _ in pairs]):.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clean", type=Path, help="folder of the clean runs")
    ap.add_argument("injected", type=Path, help="folder of the runs with a perturbation injected")
    ap.add_argument("--tol-mm", type=float, default=10.0)
    ap.add_argument("--tol-ratio", type=float, default=0.25)
    ap.add_argument("--hold", type=int, default=3)
    a = ap.parse_args(argv)
    print(tables(a.clean, a.injected, a.tol_mm, a.tol_ratio, a.hold))


if __name__ == "__main__":
    main()

"""The two-cue hybrid's figures of issue 34 item 4 from finished run folders, per sequence: joints
and their ratio to the joint oracle, the true surface -> tracked mesh error, its ratio to the
surface oracle and to the marker tracker's (from a reference folder's ``marker_apf`` runs), frames
lost; then the median and worst ratios against the issue's targets (joints <= 1.3x the oracle on the
median sequence and <= 1.8x on every one; surface <= 0.8x the marker tracker's on every sequence,
<= 1.5x the surface oracle on the median one). With ``--joints``, the worst joints per sequence and
the error of the first frames against the rest (where the error comes from).

    mocap track --multirun +sweep=real_motion_dev tracker=hybrid_kp,marker_apf seed=0 frames=40 \\
        hydra.launcher.n_jobs=1 hydra.sweep.dir=multirun/dev_base
    python -m experiments.accuracy_dev multirun/dev_base [multirun/dev_other ...] --marker multirun/dev_base
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

TRACKER = "hybrid_kp"


def read(folder: Path, tracker: str) -> dict[str, dict]:
    """data -> metrics of the complete runs of ``tracker`` (a manifest.json) under ``folder``."""
    out = {}
    for manifest in sorted(folder.rglob("manifest.json")):
        m = json.loads((manifest.parent / "metrics.json").read_text())
        if m["tracker"] == tracker:
            out[m["data"]] = m
    return out


def ratios(m: dict, marker: dict | None) -> dict:
    so = m.get("surface_oracle_mm")
    ms = marker.get("surface_to_mesh_mm") if marker else None
    surface = m["surface_to_mesh_mm"]
    return {"joints": m["mpjpe_mm"], "x_oracle": m["mpjpe_mm"] / m["oracle"]["raw_mm"], "surface": surface,
            "x_surface_oracle": surface / so if so else np.nan, "x_marker": surface / ms if ms else np.nan,
            "lost": m.get("frames_lost", 0)}


def table(folder: Path, marker: dict[str, dict], joints: bool) -> str:
    runs = read(folder, TRACKER)
    rows = {d: ratios(m, marker.get(d)) for d, m in runs.items()}
    lines = [f"## {folder}",
             "| sequence | joints mm | x oracle | surface mm | x surface oracle | x marker | lost |",
             "|---|---|---|---|---|---|---|"]
    for d, r in rows.items():
        lines.append(f"| {d.removeprefix('real_')} | {r['joints']:.1f} | {r['x_oracle']:.2f} | "
                     f"{r['surface']:.1f} | {r['x_surface_oracle']:.2f} | {r['x_marker']:.2f} | "
                     f"{r['lost']} |")
    if rows:
        jo = np.array([r["x_oracle"] for r in rows.values()])
        so = np.array([r["x_surface_oracle"] for r in rows.values()])
        xm = np.array([r["x_marker"] for r in rows.values()])
        lines.append(f"joints x oracle median {np.median(jo):.2f} (<= 1.3) worst {jo.max():.2f} (<= 1.8); "
                     f"surface x oracle median {np.nanmedian(so):.2f} (<= 1.5); "
                     f"x marker worst {np.nanmax(xm):.2f} (<= 0.8); "
                     f"mean joints {np.mean([r['joints'] for r in rows.values()]):.1f} mm; "
                     f"mean surface {np.mean([r['surface'] for r in rows.values()]):.1f} mm; "
                     f"lost {sum(r['lost'] for r in rows.values())}")
    if joints:
        for d, m in runs.items():
            pj = sorted(m["per_joint_mm"].items(), key=lambda kv: -kv[1])[:5]
            pf = np.asarray(m["per_frame_mm"], float)
            worst = ", ".join(f"{k} {v:.0f}" for k, v in pj)
            lines.append(f"  {d.removeprefix('real_')}: worst joints {worst}; "
                         f"frames 0-4 {pf[:5].mean():.1f}, 5-19 {pf[5:20].mean():.1f}, "
                         f"20- {pf[20:].mean():.1f}; "
                         f"oracle {m['oracle']['raw_mm']:.1f}, "
                         f"offset-removed {m['mismatch']['offset_removed_mm']:.1f} "
                         f"(oracle {m['oracle']['offset_removed_mm']:.1f})")
    return "\n".join(lines)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folders", nargs="+", type=Path)
    p.add_argument("--marker", type=Path, help="folder with the marker_apf runs (default: the first folder)")
    p.add_argument("--joints", action="store_true", help="worst joints and the error over the frames")
    a = p.parse_args(argv)
    marker = read(a.marker or a.folders[0], "marker_apf")
    print("\n\n".join(table(f, marker, a.joints) for f in a.folders))


if __name__ == "__main__":
    main()

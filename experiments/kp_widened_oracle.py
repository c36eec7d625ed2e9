"""The oracles with the tracker's own joint limits (issue 34 item 4): a tracker that tracks within
limits wider than the body's (``tracker.joint_limits=widened``) is compared with the oracles of the
body's limits in its metrics.json; this fits both oracles again (the joint oracle: our body fitted to
the true joints; the surface oracle: to the true surface, from the joint oracle's fit) on a body with
those limits, and prints every run's ratios against both, so the comparison stays honest (the
oracle is our body within its limits: wider limits lower it too).

    python -m experiments.kp_widened_oracle outputs/kp5_test [--limits widened] [--cache FILE]

The fits are kept in ``--cache`` (JSON, by data, frames and limits), fitted once each.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np


def fit_both(body, seq, frames: int) -> dict:
    """{'joints_mm': the joint oracle's raw error, 'surface_mm': the surface oracle's true -> fitted
    mean} of ``body`` (its own limits) on the first ``frames`` frames of ``seq``."""
    from mocap.eval.mismatch import fit_oracle
    from mocap.eval.run_metrics import ORACLE_METHOD
    from mocap.eval.surface_oracle import fit_surface_oracle

    gt = seq.gt
    valid = None if gt.joint_valid is None else gt.joint_valid[:frames]
    joint = fit_oracle(body, gt.joint_names, gt.joints[:frames], valid, gt.skeleton or None,
                       method=ORACLE_METHOD)
    surf = fit_surface_oracle(body, gt.surface[:frames], gt.surface_faces, joint.alpha, joint.chi)
    return {"joints_mm": float(joint.metrics["raw_mm"]),
            "surface_mm": float(surf.metrics["surface_to_mesh_mm"])}


def main(argv=None) -> None:
    from mocap.body import load_body
    from mocap.data.sources import folder_sequence
    from mocap.trackers.joint_limits import tracker_body

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folders", nargs="+", type=Path, help="folders holding finished runs (metrics.json); "
                   "each its own rows")
    p.add_argument("--limits", default="widened",
                   help="the tracker's joint_limits ('widened' or a JSON file)")
    p.add_argument("--cache", type=Path, default=Path("multirun/widened_oracles.json"))
    a = p.parse_args(argv)
    cache = json.loads(a.cache.read_text()) if a.cache.is_file() else {}
    body = load_body("paper22")
    wide = tracker_body(body, a.limits)
    rows = defaultdict(list)
    for folder in a.folders:
        for path in sorted(folder.rglob("metrics.json")):
            m = json.loads(path.read_text())
            if "oracle" not in m or "surface_oracle_mm" not in m:
                continue
            frames = int(m["config"]["frames"])
            key = f"{m['data']}|{frames}|{a.limits}"
            if key not in cache:
                seq = folder_sequence(body=body, path=m["config"]["data"]["path"], name=m["data"], seed=0)
                cache[key] = fit_both(wide, seq, frames)
                a.cache.parent.mkdir(parents=True, exist_ok=True)
                a.cache.write_text(json.dumps(cache, indent=1))
                print(f"{key}: {cache[key]} (the body's: {m['oracle']['raw_mm']:.2f}, "
                      f"{m['surface_oracle_mm']:.2f})", flush=True)
            w = cache[key]
            rows[(f"{m['tracker']} ({folder.name})", m["data"])].append(
                (m["mpjpe_mm"], m["mpjpe_mm"] / m["oracle"]["raw_mm"], m["mpjpe_mm"] / w["joints_mm"],
                 m["surface_to_mesh_mm"], m["surface_to_mesh_mm"] / m["surface_oracle_mm"],
                 m["surface_to_mesh_mm"] / w["surface_mm"], m.get("frames_lost", 0)))
    print("| tracker | sequence | runs | joints mm | x oracle (body's limits) | "
          "x oracle (tracker's limits) | surface mm | x surface oracle (body's) | "
          "x surface oracle (tracker's) | lost |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    by_tracker = defaultdict(list)
    for (tracker, data), rs in sorted(rows.items()):
        v = np.mean(np.array(rs, np.float64)[:, :6], axis=0)
        lost = sum(r[6] for r in rs)
        by_tracker[tracker].append(v)
        print(f"| {tracker} | {data.removeprefix('real_')} | {len(rs)} | {v[0]:.2f} | {v[1]:.2f} | "
              f"{v[2]:.2f} | {v[3]:.2f} | {v[4]:.2f} | {v[5]:.2f} | {lost} |")
    for tracker, vs in by_tracker.items():
        v = np.array(vs)
        print(f"{tracker}: median / worst x oracle, body's limits {np.median(v[:, 1]):.2f} / "
              f"{v[:, 1].max():.2f}, tracker's {np.median(v[:, 2]):.2f} / {v[:, 2].max():.2f}; "
              f"x surface oracle, body's "
              f"{np.median(v[:, 4]):.2f} / {v[:, 4].max():.2f}, tracker's {np.median(v[:, 5]):.2f} / "
              f"{v[:, 5].max():.2f}")


if __name__ == "__main__":
    main()

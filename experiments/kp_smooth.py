"""The two-cue hybrid's jitter (issue 34 item 4): what the offline zero-phase smoother of the finished
track (:mod:`mocap.trackers.smoothing`, ``tracker.smoothing.cutoff_hz``) does to finished runs.

The smoother acts only on the finished track (the tracker's ``final_tracks``), so a run with it on is
its run without it, smoothed: each finished run folder's ``motion.npz`` (poses and shapes per frame) is
smoothed at each cut-off and scored as the run's own metrics are (:func:`score`): joints, surface
(true -> tracked mean), frames lost, and the offset-removed error. The unsmoothed row re-scores the run
as it is and must equal its metrics.json (checked). ``--check RUN`` compares a run made with the
smoother on (``mocap track ... tracker.smoothing.cutoff_hz=C``) with its base run smoothed here.

    python -m experiments.kp_smooth multirun/kp4/base --cutoffs 2 3 4 6 8 [--order 4]
    python -m experiments.kp_smooth multirun/kp4/base --check multirun/kp4/s4/base
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def load_run(run: Path):
    """(metrics, body, seq, chis (F, D), alphas (F, K)) of a finished run folder."""
    from mocap.body import load_body
    from mocap.data.sources import folder_sequence

    m = json.loads((run / "metrics.json").read_text())
    body = load_body(m["config"]["body"]["name"])
    path = Path(m["config"]["data"]["path"])
    if not path.is_dir() and "data" in path.parts:          # a run made in another checkout: this one's data
        path = Path.cwd().joinpath(*path.parts[len(path.parts) - path.parts[::-1].index("data") - 1:])
    seq = folder_sequence(body=body, path=str(path), name=m["data"], seed=m["seed"])
    z = np.load(run / "motion.npz")
    return m, body, seq, np.asarray(z["chi"], np.float64), np.asarray(z["alpha"], np.float64)


def score(body, seq, chis, alphas, m: dict) -> dict:
    """The figures compared, as the run's metrics compute them (joints by name, frames lost, the
    offset-removed error; the surface true -> tracked mean); the oracles' from its metrics.json
    (the same ground truth and frames). The silhouette overlap is left out (slow, not compared)."""
    from mocap.eval.by_name import NameScorer
    from mocap.eval.estimates import per_shape
    from mocap.eval.mismatch import LOST_MM, mismatch_metrics
    from mocap.eval.surface import surface_metrics

    F = len(chis)
    scorer = NameScorer(body, seq.gt)
    points = scorer.points_by_shape(alphas, chis)
    s = scorer.score(points)
    valid = None if seq.gt.joint_valid is None else seq.gt.joint_valid[:F]
    mm = mismatch_metrics(points, seq.gt.joint_names, seq.gt.joints[:F], valid, seq.gt.skeleton or None)
    verts = per_shape(body, alphas, chis, lambda shaped, c: shaped.vertices(c)).astype(np.float64)
    surf = surface_metrics(seq.gt.surface[:F], verts, body.faces, seq.gt.surface_faces)
    return {"joints": s["mpjpe_mm"], "surface": surf["surface_to_mesh_mm"],
            "lost": int(np.sum(np.asarray(s["per_frame_mm"][1:]) > LOST_MM)),
            "removed": mm["offset_removed_mm"], "oracle": m["oracle"]["raw_mm"],
            "surface_oracle": m["surface_oracle_mm"]}


def sweep(run: Path, cutoffs: list[float], order: int) -> dict:
    """{cutoff (0: as tracked): score} of one run."""
    from mocap.trackers.smoothing import TrackSmoothing, smooth_poses

    m, body, seq, chis, alphas = load_run(run)
    out = {0.0: score(body, seq, chis, alphas, m)}
    for key, mine in (("mpjpe_mm", "joints"), ("surface_to_mesh_mm", "surface")):
        if not np.isclose(m[key], out[0.0][mine], atol=1e-6):
            raise AssertionError(f"{run}: re-scored {mine} {out[0.0][mine]} != metrics.json {m[key]}")
    for c in cutoffs:
        smoothed = smooth_poses(chis, body.limits, seq.fps, TrackSmoothing(cutoff_hz=float(c), order=order))
        out[float(c)] = score(body, seq, smoothed, alphas, m)
    return out


def check(base: Path, smoothed_runs: Path, order: int) -> None:
    """Each run under ``smoothed_runs`` (made with the smoother on) against its base run smoothed here."""
    from mocap.trackers.smoothing import TrackSmoothing, smooth_poses

    for run in sorted(p.parent for p in smoothed_runs.glob("*/metrics.json")):
        m = json.loads((run / "metrics.json").read_text())
        cutoff = m["config"]["tracker"]["smoothing"]["cutoff_hz"]
        _, body, seq, chis, _ = load_run(base / run.name)
        mine = smooth_poses(chis, body.limits, seq.fps, TrackSmoothing(cutoff_hz=cutoff, order=order))
        theirs = np.load(run / "motion.npz")["chi"]
        print(f"{run.name}: cutoff {cutoff} Hz, max |chi - base smoothed| = "
              f"{np.abs(theirs - mine).max():.2e}, joints {m['mpjpe_mm']:.2f} mm, "
              f"surface {m['surface_to_mesh_mm']:.2f} mm")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", type=Path, help="a folder of finished run folders (<runs>/<data>/metrics.json)")
    p.add_argument("--cutoffs", type=float, nargs="+", default=[2.0, 3.0, 4.0, 6.0, 8.0])
    p.add_argument("--order", type=int, default=4)
    p.add_argument("--check", type=Path, help="runs made with the smoother on, compared with these smoothed")
    a = p.parse_args(argv)
    if a.check:
        check(a.runs, a.check, a.order)
        return
    rows = {}
    for run in sorted(q.parent for q in a.runs.glob("*/metrics.json")):
        rows[run.name] = res = sweep(run, a.cutoffs, a.order)
        b = res[0.0]
        print(f"{run.name}: as tracked joints {b['joints']:.2f} mm (oracle {b['oracle']:.2f}), "
              f"offset-removed {b['removed']:.2f}, surface {b['surface']:.2f} "
              f"(oracle {b['surface_oracle']:.2f}), lost {b['lost']}", flush=True)
        for c in a.cutoffs:
            r = res[float(c)]
            print(f"  {c:g} Hz: joints {r['joints']:.2f} ({r['joints'] - b['joints']:+.2f}), offset-removed "
                  f"{r['removed']:.2f}, surface {r['surface']:.2f} "
                  f"({100 * (r['surface'] / b['surface'] - 1):+.1f} %), lost {r['lost']}", flush=True)
    print("\n| cut-off | " + " | ".join(rows) + " | mean (joints/base + surface/base) | passes |")
    print("|---|" + "---|" * (len(rows) + 2))
    for c in a.cutoffs:
        cells, ratio, ok = [], [], True
        for res in rows.values():
            b, r = res[0.0], res[float(c)]
            cells.append(f"{r['joints']:.2f} ({r['joints'] - b['joints']:+.2f}) / {r['surface']:.2f} "
                         f"({100 * (r['surface'] / b['surface'] - 1):+.1f} %)")
            ratio.append(r["joints"] / b["joints"] + r["surface"] / b["surface"])
            ok &= r["joints"] < b["joints"] and r["surface"] <= 1.02 * b["surface"] and r["lost"] <= b["lost"]
        print(f"| {c:g} Hz | " + " | ".join(cells) + f" | {np.mean(ratio):.4f} | {'yes' if ok else 'no'} |")


if __name__ == "__main__":
    main()

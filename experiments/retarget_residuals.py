"""Question: how closely can our body (one shape per clip, joint limits) follow real motion
capture, clip by clip, and where does it not?

Every clip of the Bandai Namco Research Motion Dataset 1 in ../shared/data/real-motion (index.csv)
is read (mocap.clips.read_bvh) and retargeted onto the body (mocap.clips.retarget, every
``--step``-th frame, the name map ``bandai_namco``). Per clip: the residual of the fitted points
(median and max over frames and points, mm), per point, the angle between the clip's and our
limb segments (degrees), and the time per frame. Writes a markdown table (default
docs/results/real_motion_retargeting.md) and the numbers as JSON beside it.

    OPENBLAS_NUM_THREADS=1 python experiments/retarget_residuals.py --step 5 [--limit N] [--body paper22]
        [--match positions|segments] [--out docs/results/real_motion_retargeting.md]

The residuals are derived from data licensed CC BY-NC 4.0 (see the output's attribution).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from mocap.body import load_body
from mocap.clips import read_bvh, retarget

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "real-motion"
ATTRIBUTION = ("Motion data: Bandai-Namco-Research-Motiondataset (c) 2022 Bandai Namco Research Inc., "
               "licensed under CC BY-NC 4.0 (https://creativecommons.org/licenses/by-nc/4.0/), "
               "https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset.")
SEGMENTS = {"upper arm": [("l_shoulder", "l_elbow"), ("r_shoulder", "r_elbow")],
            "forearm": [("l_elbow", "l_wrist"), ("r_elbow", "r_wrist")],
            "thigh": [("l_hip", "l_knee"), ("r_hip", "r_knee")],
            "shin": [("l_knee", "l_ankle"), ("r_knee", "r_ankle")],
            "trunk": [("pelvis", "neck_base")]}
UNDER_MM = 15.0


def segment_angles(r) -> dict[str, float]:
    """Median over frames and sides of the angle (deg) between the clip's and our segment."""
    names = list(r.point_names)
    out = {}
    for seg, pairs in SEGMENTS.items():
        angs = []
        for a, b in pairs:
            if a in names and b in names:
                u = r.targets[:, names.index(b)] - r.targets[:, names.index(a)]
                v = r.fitted[:, names.index(b)] - r.fitted[:, names.index(a)]
                c = (u * v).sum(-1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
                angs.append(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))
        if angs:
            out[seg] = float(np.median(np.concatenate(angs)))
    return out


def offset_removed(r) -> float:
    """Median residual (mm) once each point's constant offset in the clip's heading frame is
    removed (:func:`mocap.eval.mismatch.offset_removed_errors`): what is not a fixed difference
    of joint definitions."""
    from mocap.eval.mismatch import heading_frames, offset_removed_errors

    names = list(r.point_names)
    frames = heading_frames(r.targets[:, names.index("l_hip")], r.targets[:, names.index("r_hip")])
    err, _ = offset_removed_errors(r.fitted, r.targets, np.ones(r.residual_mm.shape, bool), frames)
    return float(np.median(err))


def run(data: Path, step: int, body_name: str, limit: int | None, match: str = "positions") -> dict:
    index = list(csv.DictReader(open(data / "index.csv")))[:limit]
    body = load_body(body_name)
    clips = []
    for k, row in enumerate(index):
        path = data / row["file"]
        t0 = time.perf_counter()
        clip = read_bvh(path)
        t_read = time.perf_counter() - t0
        r = retarget(clip, body, step=step, match=match)
        s = r.summary()
        s.update(file=row["file"], motion=row["motion"], style=row["style"], source_frames=clip.num_frames,
                 read_s=t_read, segment_deg=segment_angles(r), offset_removed_median_mm=offset_removed(r),
                 alpha_at_bound=int((np.abs(r.alpha) > 2.99).sum()))
        clips.append(s)
        print(f"[{k + 1}/{len(index)}] {Path(row['file']).name}: {r.num_frames} frames, "
              f"median {r.median_mm:.1f} max {r.max_mm:.1f} mm (offsets removed: "
              f"{s['offset_removed_median_mm']:.1f}), {1e3 * r.seconds_per_frame:.1f} ms/frame "
              f"({s['cpu_ms_per_frame']:.1f} CPU)", flush=True)
    return {"body": body_name, "step": step, "match": match, "clips": clips}


def table(res: dict, command: str, commit: str) -> str:
    clips = res["clips"]
    med = np.array([c["median_mm"] for c in clips])
    mx = np.array([c["max_mm"] for c in clips])
    ms = np.array([c["ms_per_frame"] for c in clips])
    cpu = np.array([c["cpu_ms_per_frame"] for c in clips])
    orm = np.array([c["offset_removed_median_mm"] for c in clips])
    frames = np.array([c["frames"] for c in clips])
    points = list(clips[0]["per_joint_median_mm"])
    L = [f"# Real motion retargeted onto our body ({res['body']})", "",
         f"Command: `{command}`  ", f"Commit: `{commit}`  ",
         f"Clips: {len(clips)} of the Bandai Namco Research Motion Dataset 1, every {res['step']}th frame "
         f"({int(frames.sum())} frames); name map `bandai_namco`; one shape per clip, joint limits; "
         f"match `{res.get('match', 'positions')}`.", "",
         f"> {ATTRIBUTION} These figures are derived from it (non-commercial use).", "",
         "## Summary", "",
         "| | value |", "|---|---|",
         f"| clips with median residual < {UNDER_MM:g} mm | {np.mean(med < UNDER_MM):.0%} "
         f"({int((med < UNDER_MM).sum())} of {len(clips)}) |",
         f"| the same, each point's constant offset (heading frame) removed | {np.mean(orm < UNDER_MM):.0%} "
         f"(per-clip median: median {np.median(orm):.1f} mm, max {orm.max():.1f} mm) |",
         f"| clips with max residual < {UNDER_MM:g} mm | {np.mean(mx < UNDER_MM):.0%} |",
         f"| per-clip median residual (mm): median / min / max | {np.median(med):.1f} / {med.min():.1f} / "
         f"{med.max():.1f} |",
         f"| per-clip max residual (mm): median / max | {np.median(mx):.1f} / {mx.max():.1f} |",
         f"| time per frame (ms, whole retargeting incl. shape; wall): median / max | {np.median(ms):.1f} / "
         f"{ms.max():.1f} |",
         f"| the same, process CPU time (ms): median / max | {np.median(cpu):.1f} / {cpu.max():.1f} |",
         f"| total time (s) | {sum(c['seconds'] for c in clips):.0f} |",
         f"| clips whose shape hits the bound (+-3) in >= 10 of 20 coefficients | "
         f"{sum(c['alpha_at_bound'] >= 10 for c in clips)} |", "",
         "## Per point (median over clips of the per-clip median; and the largest per-clip max), mm", "",
         "| point | median | max |", "|---|---|---|"]
    for p in points:
        L.append(f"| {p} | {np.median([c['per_joint_median_mm'][p] for c in clips]):.1f} | "
                 f"{max(c['per_joint_max_mm'][p] for c in clips):.1f} |")
    L += ["", "## Limb directions: angle between the clip's segment and ours (deg, median over clips)", "",
          "| segment | median |", "|---|---|"]
    for seg in SEGMENTS:
        vals = [c["segment_deg"][seg] for c in clips if seg in c["segment_deg"]]
        if vals:
            L.append(f"| {seg} | {np.median(vals):.1f} |")
    L += ["", "## Per motion type (median over its clips)", "",
          "| motion | clips | median mm | max mm | CPU ms/frame |", "|---|---|---|---|---|"]
    for m in sorted({c["motion"] for c in clips}):
        cs = [c for c in clips if c["motion"] == m]
        L.append(f"| {m} | {len(cs)} | {np.median([c['median_mm'] for c in cs]):.1f} | "
                 f"{max(c['max_mm'] for c in cs):.1f} | "
                 f"{np.median([c['cpu_ms_per_frame'] for c in cs]):.1f} |")
    L += ["", "## Per clip", "", "| clip | frames | median mm | max mm | offsets removed mm | CPU ms/frame |",
          "|---|---|---|---|---|---|"]
    for c in clips:
        L.append(f"| {Path(c['file']).stem} | {c['frames']} | {c['median_mm']:.1f} | {c['max_mm']:.1f} | "
                 f"{c['offset_removed_median_mm']:.1f} | {c['cpu_ms_per_frame']:.1f} |")
    return "\n".join(L) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--step", type=int, default=5)
    ap.add_argument("--body", default="paper22")
    ap.add_argument("--limit", type=int, default=None, help="only the first N clips of index.csv")
    ap.add_argument("--match", default="positions", choices=["positions", "segments"],
                    help="retarget's match: the clip's joint positions or its segments' directions")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "results" / "real_motion_retargeting.md")
    args = ap.parse_args(argv)
    if not (args.data / "index.csv").is_file():
        print(f"{args.data}: no index.csv (the real-motion clips are not here)", file=sys.stderr)
        return 2
    command = ("OPENBLAS_NUM_THREADS=1 python experiments/retarget_residuals.py "
               + " ".join(argv or sys.argv[1:]))
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                            text=True).stdout.strip()
    res = run(args.data, args.step, args.body, args.limit, args.match)
    res.update(command=command, commit=commit, attribution=ATTRIBUTION)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(table(res, command, commit))
    args.out.with_suffix(".json").write_text(json.dumps(res, indent=1))
    print(f"wrote {args.out} and {args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Shape or pose: where the two-cue hybrid's (``hybrid_kp``) error on the real-motion benchmark comes
from (issue 34 item 4). Each dev sequence is tracked as ``mocap track`` tracks it (same config,
run folder, metrics.json, init and oracle caches), in variants:

- ``base``: ``hybrid_kp`` as it is (its shape from the silhouettes, fitted to frame 0's and then
  15 frames' keypoint bone lengths, refined on the silhouettes every 10 frames);
- ``surface``: the shape (alpha) fixed for the whole run to the SURFACE oracle's (our body's shape
  fitted to the true surface, :func:`mocap.eval.surface_oracle.fit_surface_oracle`), no shape
  estimation or refinement (``keypoints.shape_std=0``, ``local.shape.every=0``; the start's pose
  is the self-initialisation's, refined with the keypoints on that shape);
- ``joint``: the same with the JOINT oracle's shape (our body fitted to the true joints,
  :func:`mocap.eval.run_metrics.oracle_fit`);
- ``mix``: the same with ``--mix`` t x the joint oracle's shape + (1 - t) x the surface oracle's
  (is there a shape between the two that beats the tracker's own on both measures?);
- ``--set key=value`` (dotted tracker overrides) applies to every variant (e.g. a candidate fix;
  ``--tag`` names the folder).

A fixed shape splits "shape" from "pose": what is left with the oracle's shape is the pose's.
Each run's metrics.json gains ``shape_split``: the variant, the shape's distance from the
oracles' shapes (standardised units), per joint the constant offset (tracked - true, mean over
frames, mm) and the error left when it is removed, and per bone (HumanEva-15 names) the tracked
and true lengths (mean over frames, mm). The oracles' shapes are kept in
``<out>/shapes/<data>.npz`` (fitted once).

    python -m experiments.kp_shape_split walk_heavy_man bow_tall_man bye_petite_woman \\
        --variants base surface joint --frames 40 --seed 0 --out multirun/kp_split
    python -m experiments.kp_shape_split --report multirun/kp_split [--noise]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import yaml

#: HumanEva-15 bones (by the ground truth's joint names)
BONES = [("lsho", "lelb"), ("lelb", "lwri"), ("rsho", "relb"), ("relb", "rwri"), ("lhip", "lkne"),
         ("lkne", "lank"), ("rhip", "rkne"), ("rkne", "rank"), ("lhip", "rhip"), ("lsho", "rsho"),
         ("pelvis", "thorax"), ("thorax", "head")]


_SURFACE_FITS: dict = {}


def _memo_surface_oracle() -> None:
    """Let the run's surface-oracle metrics reuse the fit made here for its shape (one process)."""
    import mocap.eval.surface_oracle as so

    if getattr(so.fit_surface_oracle, "memo", False):
        return
    inner = so.fit_surface_oracle

    def fit(body, truth, true_faces, alpha0, chi0, *args, **kwargs):
        key = (np.asarray(truth).shape, np.asarray(truth).tobytes()[:4096], np.asarray(alpha0).tobytes())
        if key not in _SURFACE_FITS:
            _SURFACE_FITS[key] = inner(body, truth, true_faces, alpha0, chi0, *args, **kwargs)
        return _SURFACE_FITS[key]

    fit.memo = True
    so.fit_surface_oracle = fit


def oracle_shapes(body, seq, frames: int, folder: Path) -> dict[str, np.ndarray]:
    """{'joint': alpha (K,), 'surface': alpha (K,)} of ``seq``'s first ``frames`` frames, kept in
    ``folder/<data>.npz``."""
    import mocap.eval.surface_oracle as so
    from mocap.eval.run_metrics import oracle_fit

    _memo_surface_oracle()
    path = folder / f"{seq.name}-{frames}.npz"
    if path.is_file():
        z = np.load(path)
        return {"joint": z["joint"], "surface": z["surface"]}
    joint = oracle_fit(body, seq, frames)
    surf = so.fit_surface_oracle(body, seq.gt.surface[:frames], seq.gt.surface_faces, joint.alpha,
                              joint.chi[:frames])
    folder.mkdir(parents=True, exist_ok=True)
    np.savez(path, joint=np.asarray(joint.alpha), surface=np.asarray(surf.alpha),
             surface_chi=surf.chi, surface_frames=surf.frames)
    return {"joint": np.asarray(joint.alpha), "surface": np.asarray(surf.alpha)}


def breakdown(body, seq, result, shapes: dict) -> dict:
    """Per joint: constant offset (mm, (3,)), its norm, error with it removed; per bone: tracked
    and true mean lengths (mm); the tracked shape's distance from the oracles' (last frame)."""
    from mocap.eval.by_name import NameScorer

    ests = result.estimates
    chis = np.stack([e.chi for e in ests])
    alphas = np.stack([e.alpha for e in ests])
    scorer = NameScorer(body, seq.gt.person(0))
    pts = scorer.points_by_shape(alphas, chis)
    gt = scorer.gt
    names = [n for n in gt.joint_names if scorer.mapping.get(n) is not None
             and (not scorer.kwargs["only"] or n in scorer.kwargs["only"])]
    F = len(chis)
    truth = {n: np.asarray(gt.joints[:F, list(gt.joint_names).index(n)], np.float64) for n in names}
    est = {n: np.asarray(pts[scorer.mapping[n]], np.float64)[:F] for n in names}
    joints = {}
    for n in names:
        d = 1e3 * (est[n] - truth[n])                                    # (F, 3) mm
        off = d.mean(axis=0)
        joints[n] = {"offset": [round(float(x), 1) for x in off],
                     "offset_mm": round(float(np.linalg.norm(off)), 1),
                     "error_mm": round(float(np.linalg.norm(d, axis=1).mean()), 1),
                     "removed_mm": round(float(np.linalg.norm(d - off, axis=1).mean()), 1)}
    bones = {}
    for a, b in BONES:
        if a in est and b in est:
            lt = 1e3 * np.linalg.norm(est[a] - est[b], axis=1).mean()
            lg = 1e3 * np.linalg.norm(truth[a] - truth[b], axis=1).mean()
            bones[f"{a}-{b}"] = {"tracked": round(float(lt), 1), "true": round(float(lg), 1),
                                 "diff": round(float(lt - lg), 1)}
    alpha = alphas[-1]
    return {"joints": joints, "bones": bones,
            "alpha_final": [round(float(x), 3) for x in alpha],
            "alpha_from": {k: round(float(np.linalg.norm(alpha - v)), 2) for k, v in shapes.items()}}


def run_variant(data: str, variant: str, frames: int, seed: int, sets: list[str], out: Path,
                mix: float = 0.5, limits: Path | None = None) -> dict:
    from mocap.run_folder import run_tracking
    from mocap_cli.hydra_edge import build, compose, plain

    overrides = ["+sweep=real_motion_dev", "tracker=hybrid_kp", f"data=real_{data}", f"seed={seed}",
                 f"frames={frames}", "threads=1", "recording.enabled=false"]
    if variant != "base":
        overrides += ["tracker.keypoints.shape_std=0", "tracker.local.shape.every=0"]
    overrides += [f"tracker.{s}" for s in sets]
    cfg = compose("track", overrides)
    body = build(cfg.body)
    if limits is not None:          # the body's joint limits widened ({dof: [lo, hi] degrees}); the
        for n, lim in json.loads(limits.read_text()).items():      # oracles come from their cache
            body.limits[body.dof_index(n)] = np.deg2rad(lim)
    seq = build(cfg.data, body=body)
    shapes = oracle_shapes(body, seq, frames, out / "shapes")
    fixed = {**shapes, "mix": mix * shapes["joint"] + (1.0 - mix) * shapes["surface"]}.get(variant)

    built = []

    def make_tracker(**objects):
        tracker = build(cfg.tracker, **objects)
        built.append(tracker)
        if variant != "base":
            inner = tracker.refine_initial

            def refine_initial(frame, chi, alpha):
                return inner(frame, chi, fixed)

            tracker.refine_initial = refine_initial
        return tracker

    def extra(metrics, result, body, seq):
        name = f"mix {mix:g}" if variant == "mix" else variant
        two_cue = getattr(built[-1], "two_cue", None) if built else None
        return {"shape_split": {"variant": name, "sets": sets, **breakdown(body, seq, result, shapes),
                                **({"two_cue": two_cue.reports} if two_cue is not None else {})}}

    folder = out / (f"mix{mix:g}" if variant == "mix" else variant) / f"real_{data}"
    metrics = run_tracking(folder, plain(cfg), make_body=lambda: body, make_sequence=lambda b: seq,
                           make_tracker=make_tracker, source=Path.cwd(), extra=extra,
                           overrides=overrides + [f"shape_split={variant}"])
    if metrics is None:
        metrics = json.loads((folder / "metrics.json").read_text())
    return metrics


def slow_and_jitter(run: Path, smooth: int = 5) -> tuple[float, float, float, dict]:
    """A finished run's offset-removed joint error split in two (mm, mean over joints and frames): the
    slow part (the error's centred ``smooth``-frame mean less its constant offset) and the jitter (the
    error less that mean); the raw error with the error's mean taken (a bound on what a smoother of
    the error could give); and per joint (slow, jitter). From the run's motion.npz and its data."""
    from mocap.body import load_body
    from mocap.data.sources import folder_sequence
    from mocap.eval.by_name import NameScorer

    m = json.loads((run / "metrics.json").read_text())
    body = load_body("paper22")
    seq = folder_sequence(body=body, path=m["config"]["data"]["path"], name=m["data"], seed=m["seed"])
    z = np.load(run / "motion.npz")
    scorer = NameScorer(body, seq.gt.person(0))
    pts = scorer.points_by_shape(z["alpha"], z["chi"])
    gt = scorer.gt
    names = [n for n in gt.joint_names if scorer.mapping.get(n) is not None
             and (not scorer.kwargs["only"] or n in scorer.kwargs["only"])]
    F = len(z["chi"])
    col = {n: list(gt.joint_names).index(n) for n in names}
    d = np.stack([1e3 * (np.asarray(pts[scorer.mapping[n]])[:F] - gt.joints[:F, col[n]]) for n in names],
                 1)                                                                   # (F, J, 3) mm
    off = d.mean(axis=0)
    h = smooth // 2
    padded = np.concatenate([np.repeat(d[:1], h, 0), d, np.repeat(d[-1:], h, 0)])
    mean = np.stack([padded[i:i + F] for i in range(smooth)]).mean(axis=0)            # centred window
    slow, jit = np.linalg.norm(mean - off, axis=-1), np.linalg.norm(d - mean, axis=-1)    # (F, J)
    per = {n: (round(float(slow[:, j].mean()), 1), round(float(jit[:, j].mean()), 1))
           for j, n in enumerate(names)}
    return float(slow.mean()), float(jit.mean()), float(np.linalg.norm(mean, axis=-1).mean()), per


def report(out: Path, noise: bool = False) -> str:
    """Per variant and sequence: joints, x oracle, offset-removed, surface, x surface oracle; then
    the joints carrying the offset and the bones off by most."""
    lines = ["| variant | sequence | joints mm | x oracle | offset-removed mm | surface mm | "
             "x surface oracle | shape from surface / joint oracle's | lost |",
             "|---|---|---|---|---|---|---|---|---|"]
    detail = []
    for m_path in sorted(out.glob("*/*/metrics.json")):
        m = json.loads(m_path.read_text())
        s = m.get("shape_split")
        if s is None:
            continue
        v = f"{s['variant']}{' ' + ' '.join(s['sets']) if s['sets'] else ''} ({m_path.parent.parent.name})"
        sm = m["surface_to_mesh_mm"]
        lines.append(f"| {v} | {m['data'].removeprefix('real_')} | {m['mpjpe_mm']:.1f} | "
                     f"{m['mpjpe_mm'] / m['oracle']['raw_mm']:.2f} | "
                     f"{m['mismatch']['offset_removed_mm']:.1f} | "
                     f"{sm:.1f} | {sm / m['surface_oracle_mm']:.2f} | "
                     f"{s['alpha_from']['surface']:.2f} / {s['alpha_from']['joint']:.2f} | "
                     f"{m.get('frames_lost', 0)} |")
        j = sorted(s["joints"].items(), key=lambda kv: -kv[1]["offset_mm"])[:6]
        b = sorted(s["bones"].items(), key=lambda kv: -abs(kv[1]["diff"]))[:6]
        if noise:
            slow, jit, smoothed, per = slow_and_jitter(m_path.parent)
            detail.append(f"{v} {m['data'].removeprefix('real_')}: offset-removed error: slow {slow:.1f}, "
                          f"jitter {jit:.1f} mm (error's 5-frame mean {smoothed:.1f} mm against "
                          f"{m['mpjpe_mm']:.1f}); "
                          + ", ".join(f"{n} {a_}/{b_}" for n, (a_, b_) in per.items()))
        detail.append(f"{v} {m['data'].removeprefix('real_')}: offsets "
                      + ", ".join(f"{n} {d['offset_mm']:.0f} {d['offset']} (left {d['removed_mm']:.0f})"
                                  for n, d in j)
                      + "; bones " + ", ".join(f"{n} {d['diff']:+.0f}" for n, d in b))
    return "\n".join(lines + [""] + detail)


def rule_table(out: Path, surface_tolerance: float = 0.02) -> str:
    """Every ``--tag`` candidate under ``out`` (``out/<tag>/base/<data>``) against ``hybrid_kp`` as it
    is (``out/base/<data>``), by the choice rule (docs/results/surface.md, "Shape or pose"): on
    every sequence run, joints lower and surface (true -> tracked mean) not higher by more than
    ``surface_tolerance``, no frame lost; the score: the mean of joints / base + surface / base."""
    def load(folder: Path) -> dict:
        return {p.parent.name: json.loads(p.read_text()) for p in sorted(folder.glob("*/metrics.json"))}

    base = load(out / "base")
    seqs = list(base)
    lines = ["| candidate | " + " | ".join(d.removeprefix("real_") for d in seqs) + " | passes | score |",
             "|---|" + "---|" * (len(seqs) + 2)]
    lines.append("| `hybrid_kp` as it is | " + " | ".join(
        f"{base[d]['mpjpe_mm']:.2f} / {base[d]['surface_to_mesh_mm']:.2f}" for d in seqs) + " | | |")
    for tag in sorted(p.parent.name for p in out.glob("*/base")):
        runs = load(out / tag / "base")
        cells, ok, score = [], bool(runs), []
        for d in seqs:
            if d not in runs:
                cells.append("-")
                continue
            m, b = runs[d], base[d]
            dj, ds = m["mpjpe_mm"] - b["mpjpe_mm"], m["surface_to_mesh_mm"] / b["surface_to_mesh_mm"] - 1
            ok = ok and dj < 0 and ds <= surface_tolerance and not m.get("frames_lost", 0)
            score.append(m["mpjpe_mm"] / b["mpjpe_mm"] + m["surface_to_mesh_mm"] / b["surface_to_mesh_mm"])
            lost = f", lost {m['frames_lost']}" if m.get("frames_lost", 0) else ""
            cells.append(f"{m['mpjpe_mm']:.2f} ({dj:+.2f}) / {m['surface_to_mesh_mm']:.2f} "
                         f"({100 * ds:+.1f} %){lost}")
        mean = f"{np.mean(score):.4f}" if score else "-"
        lines.append(f"| {tag} | " + " | ".join(cells) + f" | {'yes' if ok else 'no'}"
                     f"{'' if len(runs) == len(seqs) else ' (so far)'} | {mean} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="*", help="dev sequence folder names (data/real_motion/dev/...)")
    p.add_argument("--variants", nargs="+", default=["base", "surface", "joint"],
                   choices=["base", "surface", "joint", "mix"])
    p.add_argument("--mix", type=float, default=0.5, help="mix: t x the joint oracle's shape + (1 - t) x the "
                   "surface oracle's")
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", nargs="*", default=[], help="tracker overrides key=value (dotted), every variant")
    p.add_argument("--out", type=Path, default=Path("multirun/kp_split"))
    p.add_argument("--tag", default="", help="suffix of the variants' folders (a --set candidate)")
    p.add_argument("--limits", type=Path, help="joint limits to track with, JSON {dof: [lo, hi] degrees} "
                   "(experiments/joint_limits.py --out)")
    p.add_argument("--report", type=Path, help="print the table of a finished --out folder and stop")
    p.add_argument("--rule", type=Path, help="print every --tag candidate of a finished --out folder against "
                   "its base runs by the choice rule and stop")
    p.add_argument("--noise", action="store_true", help="with --report: the offset-removed error's slow part "
                   "and jitter per run (reads motion.npz)")
    a = p.parse_args(argv)
    if a.report:
        print(report(a.report, a.noise))
        return
    if a.rule:
        print(rule_table(a.rule))
        return
    for kv in a.set:
        yaml.safe_load(kv.split("=", 1)[1])                 # a bad value fails before any work
    for data in a.sequences:
        for variant in a.variants:
            m = run_variant(data, variant, a.frames, a.seed, a.set, a.out if not a.tag else a.out / a.tag,
                            a.mix, a.limits)
            s = m["shape_split"]
            print(f"{data} [{variant}{' ' + a.tag if a.tag else ''}] joints {m['mpjpe_mm']:.1f} mm "
                  f"({m['mpjpe_mm'] / m['oracle']['raw_mm']:.2f}x), offset-removed "
                  f"{m['mismatch']['offset_removed_mm']:.1f}, surface {m['surface_to_mesh_mm']:.1f} mm "
                  f"({m['surface_to_mesh_mm'] / m['surface_oracle_mm']:.2f}x), shape from oracles' "
                  f"{s['alpha_from']}", flush=True)


if __name__ == "__main__":
    main()

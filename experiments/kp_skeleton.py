"""The two-cue hybrid's skeleton (issue 34 item 4): rest-joint corrections fitted to the keypoints.

``--run``: track a dev sequence as ``mocap track`` does (``tracker=hybrid_kp``, its config, the init
and oracle caches; ``--set`` tracker overrides, ``--tag`` names the folder) and keep every frame's
pose, shape and joint offsets in ``<out>/<tag>/real_<data>/estimates.npz`` beside the run's
metrics.json.

``--bound``: offline, from a ``--run`` of ``--from`` (its poses and shapes): per-person rest-joint
corrections delta (J, 3) fitted to frames ``0..fit-1``'s triangulated keypoints with the tracked
poses held (:func:`mocap.body.skeleton.fit_joint_offsets`, the shape the frames ``fit..`` were
tracked with), then frames ``fit..``'s joint error (mm, the evaluation's own scorer) with delta
applied: poses held, and poses re-fitted by a local step of the tracker on the corrected body
(``--alternate`` times fitting delta and the fit frames' poses in turn first). Written to
``<out>/<from>/real_<data>/bound.json``.

    python -m experiments.kp_skeleton bow_tall_man --run --frames 40 --seed 0 --out multirun/kp7
    python -m experiments.kp_skeleton bow_tall_man --bound --from base --out multirun/kp7
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def _overrides(data: str, seed: int, frames: int, sets: list[str]) -> list[str]:
    return (["+sweep=real_motion_dev", "tracker=hybrid_kp", f"data=real_{data}", f"seed={seed}",
             f"frames={frames}", "threads=1", "recording.enabled=false"] + [f"tracker.{s}" for s in sets])


def run(data: str, frames: int, seed: int, sets: list[str], out: Path, tag: str) -> dict:
    """Track ``data``; keep the estimates (module docstring); the run's metrics."""
    from mocap.run_folder import run_tracking
    from mocap_cli.hydra_edge import build, compose, plain

    overrides = _overrides(data, seed, frames, sets)
    cfg = compose("track", overrides)
    body = build(cfg.body)
    seq = build(cfg.data, body=body)
    folder = out / tag / f"real_{data}"
    built = []

    def make_tracker(**objects):
        built.append(build(cfg.tracker, **objects))
        return built[-1]

    def extra(metrics, result, body_, seq_):
        est = result.estimates
        offsets = [getattr(e, "joint_offsets", None) for e in est]
        J = body_.num_joints
        np.savez(folder / "estimates.npz", chi=np.stack([e.chi for e in est]).astype(np.float64),
                 alpha=np.stack([e.alpha for e in est]).astype(np.float64),
                 joint_offsets=np.stack([np.zeros((J, 3)) if o is None else o for o in offsets]))
        two_cue = getattr(built[-1], "two_cue", None) if built else None
        reports = {"two_cue": two_cue.reports} if two_cue is not None else {}
        return {"kp_skeleton": {"sets": sets, **reports}}

    metrics = run_tracking(folder, plain(cfg), make_body=lambda: body, make_sequence=lambda b: seq,
                           make_tracker=make_tracker, source=Path.cwd(), extra=extra,
                           overrides=overrides + [f"kp_skeleton={tag}"])
    if metrics is None:
        metrics = json.loads((folder / "metrics.json").read_text())
    print(folder, metrics.get("mpjpe_mm"), metrics.get("surface_to_mesh_mm"), flush=True)
    return metrics


def bound(data: str, source: str, out: Path, fit: int = 15, ridge: float = 0.03, alternate: int = 1,
          seed: int = 0) -> dict:
    """The offline bound of the module docstring."""
    from mocap.body.skeleton import fit_joint_offsets
    from mocap.eval.by_name import NameScorer
    from mocap.trackers.run import frame_of
    from mocap_cli.hydra_edge import build, compose

    folder = out / source / f"real_{data}"
    z = np.load(folder / "estimates.npz")
    chis, alphas = z["chi"], z["alpha"]
    F = len(chis)
    cfg = compose("track", _overrides(data, seed, F, []))
    body = build(cfg.body)
    seq = build(cfg.data, body=body)
    tracker = build(cfg.tracker, body=body, rig=seq.rig, rng=np.random.default_rng(seed))
    body = tracker.body                          # the tracker's (its joint limits)
    scorer = NameScorer(body, seq.gt)
    cue = tracker.cue
    frames = [frame_of(seq, f) for f in range(F)]
    obs = [cue.observe(fr) for fr in frames]
    measured = np.stack([cue.triangulated(o) for o in obs])             # (F, L, 3)
    alpha = alphas[fit]                            # the shape the later frames were tracked with
    lm = cue.landmarks

    def score(chi, a, delta):
        shaped = body.shaped(a, joint_offsets=delta)
        pts = scorer.points(shaped, chi)
        return _mpjpe(scorer, pts, fit)

    def refit(sel, poses, delta, steps=1):
        tracker.initialize(poses[sel[0]], alpha)
        tracker.set_shape(alpha, joint_offsets=delta)
        new = poses.copy()
        for f in sel:
            c = poses[f]
            for _ in range(steps):
                c = tracker.local_step(frames[f], c, extra=tracker.keypoint_lines(obs[f]))[0]
            new[f] = c
        return new

    zero = np.zeros((body.num_joints, 3))
    fit_sel, test_sel = np.arange(fit), np.arange(fit, F)
    rows = {"frames_fit": fit, "frames_scored": int(F - fit), "std": ridge}
    rows["held_no_offsets"] = score(chis[test_sel], alpha, zero)

    def fitted(poses, start=None):
        found = fit_joint_offsets(body, lm, alpha, poses[fit_sel], measured[fit_sel], std=ridge, start=start)
        return found.offsets, found.report

    # (a) the fit frames' poses as tracked (with the start's shape); (b) first re-fitted by a local
    # step on the new shape (what the two-cue fit's shift and shape moved), then alternating
    plans = {"as_tracked": chis.copy(), "refit": refit(fit_sel, chis, zero)}
    best = None
    for name, poses in plans.items():
        delta, info = fitted(poses)
        rows[f"{name}_fit0"] = info
        rows[f"{name}_held_0"] = score(chis[test_sel], alpha, delta)
        for it in range(1, alternate + 1):
            poses = refit(fit_sel, poses, delta)
            delta, info = fitted(poses, delta)
            rows[f"{name}_fit{it}"] = info
            rows[f"{name}_held_{it}"] = score(chis[test_sel], alpha, delta)
        rows[f"{name}_offsets_mm"] = {n: np.round(1e3 * d, 1).tolist()
                                      for n, d in zip(body.joint_names, delta, strict=True)}
        print(name, {k: v for k, v in rows.items() if k.startswith(name) and "held" in k}, flush=True)
        best = delta if name == "refit" else best
    rows["refit_no_offsets"] = score(refit(test_sel, chis, zero)[test_sel], alpha, zero)
    rows["refit_offsets"] = score(refit(test_sel, chis, best)[test_sel], alpha, best)
    shown = {k: v for k, v in rows.items() if not isinstance(v, dict)}
    print(json.dumps(shown), flush=True)
    (folder / "bound.json").write_text(json.dumps(rows, indent=1))
    return rows


def _mpjpe(scorer, points: dict, start: int) -> float:
    return round(float(scorer.score(points, start)["mpjpe_mm"]), 3)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="+")
    p.add_argument("--run", action="store_true")
    p.add_argument("--bound", action="store_true")
    p.add_argument("--from", dest="source", default="base")
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fit", type=int, default=15)
    p.add_argument("--ridge", type=float, default=0.03, help="the offsets' prior spread (m)")
    p.add_argument("--alternate", type=int, default=1)
    p.add_argument("--set", nargs="*", default=[])
    p.add_argument("--tag", default="base")
    p.add_argument("--out", type=Path, default=Path("multirun/kp7"))
    a = p.parse_args(argv)
    for data in a.sequences:
        if a.run:
            run(data, a.frames, a.seed, a.set, a.out, a.tag)
        if a.bound:
            bound(data, a.source, a.out, a.fit, a.ridge, a.alternate, a.seed)


if __name__ == "__main__":
    main()

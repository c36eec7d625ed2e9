"""Where the silhouette-only hybrid's joint error comes from (issue 34 item 4), on one sequence folder
of the real-motion benchmark: the start or the tracking, which joints, left/right swaps, and what the
misalignment check and its repair APF do.

The tracker runs here (not through ``mocap track``) so that every repair can be scored: for each APF
call, the joint error of the local step's pose (before) and of the frame's final pose (after), and
whether the search's pose was kept. Two starts:

- ``self``: the tracker's own silhouette self-initialisation, read from ``--init-cache`` with the
  random state ``mocap track`` gives it (the same run as ``mocap track ... seed=S frames=F``);
- ``oracle``: the joint oracle's pose and shape of frame 0 (our body fitted to the true joints,
  ``mocap.eval.run_metrics.oracle_fit``), tracked with the same settings: what tracking loses when
  the start is as good as our body can be;
- ``self_pose`` / ``oracle_pose``: the self-initialisation's pose with the oracle's shape / the
  oracle's pose with the self-initialisation's shape (is the start's error its shape or its pose?).

Per run: the error of frame 0, frames 1-9 and 10-; per joint (mean and frame 0); the frames where
the tracked arms or legs are nearer the other side's true joints (left/right swapped); the APF calls,
kept, and how many of the kept ones lowered the joint error.

    python -m experiments.sil_hybrid_diagnosis data/real_motion/dev/walk_heavy_man --start self oracle \\
        --frames 40 --init-cache outputs/init_cache [--tracker hybrid] [--set key=value ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from experiments.tools.jsonl import report
from mocap.body import load_body
from mocap.data.sources import folder_sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.run_metrics import oracle_fit
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of, run_frames

#: HumanEva-15 left/right pairs of the limbs (arms, legs)
PAIRS = {"arms": [("lsho", "rsho"), ("lelb", "relb"), ("lwri", "rwri")],
         "legs": [("lhip", "rhip"), ("lkne", "rkne"), ("lank", "rank")]}


def joint_errors(scorer: NameScorer, alphas: np.ndarray, chis: np.ndarray):
    """(names (n,), err (F, n) mm, est (F, n, 3), truth (F, n, 3)) of poses chis (F, D) with shapes
    alphas (F, K) against the first F frames of the ground truth."""
    pts = scorer.points_by_shape(alphas, chis)
    gt = scorer.gt
    names = [n for n in gt.joint_names if scorer.mapping.get(n) is not None and n in scorer.kwargs["only"]] \
        if scorer.kwargs["only"] else [n for n in gt.joint_names if scorer.mapping.get(n) is not None]
    F = len(chis)
    idx = [list(gt.joint_names).index(n) for n in names]
    truth = np.asarray(gt.joints[:F], np.float64)[:, idx]
    est = np.stack([np.asarray(pts[scorer.mapping[n]])[:F] for n in names], axis=1)
    return names, 1e3 * np.linalg.norm(est - truth, axis=-1), est, truth


def swapped_frames(names: list[str], est: np.ndarray, truth: np.ndarray, margin_mm: float = 20.0) -> dict:
    """Per limb pair set: frames where the tracked joints are nearer the other side's truth by more
    than ``margin_mm`` (mean over the pair set's joints)."""
    out = {}
    for part, pairs in PAIRS.items():
        li = [names.index(a) for a, _ in pairs]
        ri = [names.index(b) for _, b in pairs]
        def dist(a, b):
            return np.linalg.norm(est[:, a] - truth[:, b], axis=-1)

        same, cross = dist(li, li) + dist(ri, ri), dist(li, ri) + dist(ri, li)
        gain = 1e3 * (same - cross).mean(axis=1) / 2
        out[part] = [int(f) for f in np.flatnonzero(gain > margin_mm)]
    return out


class Recorder:
    """Wraps the tracker's APF search so that the pose it starts from (the local step's) is kept per frame."""

    def __init__(self, tracker):
        self.before: dict[int, np.ndarray] = {}
        inner = tracker.search

        def search(frame, chi, predicted, free, obs=None, **kwargs):
            self.before[frame.index] = np.array(chi)
            return inner(frame, chi, predicted, free, obs, **kwargs)

        tracker.search = search


def run(seq_path: Path, start: str, frames: int, seed: int, tracker_name: str, overrides: dict,
        init_cache: str | None) -> dict:
    body = load_body("paper22")
    seq = folder_sequence(body=body, path=str(seq_path), name=f"real_{seq_path.name}", seed=seed)
    tracker = make_tracker(tracker_name, body=body, rig=seq.rig, rng=np.random.default_rng([seed, 1]),
                           **overrides)
    scorer = NameScorer(body, seq.gt.person(0))
    if start == "self":
        est0, info = tracker.initializer(init_cache)(frame_of(seq, 0))
        initial = est0
    else:
        from mocap.trackers.contract import initial_estimate_of

        fit = oracle_fit(body, seq, frames)
        chi, alpha = np.array(fit.chi[0]), np.array(fit.alpha)
        info = {"oracle_mm": fit.metrics["raw_mm"]}
        if start != "oracle":           # one of the two from the self-initialisation (cached)
            own = tracker.initializer(init_cache).start(frame_of(seq, 0))[0][0]
            if start == "self_pose":
                chi = np.array(own.chi)
            else:                       # oracle_pose: the oracle's pose on the self-initialisation's shape
                alpha = np.array(own.alpha)
        initial = {0: initial_estimate_of(chi, alpha)}
    rec = Recorder(tracker)
    result = run_frames(tracker, seq, initial, frames, threads=1)
    ests = result.estimates
    chis = np.stack([e.chi for e in ests])
    alphas = np.stack([e.alpha for e in ests])
    names, err, est, truth = joint_errors(scorer, alphas, chis)
    per_frame = err.mean(axis=1)
    calls = []
    for f, chi_local in rec.before.items():
        d = ests[f].diagnostics.misalignment
        pts_b = scorer.points_by_shape(alphas[f], chi_local[None])
        b = np.stack([np.asarray(pts_b[scorer.mapping[n]])[0] for n in names])
        e_b = float(1e3 * np.linalg.norm(b - truth[f], axis=-1).mean())
        calls.append({"frame": f, "limbs": list(d.limbs), "accepted": bool(d.apf_accepted),
                      "before_mm": e_b, "after_mm": float(per_frame[f])})
    flagged = [int(i) for i, e in enumerate(ests[1:], 1) if e.diagnostics and e.diagnostics.misalignment
               and e.diagnostics.misalignment.limbs]
    return {"data": seq.name, "start": start, "info": {k: v for k, v in info.items() if k != "hypotheses"},
            "mpjpe_mm": float(per_frame.mean()), "frame0_mm": float(per_frame[0]),
            "frames1_9_mm": float(per_frame[1:10].mean()), "frames10_mm": float(per_frame[10:].mean()),
            "per_frame_mm": [round(float(x), 1) for x in per_frame],
            "per_joint_mm": {n: round(float(err[:, k].mean()), 1) for k, n in enumerate(names)},
            "per_joint_frame0_mm": {n: round(float(err[0, k]), 1) for k, n in enumerate(names)},
            "swapped_frames": swapped_frames(names, est, truth),
            "flagged_frames": flagged, "apf": calls,
            "heading_turns": {int(f): a for f, a in getattr(tracker, "heading_turns", {}).items()},
            "stuck_searches": list(getattr(tracker, "stuck_searches", [])),
            "start_choice": getattr(tracker, "start_choice", None)}


def summary(r: dict) -> str:
    worst = sorted(r["per_joint_mm"].items(), key=lambda kv: -kv[1])[:5]
    w0 = sorted(r["per_joint_frame0_mm"].items(), key=lambda kv: -kv[1])[:4]
    acc = [c for c in r["apf"] if c["accepted"]]
    helped = [c for c in acc if c["after_mm"] < c["before_mm"] - 1.0]
    hurt = [c for c in acc if c["after_mm"] > c["before_mm"] + 1.0]
    sw = {k: len(v) for k, v in r["swapped_frames"].items()}
    worst = ", ".join(f"{k} {v:.0f}" for k, v in worst)
    return (f"{r['data']} [{r['start']}] mpjpe {r['mpjpe_mm']:.1f}: frame0 {r['frame0_mm']:.1f}, 1-9 "
            f"{r['frames1_9_mm']:.1f}, 10- {r['frames10_mm']:.1f}; worst {worst}; "
            f"frame0 worst {', '.join(f'{k} {v:.0f}' for k, v in w0)}; swapped frames {sw}; "
            f"flagged {len(r['flagged_frames'])}, APF {len(r['apf'])} kept {len(acc)} "
            f"(joints lower {len(helped)}, higher {len(hurt)}); turned {len(r.get('heading_turns', {}))}, "
            f"stuck searches {len(r.get('stuck_searches', []))}"
            + (f"; start over frames: {r['start_choice']['chosen']}" if r.get("start_choice") else ""))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="+", type=Path)
    p.add_argument("--start", nargs="+", default=["self", "oracle"],
                   choices=["self", "oracle", "self_pose", "oracle_pose"],
                   help="self_pose: the self-initialisation's pose with the oracle's shape; oracle_pose: "
                        "the reverse")
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--tracker", default="hybrid")
    p.add_argument("--set", nargs="*", default=[], help="tracker overrides key=value (dotted)")
    p.add_argument("--init-cache", default="outputs/init_cache")
    p.add_argument("--out", type=Path, help="append each run's JSON here (one line each)")
    a = p.parse_args(argv)
    overrides: dict = {}
    for kv in a.set:
        key, value = kv.split("=", 1)
        node = overrides
        *path, last = key.split(".")
        for k in path:
            node = node.setdefault(k, {})
        node[last] = yaml.safe_load(value)
    for s in a.sequences:
        for start in a.start:
            r = run(s, start, a.frames, a.seed, a.tracker, overrides, a.init_cache)
            report(r, summary(r), a.out)


if __name__ == "__main__":
    main()

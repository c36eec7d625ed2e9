"""The two-cue hybrid's proportions (issue 34 item 4): what pulls ``hybrid_kp``'s two-cue shape fit
(:func:`mocap.trackers.two_cue_shape.fit_two_cue_shape`) away from the keypoints' bone lengths.

``--capture``: track a dev sequence as ``mocap track`` does (``tracker=hybrid_kp``, its config, the
init cache) until the two-cue fit is due and keep what the fit is given (the shape, the landmarks
triangulated in every frame so far, the keyframes' poses and frame indices; the masks are the
sequence's) in ``<out>/<data>-s<seed>.npz``, with every frame's triangulated landmarks of the first
``--all`` frames beside them. No tracking after that frame.

``--trace``: the fit on those stored frames with one factor changed at a time (the silhouettes'
weight, the prior's, the components, the frames the lengths come from), and per landmark pair the
lengths: the keypoints' median, the TRUE joints' (the ground truth's, by the detections' labels),
our body's at the joint oracle's shape, at the start's and at each fit's.

    python -m experiments.kp_proportions bow_tall_man --capture --seed 0 --out multirun/kp6_trace
    python -m experiments.kp_proportions bow_tall_man --trace --seed 0 --out multirun/kp6_trace
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

#: detection label -> the ground truth's (HumanEva-15) joint name
GT_NAME = {"mid_hip": "pelvis", "neck_base": "thorax", "head_centre": "head", "l_shoulder": "lsho",
           "l_elbow": "lelb", "l_wrist": "lwri", "r_shoulder": "rsho", "r_elbow": "relb", "r_wrist": "rwri",
           "l_hip": "lhip", "l_knee": "lkne", "l_ankle": "lank", "r_hip": "rhip", "r_knee": "rkne",
           "r_ankle": "rank"}


class _Captured(Exception):
    pass


def _compose(data: str, seed: int, frames: int, sets: list[str]):
    from mocap_cli.hydra_edge import build, compose

    overrides = ["+sweep=real_motion_dev", "tracker=hybrid_kp", f"data=real_{data}", f"seed={seed}",
                 f"frames={frames}", "threads=1", "recording.enabled=false"] + [f"tracker.{s}" for s in sets]
    cfg = compose("track", overrides)
    body = build(cfg.body)
    seq = build(cfg.data, body=body)
    return cfg, body, seq


def capture(data: str, seed: int, out: Path, every_frames: int = 40, sets: list[str] = ()) -> Path:
    """Track until the two-cue fit is due; keep its inputs (module docstring)."""
    import mocap.trackers.hybrid_tracker as ht
    from mocap.run_folder.settings import RunSettings
    from mocap.run_folder.tracking import _prepare
    from mocap_cli.hydra_edge import build, plain

    cfg, body, seq = _compose(data, seed, every_frames, list(sets))
    settings = RunSettings.from_config(plain(cfg))
    tracker_box = []

    def make_tracker(**objects):
        tracker_box.append(build(cfg.tracker, **objects))
        return tracker_box[-1]

    kept = {}

    def grab(body_, rig, landmarks, alpha, measured, chis, masks, settings_, rng):
        t = tracker_box[-1]
        kept.update(alpha=np.asarray(alpha, np.float64), measured=np.asarray(measured, np.float64),
                    chis=np.asarray(chis, np.float64),
                    frames=np.array([f for f, _, _ in t.two_cue.chosen()], int),
                    landmarks=np.array(landmarks.names), view_samples=settings_.view_samples)
        raise _Captured

    from mocap.trackers.run import run_frames

    ht.fit_two_cue_shape, inner = grab, ht.fit_two_cue_shape
    try:
        p = _prepare(settings, 1, lambda: body, lambda b: seq, make_tracker, None)
        try:
            run_frames(p.stepped, p.seq, p.initial, p.frames, threads=1)
        except _Captured:
            pass
    finally:
        ht.fit_two_cue_shape = inner
    if not kept:
        raise RuntimeError(f"{data}: the two-cue fit was never due in {every_frames} frames")
    cue = tracker_box[-1].cue
    every = []
    for f in range(min(every_frames, seq.num_frames)):
        from mocap.trackers.run import frame_of

        obs = cue.observe(frame_of(seq, f))
        every.append(cue.triangulated(obs) if obs is not None else np.full((len(cue.landmarks), 3), np.nan))
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{data}-s{seed}.npz"
    np.savez(path, every=np.stack(every), **kept)
    return path


#: the trace's variants: name -> changes of hybrid_kp's TwoCueShape, and where the lengths come from
#: ("kp15": the 15 tracked frames' keypoints, as the tracker; "kp40": 40 frames'; "true": the true
#: joints' lengths, the same counts and spreads as kp15's)
VARIANTS = {
    "as_is": ({}, "kp15"),
    "kp_only": ({"view_samples": 0.0}, "kp15"),
    "kp_only_c20": ({"view_samples": 0.0, "components": 20}, "kp15"),
    "kp_lsq_c20": ({"view_samples": 0.0, "components": 20, "prior": 0.0}, "kp15"),
    "true_kp_only_c20": ({"view_samples": 0.0, "components": 20}, "true"),
    "c20": ({"components": 20}, "kp15"),
    "prior0": ({"prior": 0.0}, "kp15"),
    "prior0_c20": ({"prior": 0.0, "components": 20}, "kp15"),
    "w4": ({"view_samples": 4.0}, "kp15"),
    "kp40": ({}, "kp40"),
    "true_lengths": ({}, "true"),
    "true_lengths_c20": ({"components": 20}, "true"),
    "polish2000": ({"polish": 2000}, "kp15"),
    "c20_polish2000": ({"components": 20, "polish": 2000}, "kp15"),
    "w4_polish2000": ({"view_samples": 4.0, "polish": 2000}, "kp15"),
    "c20_apf100x15": ({"components": 20, "particles": 100, "layers": 15}, "kp15"),
    "q6": ({"quadratic": 6}, "kp15"),
    "q6_c20": ({"quadratic": 6, "components": 20}, "kp15"),
}

#: bones reported (detection labels)
BONES = [("l_hip", "l_knee"), ("r_hip", "r_knee"), ("l_knee", "l_ankle"), ("r_knee", "r_ankle"),
         ("l_shoulder", "l_elbow"), ("r_shoulder", "r_elbow"), ("l_elbow", "l_wrist"), ("r_elbow", "r_wrist"),
         ("l_hip", "r_hip"), ("l_shoulder", "r_shoulder")]


def trace(data: str, seed: int, out: Path, variants: list[str] | None = None) -> dict:
    """The fit on the frames :func:`capture` kept, per variant of :data:`VARIANTS`; per landmark
    pair the lengths (mm) of the keypoints, the true joints, our body at the oracles' shapes, the
    start's and every fit's (module docstring). Written to ``<out>/<data>-s<seed>-trace.json``."""
    from dataclasses import replace

    from experiments.kp_shape_split import oracle_shapes
    from mocap.body.catalogue import landmark_entries, rest_point_basis, rigid_pairs
    from mocap.body.landmarks import LandmarkSet
    from mocap.trackers.presets import preset_settings
    from mocap.trackers.run import frame_of
    from mocap.trackers.two_cue_shape import fit_two_cue_shape, length_evidence

    z = np.load(out / f"{data}-s{seed}.npz")
    cfg, body, seq = _compose(data, seed, 40, [])
    names = [str(n) for n in z["landmarks"]]
    landmarks = LandmarkSet(body, landmark_entries(names))
    rest0, basis = rest_point_basis(body, landmarks)
    pairs = rigid_pairs(body, landmarks)
    pair_names = [f"{names[i]}-{names[j]}" for i, j in pairs]
    gt = seq.gt
    F = len(z["every"])
    T = np.asarray(gt.joints[:F][:, [list(gt.joint_names).index(GT_NAME[n]) for n in names]], np.float64)
    true_frames = np.linalg.norm(T[:, pairs[:, 0]] - T[:, pairs[:, 1]], axis=-1)            # (F, B)
    true = np.median(true_frames, axis=0)
    settings = preset_settings("hybrid_kp").keypoints.two_cue
    ev15 = length_evidence(body, landmarks, z["measured"], settings.length_floor)
    ev40 = length_evidence(body, landmarks, z["every"], settings.length_floor)
    shapes = oracle_shapes(body, seq, F, out / "shapes")

    def lengths(alpha):
        R = rest0 + np.einsum("k,klc->lc", np.asarray(alpha, np.float64), basis)
        return np.linalg.norm(R[pairs[:, 0]] - R[pairs[:, 1]], axis=-1)

    def mm(x):
        return [round(1e3 * float(v), 1) for v in x]

    rows = {"pairs": pair_names, "true_mm": mm(true), "true_spread_mm": mm(true_frames.std(axis=0)),
            "kp15_minus_true_mm": mm(ev15.median - true), "kp15_spread_mm": mm(ev15.spread),
            "kp15_count": ev15.count.tolist(), "kp40_minus_true_mm": mm(ev40.median - true),
            "start_minus_true_mm": mm(lengths(z["alpha"]) - true),
            "joint_oracle_minus_true_mm": mm(lengths(shapes["joint"]) - true),
            "surface_oracle_minus_true_mm": mm(lengths(shapes["surface"]) - true),
            "alpha_start": [round(float(a), 2) for a in z["alpha"]],
            "alpha_joint_oracle": [round(float(a), 2) for a in shapes["joint"]],
            "alpha_surface_oracle": [round(float(a), 2) for a in shapes["surface"]]}
    masks = [frame_of(seq, int(f)).masks for f in z["frames"]]
    fits = {}
    for name in variants or list(VARIANTS):
        changes, source = VARIANTS[name]
        s = replace(settings, **changes)
        measured = z["every"] if source == "kp40" else z["measured"]
        fit_fn = fit_two_cue_shape
        if source == "true":            # the true joints' lengths in place of the keypoints' medians
            import mocap.trackers.two_cue_shape as tc

            def true_evidence(body_, landmarks_, measured_, floor, _inner=tc.length_evidence):
                e = _inner(body_, landmarks_, measured_, floor)
                return replace(e, median=np.where(e.count > 0, true, np.nan))

            tc.length_evidence, inner = true_evidence, tc.length_evidence
        try:
            found = fit_fn(body, seq.rig, landmarks, z["alpha"], measured, z["chis"], masks, s,
                           np.random.default_rng(seed))
        finally:
            if source == "true":
                tc.length_evidence = inner
        fits[name] = {"alpha": [round(float(a), 2) for a in found.alpha],
                      "minus_true_mm": mm(lengths(found.alpha) - true), **found.report}
        b = {f"{a}-{c}": fits[name]["minus_true_mm"][pair_names.index(f"{a}-{c}")]
             for a, c in BONES if f"{a}-{c}" in pair_names}
        shown = {k: found.report[k] for k in ("alpha_change", "keypoints_only_change", "after")}
        print(name, json.dumps(shown), b, flush=True)
    path = out / f"{data}-s{seed}-trace.json"
    earlier = json.loads(path.read_text())["fits"] if path.is_file() else {}
    rows["fits"] = {**earlier, **fits}
    path.write_text(json.dumps(rows, indent=1))
    return rows


def poses_held(data: str, seed: int, out: Path, steps: int = 2) -> dict:
    """Does holding the keyframes' poses (tracked with the start's shape) make the silhouettes
    oppose a shape more than they do? Per shape (the start's, the keypoints' alone fit, the
    halfway point, the oracles'): the frames' mean per-view E_S (the tracker's resolution) with
    the poses held, and after ``steps`` local steps (silhouettes and keypoints, as the tracker's)
    re-fit each keyframe's pose to that shape. Written to ``<out>/<data>-s<seed>-poses.json``."""
    from experiments.kp_shape_split import oracle_shapes
    from mocap.energy.silhouette import silhouette_target
    from mocap.trackers.run import frame_of
    from mocap_cli.hydra_edge import build

    z = np.load(out / f"{data}-s{seed}.npz")
    traced = json.loads((out / f"{data}-s{seed}-trace.json").read_text())
    cfg, body, seq = _compose(data, seed, 40, [])
    tracker = build(cfg.tracker, body=body, rig=seq.rig, rng=np.random.default_rng(seed))
    shapes = oracle_shapes(body, seq, len(z["every"]), out / "shapes")
    kp = np.asarray(traced["fits"]["kp_only"]["alpha"])
    fit = np.asarray(traced["fits"]["as_is"]["alpha"])
    candidates = {"start": z["alpha"], "two_cue_fit": fit, "halfway_to_keypoints": 0.5 * (z["alpha"] + kp),
                  "keypoints_only": kp, "joint_oracle": shapes["joint"], "surface_oracle": shapes["surface"]}
    tracker.initialize(z["chis"][0], z["alpha"])
    frames = [frame_of(seq, int(f)) for f in z["frames"]]
    result = {}
    for name, alpha in candidates.items():
        tracker.set_shape(np.asarray(alpha, np.float64))
        held, refit = [], []
        for frame, chi in zip(frames, z["chis"], strict=True):
            target = silhouette_target(frame.masks, tracker.scale, view_names=tuple(seq.rig.names))
            obs = tracker.cue.observe(frame)
            new = chi
            for _ in range(steps):
                new = tracker.local_step(frame, new, extra=tracker.keypoint_lines(obs))[0]
            e = tracker.sil.per_view(np.stack([chi, new]), target)[:, target.valid].mean(axis=1)
            held.append(float(e[0]))
            refit.append(float(e[1]))
        result[name] = {"held": round(float(np.mean(held)), 3), "refit": round(float(np.mean(refit)), 3)}
        print(name, result[name], flush=True)
    (out / f"{data}-s{seed}-poses.json").write_text(json.dumps(result, indent=1))
    return result


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequence", help="dev sequence folder name (data/real_motion/dev/...)")
    p.add_argument("--capture", action="store_true")
    p.add_argument("--trace", action="store_true")
    p.add_argument("--poses", action="store_true", help="E_S of candidate shapes, poses held and re-fitted")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--all", type=int, default=40, help="frames whose triangulated landmarks are kept")
    p.add_argument("--set", nargs="*", default=[], help="tracker overrides key=value (dotted)")
    p.add_argument("--out", type=Path, default=Path("multirun/kp6_trace"))
    p.add_argument("--variants", nargs="*", choices=list(VARIANTS), help="--trace: these only")
    a = p.parse_args(argv)
    if a.capture:
        print(capture(a.sequence, a.seed, a.out, a.all, a.set))
    if a.trace:
        trace(a.sequence, a.seed, a.out, a.variants)
    if a.poses:
        poses_held(a.sequence, a.seed, a.out)


if __name__ == "__main__":
    main()

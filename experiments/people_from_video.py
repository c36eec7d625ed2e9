"""Question: from video alone (``mocap detect --people``), are several people found in every
view, followed with stable per-view ids, and tracked by the several-people tracker
(``tracker=marker_people``) over the whole recording without identity switches or ghost tracks?

Method, on ``../shared/data/pose2sim-demo-multi`` (two people, 4 cameras, 100 frames, 60 fps,
real video, no ground truth)::

    mocap detect ../shared/data/pose2sim-demo-multi --out outputs/detect/multi2 --people 2
    mocap track tracker=marker_people data=pose2sim_demo data.path=outputs/detect/multi2 \\
        data.person=all init.mode=tracker hydra.run.dir=outputs/track/multi2
    python -m experiments.people_from_video outputs/detect/multi2 outputs/track/multi2 \\
        --out outputs/people_from_video

Figures (``<out>/people_from_video.json``):

- detection: per view, people per frame, the number of per-view person ids (2 = no id was
  lost and re-born), seconds per frame (``detect.json``);
- tracking: tracks, their first and last frames; each track's fitted keypoints
  (``tracker_landmarks``) projected into each view and matched per frame to the view's
  detected person they fit best (median pixel distance over the keypoints both have): the
  per-person reprojection error against the detections (median over frames and views, px);
  an **identity switch** is a run of frames where, in more views than not, a track fits best
  a detected person other than the one it fits most often in that view (a track that moved
  onto the other actor); frames where it fits another person in one view only are listed per
  view (a detection mix-up in that view, or a view's person id that changed); a **ghost
  track** is a track that fits no detected person (median error over its frames >
  ``--ghost-px``) in 2 or more views, or one alive for fewer than half the frames;
- ``<out>/contact_<cam>.png``: frames of each view with every detected skeleton (thin, colour
  of its per-view id) and every track's projected keypoints (dots, colour of the track).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from mocap.body.skeletons import LAYOUT_BONES, LAYOUTS
from mocap.cameras import load_calibration, project
from mocap.data.openpose import read_people
from mocap.export.people_motion import load_people_motion
from mocap.video.detect import frame_file
from mocap.video.frames import match_videos

MP = list(LAYOUTS["MEDIAPIPE_33"])
COLOURS = [(230, 60, 60), (60, 160, 240), (60, 200, 90), (240, 200, 40), (200, 80, 220), (40, 220, 220)]


def read_detections(detect: Path, names, frames) -> dict:
    """{(cam, frame): (ids (N,), keypoints (N, 33, 3))} from the folder's OpenPose files."""
    out = {}
    for name in names:
        for n in frames:
            p = detect / "pose" / f"{name}_json" / frame_file(name, n, ".json")
            kp = read_people(p, 33)
            ids = [int(q["person_id"][0]) for q in json.loads(p.read_text())["people"]]
            out[name, n] = (np.array(ids, int), kp)
    return out


def fit_errors(px: np.ndarray, kps: np.ndarray, idx: np.ndarray, min_conf: float = 0.5) -> np.ndarray:
    """px (L, 2) a track's projected keypoints (MEDIAPIPE indices ``idx``); kps (N, 33, 3) ->
    (N,) median pixel distance over the keypoints detected with confidence >= min_conf."""
    out = np.full(len(kps), np.inf)
    for i, kp in enumerate(kps):
        ok = (kp[idx, 2] >= min_conf) & np.all(np.isfinite(px), axis=1)
        if ok.sum() >= 5:
            out[i] = float(np.median(np.linalg.norm(kp[idx, :2][ok] - px[ok], axis=1)))
    return out


def left_right_check(names, frames, det, proj, live, idx, head) -> dict:
    """Per view, over the frames where detect's left/right check mirrored someone: for every
    person detected in those frames, the median distance (px, body keypoints) of the
    nearest track's projected keypoints to the labels as written and to their mirror (for the
    person that was mirrored, what BlazePose gave). The tracker fits 4 views at once, so a
    wrong mirroring would fit it worse than its mirror."""
    from mocap.video.detect import BODY, MIRROR

    pos = {int(i): k for k, i in enumerate(idx)}
    body = [k for k in BODY if k in pos and MIRROR[k] in pos]
    out = {}
    for c, name in enumerate(names):
        fixed = head["views"][name].get("left_right_mirrored", [])
        written, original = [], []
        for n in fixed:
            f = frames.index(n)
            for kp in det[name, n][1]:
                best = None
                for p in range(proj.shape[1]):
                    if not live[f, p] or not np.isfinite(proj[f, p, c]).all():
                        continue
                    px = proj[f, p, c]
                    ok = [k for k in body if kp[k, 2] >= 0.5]
                    if len(ok) < 6:
                        continue
                    w = np.median([np.linalg.norm(kp[k, :2] - px[pos[k]]) for k in ok])
                    o = np.median([np.linalg.norm(kp[MIRROR[k], :2] - px[pos[k]]) for k in ok])
                    if best is None or min(w, o) < min(best):
                        best = (w, o)
                if best is not None and min(best) < 80:          # this track is this person
                    written.append(best[0])
                    original.append(best[1])
        if fixed:
            out[name] = {"frames_mirrored": len(fixed), "people_compared": len(written),
                         "median_px_as_written": float(np.median(written)) if written else None,
                         "median_px_as_blazepose_gave": float(np.median(original)) if original else None,
                         "written_fits_better": int(np.sum(np.array(written) < np.array(original)))}
    return out


def analyse(detect: Path, run: Path, ghost_px: float) -> tuple[dict, dict]:
    head = json.loads((detect / "detect.json").read_text())
    rig = load_calibration(detect / head["calibration"])
    names = list(rig.names)
    m = load_people_motion(run / "motion.npz")
    frames = [int(f) for f in m["frame_index"]]
    det = read_detections(detect, names, frames)
    lm_names = [str(n) for n in m["tracker_landmark_names"]]
    keep = [k for k, n in enumerate(lm_names) if n in MP]
    idx = np.array([MP.index(lm_names[k]) for k in keep])
    X = m["tracker_landmarks"][:, :, keep].astype(np.float64)             # (F, P, L, 3)
    live = m["live"]
    ids = [int(i) for i in m["person_ids"]]
    F, P = live.shape
    best = np.full((F, P, len(names)), -1)            # per-view person id fitted best
    err = np.full((F, P, len(names)), np.nan)
    proj = np.full((F, P, len(names), len(keep), 2), np.nan)
    for f in range(F):
        for p in range(P):
            if not live[f, p]:
                continue
            px = project(rig, X[f, p])                                         # (C, L, 2)
            proj[f, p] = px
            for c, name in enumerate(names):
                pid, kps = det[name, frames[f]]
                if len(kps):
                    e = fit_errors(px[c], kps, idx)
                    k = int(np.argmin(e))
                    if np.isfinite(e[k]):
                        best[f, p, c], err[f, p, c] = pid[k], e[k]
    tracks = {}
    for p, tid in enumerate(ids):
        alive = np.flatnonzero(live[:, p])
        fitted_views = 0
        usual, other_per_view = {}, {}
        agree = np.zeros(F, int)
        differ = np.zeros(F, int)
        for c, name in enumerate(names):
            b = best[:, p, c]
            seen = live[:, p] & (b >= 0)
            if seen.any():
                usual[name] = int(np.bincount(b[seen]).argmax())
                agree += seen & (b == usual[name])
                differ += seen & (b != usual[name])
                other_per_view[name] = [int(f) for f in np.flatnonzero(seen & (b != usual[name]))]
            e = err[alive, p, c]
            if np.isfinite(e).any() and np.nanmedian(e) <= ghost_px:
                fitted_views += 1
        switched = np.flatnonzero(differ > agree)
        e = err[alive, p]
        tracks[str(tid)] = {
            "first_frame": int(alive[0]) if len(alive) else None,
            "last_frame": int(alive[-1]) if len(alive) else None,
            "frames": len(alive), "views_fitted": fitted_views, "person_id_per_view": usual,
            "frames_fitting_another_person_per_view": other_per_view,
            "switch_frames": [int(f) for f in switched],
            "reprojection_px_median": float(np.nanmedian(e)) if np.isfinite(e).any() else None,
            "reprojection_px_per_view": {name: float(np.nanmedian(e[:, c])) if np.isfinite(e[:, c]).any()
                                         else None for c, name in enumerate(names)},
            "ghost": bool(fitted_views < 2 or len(alive) < F / 2)}
    views = {name: {k: v[k] for k in ("people_per_frame", "person_ids", "seconds_per_frame", "resolution",
                                      "left_right_mirrored") if k in v}
             for name, v in head["views"].items()}
    for v in views.values():
        counts = v.get("people_per_frame", [])
        v["frames_with_fewer_people"] = int(sum(n < 2 for n in counts))
        v.pop("people_per_frame", None)
    result_lr = left_right_check(names, frames, det, proj, live, idx, head)
    mets = json.loads((run / "metrics.json").read_text()) if (run / "metrics.json").is_file() else {}
    result = {"detect": str(detect), "run": str(run), "frames": F, "views": views, "tracks": tracks,
              "identity_switches": sum(_runs(t["switch_frames"]) for t in tracks.values() if not t["ghost"]),
              "ghost_tracks": sum(t["ghost"] for t in tracks.values()),
              "left_right_check": result_lr,
              "tracker_reprojection_px_per_person": mets.get("reprojection_px_per_person")}
    return result, {"rig": rig, "names": names, "frames": frames, "det": det, "proj": proj, "live": live,
                    "ids": ids}


def _runs(frames: list[int]) -> int:
    """Number of runs of consecutive frames (a switch and its switch back count once)."""
    return int(sum(1 for k, f in enumerate(frames) if k == 0 or frames[k - 1] != f - 1))


def contact_sheets(detect: Path, data: dict, out: Path, shown: list[int], scale: float = 0.3) -> list[Path]:
    """One PNG per view: the ``shown`` frames side by side, detections (thin skeletons, colour
    of the per-view id) and tracks (dots with a ring, colour of the track id) drawn over them."""
    bones = [(MP.index(a), MP.index(b)) for a, b in LAYOUT_BONES if a in MP and b in MP]
    paths = []
    for c, name in enumerate(data["names"]):
        video = match_videos(data["names"], detect / "videos")[c]
        cap = cv2.VideoCapture(str(video))
        tiles = []
        for f in shown:
            n = data["frames"][f]
            cap.set(cv2.CAP_PROP_POS_FRAMES, n)
            ok, img = cap.read()
            if not ok:
                continue
            pid, kps = data["det"][name, n]
            for i, kp in zip(pid, kps, strict=True):
                col = COLOURS[i % len(COLOURS)][::-1]
                for a, b in bones:
                    if kp[a, 2] >= 0.5 and kp[b, 2] >= 0.5:
                        cv2.line(img, tuple(np.int32(kp[a, :2])), tuple(np.int32(kp[b, :2])), col, 3)
                if kp[0, 2] >= 0.5:
                    x, y = np.int32(kp[0, :2])
                    cv2.putText(img, f"det {i}", (int(x) - 40, max(30, int(y) - 60)),
                                cv2.FONT_HERSHEY_SIMPLEX, 1.5, col, 3)
            for p, tid in enumerate(data["ids"]):
                if not data["live"][f, p]:
                    continue
                col = COLOURS[(tid + 3) % len(COLOURS)][::-1]
                px = data["proj"][f, p, c]
                for x, y in px[np.all(np.isfinite(px), axis=1)]:
                    cv2.circle(img, (int(x), int(y)), 9, (255, 255, 255), 3)
                    cv2.circle(img, (int(x), int(y)), 7, col, -1)
                head = px[np.all(np.isfinite(px), axis=1)]
                if len(head):
                    x, y = np.int32(head.mean(0))
                    cv2.putText(img, f"track {tid}", (int(x), int(y)), cv2.FONT_HERSHEY_SIMPLEX, 1.6,
                                (255, 255, 255), 6)
                    cv2.putText(img, f"track {tid}", (int(x), int(y)), cv2.FONT_HERSHEY_SIMPLEX, 1.6, col, 3)
            cv2.putText(img, f"{name} frame {n}", (20, 60), cv2.FONT_HERSHEY_SIMPLEX, 2, (255, 255, 255), 4)
            tiles.append(cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA))
        cap.release()
        path = out / f"contact_{name}.png"
        cv2.imwrite(str(path), np.hstack(tiles))
        paths.append(path)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("detect", type=Path, help="a mocap detect --people folder")
    ap.add_argument("run", type=Path, help="a mocap track tracker=marker_people run folder on it")
    ap.add_argument("--out", type=Path, default=Path("outputs/people_from_video"))
    ap.add_argument("--ghost-px", type=float, default=40.0,
                    help="a track fitting no detected person within this (median px) in 2+ views is a ghost")
    ap.add_argument("--show", type=int, nargs="*", default=None, help="frames of the contact sheets "
                                                                     "(default: 6 spread over the run)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    result, data = analyse(args.detect, args.run, args.ghost_px)
    F = result["frames"]
    shown = args.show if args.show is not None else [int(f) for f in np.linspace(0, F - 1, 6).round()]
    sheets = contact_sheets(args.detect, data, args.out, shown)
    rows = [cv2.imread(str(p)) for p in sheets]
    width = min(r.shape[1] for r in rows)
    every = np.vstack([cv2.resize(r, (width, round(r.shape[0] * width / r.shape[1])),
                                  interpolation=cv2.INTER_AREA) for r in rows])
    cv2.imwrite(str(args.out / "contact_all.png"), cv2.resize(every, None, fx=0.5, fy=0.5,
                                                              interpolation=cv2.INTER_AREA))
    result["contact_sheets"] = [str(p) for p in sheets] + [str(args.out / "contact_all.png")]
    (args.out / "people_from_video.json").write_text(json.dumps(result, indent=1))
    print(json.dumps({k: v for k, v in result.items() if k != "views"}, indent=1))
    for name, v in result["views"].items():
        print(name, v)


if __name__ == "__main__":
    main()

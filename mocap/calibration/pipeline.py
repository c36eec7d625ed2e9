"""``mocap calibrate`` as a function: check every input, compute intrinsics and extrinsics,
then write the calibration (ours and Pose2Sim's ``Calib.toml``), a report and a contact sheet
into a new folder, all at once at the end (nothing is half-written when something fails).
"""

from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocap.calibration.board_extrinsics import board_pose_matrix, calibrate_board_extrinsics
from mocap.calibration.boards import Board, detect_board
from mocap.calibration.bundle import project_points
from mocap.calibration.compare import compare_rigs, poses_of, rig_from_poses, transform_rig
from mocap.calibration.errors import CalibrationInputError
from mocap.calibration.intrinsics import IntrinsicsSettings, calibrate_intrinsics
from mocap.calibration.keypoints import read_view_keypoints
from mocap.calibration.known_points import calibrate_known_points, read_known_points
from mocap.calibration.methods import EXTRINSICS
from mocap.calibration.people import PeopleSettings, calibrate_from_keypoints, check_overlap
from mocap.calibration.report import Tile, contact_sheet, rms
from mocap.calibration.scale_floor import floor_frame, measured_height, measured_length
from mocap.calibration.sources import CameraSource, check_same_length, find_sources, frames
from mocap.cameras import Rig, load_calibration, save_calibration


@dataclass(frozen=True)
class CalibrateOptions:
    """What ``mocap calibrate`` was asked (see its --help)."""

    out: str
    intrinsics: str | None = None
    intrinsics_from: str | None = None
    board: Board = Board()
    extrinsics: str = "none"
    board_views: str | None = None
    points: str | None = None
    keypoints: str | None = None
    layout: str = "BODY_25B"
    height: float | None = None
    length: tuple[str, str, float] | None = None
    frames: int | None = None
    max_video_frames: int = 60
    compare: str | None = None
    overwrite: bool = False
    intrinsics_settings: IntrinsicsSettings = IntrinsicsSettings()
    people_settings: PeopleSettings = PeopleSettings()
    reference: int = 0
    log: object = field(default=print, repr=False)


def _key(s: str) -> str:
    return "".join(ch for ch in s.lower() if ch.isalnum())


def _match(names: list[str], sources: list[CameraSource], what: str) -> list[CameraSource]:
    by = {_key(s.name): s for s in sources}
    missing = [n for n in names if _key(n) not in by]
    if missing:
        raise CalibrationInputError(missing[0], f"has no {what} (found cameras {[s.name for s in sources]}): "
                                                "name the folders or files after the cameras")
    return [by[_key(n)] for n in names]


def check_options(o: CalibrateOptions) -> None:
    """Every check that needs no work, in the order a user meets them."""
    out = Path(o.out)
    if out.exists() and not o.overwrite:
        raise FileExistsError(f"output folder {out} exists: choose another or pass --overwrite")
    if (o.intrinsics is None) == (o.intrinsics_from is None):
        raise ValueError("give exactly one of --intrinsics FOLDER (board images or videos per camera) and "
                         "--intrinsics-from CALIBRATION")
    if o.extrinsics not in EXTRINSICS:
        raise ValueError(f"--extrinsics must be one of {', '.join(EXTRINSICS)}, got {o.extrinsics!r}")
    need = {"board": ("board_views", "--board-views FOLDER"), "points": ("points", "--points FILE"),
            "people": ("keypoints", "--keypoints FOLDER")}
    if o.extrinsics in need and getattr(o, need[o.extrinsics][0]) is None:
        raise ValueError(f"--extrinsics {o.extrinsics} needs {need[o.extrinsics][1]}")
    if o.height is not None and o.length is not None:
        raise ValueError("give --height or --length, not both")
    if o.height is not None and not o.height > 0:
        raise ValueError(f"--height must be positive (metres), got {o.height}")
    if o.length is not None and not o.length[2] > 0:
        raise ValueError(f"--length must be positive (metres), got {o.length[2]}")
    if o.frames is not None and o.frames < 1:
        raise ValueError(f"--frames must be at least 1, got {o.frames}")
    for name in ("intrinsics_from", "points", "compare"):
        p = getattr(o, name)
        if p is not None and not Path(p).is_file():
            raise FileNotFoundError(f"--{name.replace('_', '-')}: file not found: {p}")
    for name in ("intrinsics", "board_views", "keypoints"):
        p = getattr(o, name)
        if p is not None and not Path(p).is_dir():
            raise FileNotFoundError(f"--{name.replace('_', '-')}: folder not found: {p}")


def _detect(source: CameraSource, board: Board, max_frames: int):
    found, first = {}, None
    for key, label, img in frames(source, max_frames):
        d = detect_board(img, board)
        if d is not None:
            found[key] = (label, d)
            if first is None:
                first = (key, img)
    return found, first


def run_calibration(o: CalibrateOptions) -> dict:
    """Calibrate as ``o`` says; returns the report (also written as report.json)."""
    log = o.log
    check_options(o)
    # --- open every input before any work --------------------------------------------------
    intr_sources = find_sources(o.intrinsics) if o.intrinsics else None
    given = load_calibration(o.intrinsics_from) if o.intrinsics_from else None
    names = [s.name for s in intr_sources] if intr_sources else list(given.names)
    view_sources = None
    if o.extrinsics == "board":
        view_sources = _match(names, find_sources(o.board_views), "board views")
        check_same_length(view_sources)
    known = read_known_points(o.points) if o.extrinsics == "points" else None
    keypoints = None
    if o.extrinsics == "people":
        keypoints = read_view_keypoints(o.keypoints, names, o.layout, o.people_settings.min_confidence,
                                        o.frames)
        check_overlap(names, keypoints.flat()[1] >= o.people_settings.min_confidence,
                      o.people_settings.min_shared)
    reference = load_calibration(o.compare) if o.compare else None
    report: dict = {"cameras": names, "board": o.board.describe(), "extrinsics": o.extrinsics}
    tiles: list[Tile] = []
    # --- intrinsics -------------------------------------------------------------------------
    if intr_sources:
        detections = []
        for s in intr_sources:
            log(f"{s.name}: looking for the board in {s.frames} {'frames' if s.video else 'images'}")
            found, first = _detect(s, o.board, o.max_video_frames)
            if not found:
                raise CalibrationInputError(
                    s.name, f"the board ({o.board.describe()}) was not found in any of its {s.frames} "
                            "images: check --board (inner corners, not squares) and that the whole board is "
                            "in view")
            detections.append((found, first))
        results = []
        for s, (found, _) in zip(intr_sources, detections, strict=True):
            views = {label: d for label, d in found.values()}
            results.append(calibrate_intrinsics(s.name, views, o.board, s.size, o.intrinsics_settings))
        K = np.stack([r.K for r in results])
        dist = np.stack([r.dist for r in results])
        sizes = [s.size for s in intr_sources]
        report["intrinsics"] = {r.camera: {"K": r.K.tolist(), "dist": r.dist.tolist(), "rms_px": r.rms,
                                           "views_px": r.view_errors, "dropped_views_px": r.dropped}
                                for r in results}
        for s, r, (found, first) in zip(intr_sources, results, detections, strict=True):
            label, (corners, ids) = found[first[0]]
            if label in r.poses:
                rv, tv = r.poses[label]
                X = o.board.object_points()[ids]
                pred = project_points(np.repeat(rv[None], len(X), 0), np.repeat(tv[None], len(X), 0), X,
                                      np.repeat(r.K[None], len(X), 0), np.repeat(r.dist[None], len(X), 0))
                tiles.append(Tile(f"{s.name} intrinsics {label}: {r.view_errors[label]:.2f} px", s.size,
                                  corners, pred, first[1]))
    else:
        K, dist = given.K.copy(), given.dist.copy()
        sizes = [tuple(int(v) for v in s) for s in given.sizes]
    # --- extrinsics -------------------------------------------------------------------------
    cams = np.zeros((len(names), 6))
    per_camera: dict[str, dict] = {n: {} for n in names}
    if o.extrinsics == "board":
        dets, firsts = [], []
        for s in view_sources:
            log(f"{s.name}: looking for the board in the synchronised {'video' if s.video else 'images'}")
            found, first = _detect(s, o.board, o.max_video_frames)
            if not found:
                raise CalibrationInputError(
                    s.name, "the board was not found in any of its synchronised views: every camera must see "
                            "the board at least once with another")
            dets.append({k: d for k, (_, d) in found.items()})
            firsts.append(first)
        res = calibrate_board_extrinsics(names, K, dist, o.board, dets, o.reference)
        cams = res.cams
        for (c, f), r in res.residuals.items():
            per_camera[names[c]][f"frame {int(f)}"] = rms(r)
        for c, n in enumerate(names):
            f = firsts[c][0]
            if (c, f) in res.residuals:
                obs = dets[c][f][0]
                tiles.append(Tile(f"{n} board frame {int(f)}: {rms(res.residuals[(c, f)]):.2f} px", sizes[c],
                                  obs, obs + res.residuals[(c, f)], firsts[c][1]))
        report["board_poses"] = {f: board_pose_matrix(p).tolist() for f, p in res.boards.items()}
    elif o.extrinsics == "points":
        cams, residuals = calibrate_known_points(names, K, dist, known)
        by = {_key(k): v for k, v in known.items()}
        for c, n in enumerate(names):
            X, uv, pnames = by[_key(n)]
            per_camera[n] = {p: float(np.linalg.norm(r)) for p, r in zip(pnames, residuals[c], strict=True)}
            tiles.append(Tile(f"{n} known points: {rms(residuals[c]):.2f} px", sizes[c], uv,
                              uv + residuals[c]))
    elif o.extrinsics == "people":
        xy, conf = keypoints.flat()
        log(f"people: {len(keypoints.frames)} frames x {len(keypoints.labels)} keypoints in {len(names)} "
            "views; essential matrices, then bundle adjustment")
        res = calibrate_from_keypoints(names, K, dist, xy, conf, o.people_settings)
        F, Kk = len(keypoints.frames), len(keypoints.labels)
        rig0 = rig_from_poses(names, K, dist, sizes, res.cams)
        points = res.points.reshape(F, Kk, 3)
        Rf, tf, how = floor_frame(points, keypoints.labels, rig0.R)
        report["floor_from"] = how
        pts = points @ Rf.T + tf
        if o.height is not None:
            s = o.height / measured_height(pts, keypoints.labels)
            report["scale_from"] = f"height {o.height} m"
        elif o.length is not None:
            s = o.length[2] / measured_length(pts, keypoints.labels, o.length[0], o.length[1])
            report["scale_from"] = f"length {o.length[0]}-{o.length[1]} {o.length[2]} m"
        else:
            s = 1.0
            report["scale_from"] = "none: units are arbitrary (give --height or --length)"
        rig1 = transform_rig(rig0, s, Rf, s * tf)
        cams = poses_of(rig1)
        report["pairs_inliers"] = [[names[i], names[j], n] for i, j, n in res.pairs]
        err = np.linalg.norm(res.residuals, axis=-1)
        for c, n in enumerate(names):
            e = np.where(res.used[c], err[c], np.nan).reshape(F, Kk)
            per_camera[n] = {f"frame {int(fr)}": float(np.sqrt(np.nanmean(e[i] ** 2)))
                             for i, fr in enumerate(keypoints.frames) if np.isfinite(e[i]).any()}
            u = res.used[c].reshape(F, Kk).copy()
            u[np.arange(F) % max(1, F // 8) != 0] = False            # every eighth of the frames
            u = u.ravel()
            tiles.append(Tile(f"{n} keypoints: median {np.nanmedian(err[c][res.used[c]]):.1f} px, 8 frames",
                              sizes[c], xy[c][u], xy[c][u] + res.residuals[c][u]))
        report["keypoints_used"] = {n: int(res.used[c].sum()) for c, n in enumerate(names)}
    rig = rig_from_poses(names, K, dist, sizes, cams)
    if o.extrinsics != "none":
        report["extrinsics_px"] = {n: {"rms_px": rms(np.array([[v, 0.0] for v in per_camera[n].values()]))
                                       if per_camera[n] else float("nan"), "views_px": per_camera[n]}
                                   for n in names}
    if reference is not None:
        cmp = compare_rigs(rig, reference, poses=o.extrinsics != "none")
        def per_camera_values(values: np.ndarray) -> dict[str, float]:
            return dict(zip(cmp.names, values.tolist(), strict=True))
        report["compare"] = {"reference": str(o.compare), "table": cmp.table(), "scale": cmp.scale,
                             "centre_error_m": per_camera_values(cmp.centre_error),
                             "rotation_error_deg": per_camera_values(cmp.rotation_error),
                             "focal_error": per_camera_values(cmp.focal_error),
                             "principal_point_error_px": per_camera_values(cmp.principal_point_error)}
    _write(Path(o.out), rig, report, tiles, o.overwrite)
    return report


def _write(out: Path, rig: Rig, report: dict, tiles: list[Tile], overwrite: bool) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    # a new folder of an unpredictable name beside ``out`` (never a planted one), renamed at the end
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        tmp.chmod(0o755)                    # mkdtemp's 0700 would stay on the output folder
        save_calibration(rig, tmp / "calibration.json")
        save_calibration(rig, tmp / "Calib.toml", format="pose2sim")
        (tmp / "report.json").write_text(json.dumps(report, indent=1))
        if tiles:
            contact_sheet(tiles, tmp / "contact_sheet.png")
        if out.exists() and overwrite:
            shutil.rmtree(out)
        tmp.rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)      # a failed write leaves nothing half made


def summary(report: dict) -> str:
    """Lines for the terminal."""
    lines = []
    for n, r in report.get("intrinsics", {}).items():
        K = np.array(r["K"])
        drop = ", dropped " + ", ".join(f"{v} ({e:.2f} px)" for v, e in r["dropped_views_px"].items()) \
            if r["dropped_views_px"] else ""
        lines.append(f"{n}: intrinsics from {len(r['views_px'])} views, RMS {r['rms_px']:.3f} px, "
                     f"f = {K[0, 0]:.1f} {K[1, 1]:.1f} px, c = {K[0, 2]:.1f} {K[1, 2]:.1f} px{drop}")
    for n, r in report.get("extrinsics_px", {}).items():
        lines.append(f"{n}: extrinsics ({report['extrinsics']}) reprojection RMS {r['rms_px']:.2f} px over "
                     f"{len(r['views_px'])} views")
    if "floor_from" in report:
        lines.append(f"floor: {report['floor_from']}")
    if "scale_from" in report:
        lines.append(f"scale: {report['scale_from']}")
    if "compare" in report:
        lines.append(f"against {report['compare']['reference']} (after a similarity alignment):")
        lines.append(report["compare"]["table"])
    return "\n".join(lines)

"""The catalogue of files from others and faults (issue 36): each case builds a bad input or a
fault in a temporary folder and does what a user would (a library call, or ``mocap`` in-process),
and its outcome is classified:

    refused   an exception (or a non-zero ``mocap`` exit) with one line holding the case's words
    flagged   the call went on, with a warning / a problem line holding the case's words
    unclear   refused, but with a traceback-style error (TypeError, KeyError...), several lines,
              or a message without the words (the file, field or name is not named)
    silent    accepted without a word, or it hung, or a file outside the case's output was touched

The security cases also fail when any file outside what the command may write changes (the
whole temporary tree is listed before and after) or when a function outside the registry is
reached. Only interfaces that exist on ``main`` are imported at module level, so the same
catalogue runs against the code before this work (``python -m tests.safety.catalogue``, the
"before -> after" figures of the issue's report).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import shutil
import subprocess
import sys
import threading
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tests.safety.helpers import tree

#: the longest a case may take before it counts as a hang
HANG_S = 20.0
#: an absolute camera name of the path cases; what it would reach is checked too (and removed)
ABS_NAME = "/tmp/mocap_catalogue_abs"
#: what a case returns where it cannot be made here (e.g. a read-only folder for root)
NOT_APPLICABLE = "not applicable for this user"
#: exceptions that are a program's, not a refusal of the input
PROGRAM_ERRORS = (TypeError, AttributeError, IndexError, ZeroDivisionError, AssertionError, NameError,
                  RecursionError, MemoryError, OverflowError, UnboundLocalError)


class Refused(Exception):
    """A ``mocap`` command that exited non-zero: its stderr."""

    def __init__(self, code: int, err: str):
        super().__init__(err)
        self.code = code


@dataclass(frozen=True)
class Case:
    category: str
    name: str
    action: Callable[[Path], object]      # the user's call in a fresh folder; may return a flag line
    #                                       (watch cases: prepares the folder, returns the call)
    words: tuple[str, ...]                # what the line must name (case-insensitive)
    expect: str = "refused"               # refused | flagged
    watch: bool = False                   # security: the tree outside <tmp>/out must not change


def cli(*argv: str) -> str:
    """``mocap <argv>`` in-process; raises :class:`Refused` on a non-zero exit, else returns
    stderr (a flag may be there)."""
    from mocap_cli.main import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(list(argv))
    if code:
        raise Refused(code, err.getvalue())
    return err.getvalue()


def _one_line(text: str) -> list[str]:
    return [ln for ln in str(text).splitlines() if ln.strip() and "%|" not in ln]


def classify(case: Case, tmp: Path) -> tuple[str, str]:
    """(outcome, the line seen) of one case run in ``tmp``."""
    tmp.mkdir(parents=True, exist_ok=True)
    box: dict = {}

    def work():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                box["value"] = case.action(tmp)
            except BaseException as exc:       # noqa: BLE001 (classified below)
                box["exc"] = exc
            box["warnings"] = [str(w.message) for w in caught]

    before = None
    if case.watch:
        for p in (Path(ABS_NAME), Path(ABS_NAME + "_json")):
            shutil.rmtree(p, ignore_errors=True)
        call = case.action(tmp)
        before = tree(tmp)
        case = Case(case.category, case.name, lambda _tmp: call(), case.words, case.expect, case.watch)
    t = threading.Thread(target=work, daemon=True)
    t.start()
    t.join(HANG_S)
    if t.is_alive():
        return "silent", f"hung for more than {HANG_S:g} s"
    if case.watch:
        reached = [p for p in (Path(ABS_NAME), Path(ABS_NAME + "_json")) if p.exists()]
        for p in reached:
            shutil.rmtree(p, ignore_errors=True)
        if reached:
            return "silent", f"wrote outside its output: {[str(p) for p in reached]}"
        after = tree(tmp)
        changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k)
                         and not k.startswith("out"))
        if changed:
            return "silent", f"touched outside its output: {changed[:3]}"
    words = [w.lower() for w in case.words]
    exc = box.get("exc")
    if exc is not None:
        if isinstance(exc, Refused):
            lines = [ln for ln in _one_line(str(exc)) if "not complete, no manifest" not in ln]
            text = lines[-1] if lines else ""
            clear = len(lines) == 1 and "Traceback" not in str(exc)
        else:
            text = str(exc)
            clear = len(_one_line(text)) == 1 and not isinstance(exc, PROGRAM_ERRORS) \
                and not isinstance(exc, (ImportError, KeyError))
            if isinstance(exc, ImportError):
                return "silent", f"feature absent ({exc})"
        if clear and all(w in text.lower() for w in words):
            return "refused", text
        return "unclear", f"{type(exc).__name__}: {text[:300]}"
    if box.get("value") is NOT_APPLICABLE:
        return "n/a", NOT_APPLICABLE
    seen = [str(box.get("value") or "")] + box.get("warnings", [])
    for line in seen:
        if line and all(w in line.lower() for w in words):
            return "flagged", line
    return "silent", "accepted: " + " | ".join(s[:120] for s in seen if s)[:300]


# --- the inputs -----------------------------------------------------------------------------


_SEQ: dict[str, Path] = {}


def base_sequence() -> Path:
    """A 2-frame synthetic sequence folder (masks, labelled detections, ground truth), made once."""
    if "seq" not in _SEQ:
        import tempfile

        from mocap.body import load_body
        from mocap.data.sequence_io import write_sequence
        from mocap.data.sources import synthetic_sequence

        body = load_body("paper22")
        seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=2, fps=25, seed=0,
                                 name="tiny", shape_scale=0.8, masks=True, images=False,
                                 detections={"enabled": True, "detection_rate": 1.0,
                                             "false_positive_rate": 0.0,
                                             "noise_px": 1.0, "labelled": True, "occlusion": False})
        _SEQ["seq"] = write_sequence(seq, Path(tempfile.mkdtemp(prefix="mocap_catalogue_")) / "tiny")
    return _SEQ["seq"]


def seq_variant(tmp: Path, file: str, change: Callable[[dict], None]) -> Path:
    d = tmp / "seq"
    shutil.copytree(base_sequence(), d)
    data = json.loads((d / file).read_text())
    change(data)
    (d / file).write_text(json.dumps(data))
    return d


def load_variant(file: str, change: Callable[[dict], None]) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.data.sequence_io import load_sequence

        return load_sequence(seq_variant(tmp, file, change), images=False)
    return act


def setter(key: str, value) -> Callable[[dict], None]:
    def change(d: dict):
        d[key] = value
    return change


def rig_with(names) -> object:
    from mocap.cameras import ring_rig

    return ring_rig(len(names), 3.5, 1.5, 64, 48, fov_deg=45.0, names=list(names))


def calib_file(tmp: Path, names, suffix: str) -> Path:
    from mocap.cameras import calibration_io as cio

    rig = rig_with(names)
    path = tmp / f"calib{suffix}"
    if suffix == ".toml":
        cio.write_pose2sim_calibration(rig, path)
    elif suffix == ".xml":
        cio.write_opencv_calibration(rig, path)
    else:
        cio.write_mocap_calibration(rig, path)
    return path


def load_calib(names, suffix: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.cameras import load_calibration

        return load_calibration(calib_file(tmp, names, suffix))
    return act


def pose2sim_recording(root: Path, names) -> Path:
    """Calib.toml, videos/ and pose/ (one empty frame per camera)."""
    from mocap.cameras import write_pose2sim_calibration

    root.mkdir(parents=True)
    write_pose2sim_calibration(rig_with(names), root / "Calib.toml")
    (root / "videos").mkdir()
    for i in range(len(names)):
        (root / "videos" / f"cam{i}.mp4").write_bytes(b"")
        d = root / "pose" / f"cam{i}_json"
        d.mkdir(parents=True)
        (d / f"cam{i}.000000.json").write_text(json.dumps({"people": []}))
    return root


GOOD_BODY = {"_target_": "mocap.body.load_body", "name": "paper22"}
GOOD_DATA = {"_target_": "mocap.data.sources.synthetic_sequence", "cameras": "ring4_small", "motion": "walk",
             "frames": 2, "fps": 25, "seed": 0, "name": "x", "images": False}


def evil_run(tmp: Path, config: dict) -> Path:
    from mocap.run_folder.manifest import write_manifest

    d = tmp / "out" / "run"
    d.mkdir(parents=True)
    shutil.copy(real_motion(), d / "motion.npz")     # (a real one: the code before read it first)
    (d / "metrics.json").write_text(json.dumps({"tracker": "apf", "mpjpe_mm": 20.0, "config": config}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


def real_motion() -> Path:
    """A valid 2-frame motion.npz of the paper22 body, made once."""
    if "motion" not in _SEQ:
        import tempfile

        from mocap.body import load_body
        from mocap.export.motion import motion_arrays, write_motion
        from mocap.trackers.base import Estimate

        body = load_body("paper22")
        ests = [Estimate(np.zeros(body.num_dofs, np.float32), np.zeros(body.num_shape, np.float32), {})
                for _ in range(2)]
        path = Path(tempfile.mkdtemp(prefix="mocap_catalogue_")) / "motion.npz"
        write_motion(path, motion_arrays(body, ests, [0.0, 0.0], 25.0))
        _SEQ["motion"] = path
    return _SEQ["motion"]


def evil_configs(victim: Path) -> dict[str, dict]:
    """Stored configs that name something outside the registry (or misuse a registered one), by label."""
    write = {"_target_": "mocap.run_folder.read.write_json", "path": str(victim / "written.json"),
             "data": {"owned": True}}
    drop = {"_target_": "mocap.run_folder.resume.drop_previous", "out_dir": str(victim)}
    git = {"_target_": "mocap.run_folder.metadata.git_revision", "source": str(victim)}
    return {
        "body=run_folder.read.write_json": {"body": write, "data": GOOD_DATA},
        "data=run_folder.read.write_json": {"body": GOOD_BODY, "data": write},
        "body=run_folder.resume.drop_previous": {"body": drop, "data": GOOD_DATA},
        "data=run_folder.metadata.git_revision": {"body": GOOD_BODY, "data": git},
        "body=os.system": {"body": {"_target_": "os.system", "command": f"touch {victim}/pwned"},
                           "data": GOOD_DATA},
        "body=mocap.presets.build(write_json)": {"body": {"_target_": "mocap.presets.build", "config": write},
                                                 "data": GOOD_DATA},
        "data.cameras=write_json": {"body": GOOD_BODY, "data": {**GOOD_DATA, "cameras": write}},
        "body=a data source": {"body": {**GOOD_DATA}, "data": GOOD_DATA},
        "body with an unknown setting": {"body": {**GOOD_BODY, "path": str(victim / "x")}, "data": GOOD_DATA},
        "_target_ as a list": {"body": {"_target_": ["mocap.run_folder.read", "write_json"]},
                               "data": GOOD_DATA},
        "body=shutil.rmtree": {"body": {"_target_": "shutil.rmtree", "path": str(victim)}, "data": GOOD_DATA},
        "extra.a[0].b=write_json (deep)": {"body": GOOD_BODY, "data": GOOD_DATA,
                                           "extra": {"a": [{"b": write}]}},
        "body=mocap.__builtins__.eval": {"body": {"_target_": "mocap.__builtins__.eval", "source": "1"},
                                         "data": GOOD_DATA},
        "body=mocap.export.export_run": {"body": {"_target_": "mocap.export.export_run",
                                                  "run_dir": str(victim),
                                                  "fmt": "bvh"}, "data": GOOD_DATA},
    }


def security_case(what: str, command: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        victim = tmp / "victim"
        victim.mkdir()
        (victim / "keep.txt").write_text("precious")
        (victim / "previous_run").mkdir()
        run = evil_run(tmp, evil_configs(victim)[what])
        argv = {"rescore --dry-run": ["rescore", str(run), "--dry-run"], "rescore": ["rescore", str(run)],
                "export gltf": ["export", str(run), "--format", "gltf", "--out", str(tmp / "out" / "m.glb")]}
        return lambda: cli(*argv[command])
    return act


def bvh_text(value: str = "0.0", offset: str = "0.0", frame_time: str = "0.0333333", frames: int = 2) -> str:
    rows = "\n".join(" ".join(["0.0"] * 6 + [value if f == frames - 1 else "0.0"] + ["0.0"] * 2)
                     for f in range(frames))
    return ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0.0 0.0 0.0\n"
            "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            f"  JOINT Chest\n  {{\n    OFFSET 0.0 {offset} 0.0\n"
            "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
            "    End Site\n    {\n      OFFSET 0.0 10.0 0.0\n    }\n  }\n}\n"
            f"MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n{rows}\n")


def read_bvh_text(text: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.clips.bvh import read_bvh

        p = tmp / "clip.bvh"
        p.write_text(text)
        return read_bvh(p, unit="cm", up="y")
    return act


def complete_run(d: Path, content: bytes = b"m") -> Path:
    from mocap.run_folder.manifest import write_manifest

    d.mkdir(parents=True, exist_ok=True)
    (d / "motion.npz").write_bytes(content)
    (d / "metrics.json").write_text(json.dumps({"config": {}}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


def manifest_case(change: Callable[[Path, dict], None]) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.run_folder.manifest import manifest_problem

        run = complete_run(tmp / "out" / "run")
        m = json.loads((run / "manifest.json").read_text())
        change(tmp, m)
        (run / "manifest.json").write_text(json.dumps(m))
        problem = manifest_problem(run)
        if problem is None:
            return ""
        return problem
    return act


def add_entry(name: str):
    def change(tmp: Path, m: dict):
        outside = tmp / "outside.bin"
        outside.write_bytes(b"x")
        import hashlib

        m["files"][name if "{tmp}" not in name else name.format(tmp=tmp)] = {
            "bytes": 1, "sha256": hashlib.sha256(b"x").hexdigest()}
    return change


def leftover_case(kind: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.run_folder.attempt import tidy_leftovers
        from mocap.run_folder.manifest import manifest_problem

        run = complete_run(tmp / "out" / "run", b"earlier")
        if kind.startswith("temporary"):
            (run / kind.split(" ", 1)[1]).write_bytes(b"half")
            tidy_leftovers(run)
            left = sorted(p.name for p in run.iterdir())
            return "" if left != ["manifest.json", "metrics.json", "motion.npz"] else "leftover removed"
        if kind.startswith("half-moved"):
            n = int(kind[-1])
            half = run / "previous_run.tmp"
            half.mkdir()
            for name in ["motion.npz", "metrics.json", "manifest.json"][:n]:
                (run / name).replace(half / name)
            tidy_leftovers(run)
            return "leftover restored" if manifest_problem(run) is None and not half.exists() else ""
        complete_run(run / "previous_run", b"older")
        tidy_leftovers(run)
        return "" if (run / "previous_run").exists() else "leftover removed"
    return act


def recording_fault(how: str) -> Callable[[Path], object]:
    """A RerunSink whose writer blocks or fails at the end of the run."""
    def act(tmp: Path):
        import errno

        import rerun as rr

        from mocap.body import load_body
        from mocap.data.sources import synthetic_sequence
        from mocap.recording import rerun_sink
        from mocap.recording.factory import RecordingSettings
        from mocap.recording.sink import RunInfo

        body = load_body("paper22")
        seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=1, fps=25, seed=0,
                                 masks=False, images=False)
        old = getattr(rerun_sink, "WRITE_TIMEOUT_S", None)
        if old is not None:
            rerun_sink.WRITE_TIMEOUT_S = 1.0
        sink = rerun_sink.RerunSink(tmp / "out" / "recording.rrd", RecordingSettings(level="summary"))
        sink.start(RunInfo("x: 1", {"run_id": "x"}), body, seq)
        real = sink.rec

        class Faulty:
            def __getattr__(self, name):
                return getattr(real, name)

            def flush(self, *a, **k):
                if how == "blocks":
                    threading.Event().wait()
                raise OSError(errno.ENOSPC, "No space left on device")

        sink.rec = Faulty()
        try:
            sink.finish({"mpjpe_mm": 1.0})
        finally:
            if old is not None:
                rerun_sink.WRITE_TIMEOUT_S = old
        del rr
        return ""
    return act


def lock_case(kind: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        import os

        from mocap.run_folder.lock import run_lock
        run = tmp / "out" / "run"
        code = ("import sys; from mocap.run_folder.lock import run_lock\n"
                f"with run_lock({str(run)!r}):\n    print('held', flush=True); sys.stdin.read()\n")
        env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
        p = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env)
        try:
            if p.stdout.readline().strip() != "held":
                raise ImportError(p.stderr.read()[-300:])
            if kind == "second writer":
                with run_lock(run):
                    return ""
            from mocap.run_folder.manifest import write_manifest
            (run / "motion.npz").write_bytes(b"m")
            (run / "metrics.json").write_text("{}")
            write_manifest(run, ["motion.npz", "metrics.json"])
            return ""
        finally:
            p.stdin.close()
            p.wait(30)
    return act


def gt_person_names(names) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.data.sequence_io import load_ground_truth

        P, F, J = len(names), 2, 3
        path = tmp / "gt.npz"
        np.savez(path, joints=np.zeros((F, P, J, 3)), joint_names=np.array(["a", "b", "c"]),
                 person_names=np.array(names, dtype=str), body=np.array(""), skeleton=np.array(""))
        return load_ground_truth(path, F)
    return act


def detect_case(names) -> Callable[[Path], object]:
    def act(tmp: Path):
        rec = pose2sim_recording(tmp / "rec", names)
        return lambda: cli("detect", str(rec), "--out", str(tmp / "out" / "det"), "--no-progress")
    return act


def convert_case(names, *extra, watch: bool = True) -> Callable[[Path], object]:
    def act(tmp: Path):
        rec = pose2sim_recording(tmp / "rec", names)
        call = lambda: cli("convert", str(rec), str(tmp / "out" / "seq"), *extra)  # noqa: E731
        return call if watch else call()
    return act


def write_sequence_case(name: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        from dataclasses import replace

        from mocap.body import load_body
        from mocap.cameras import Rig
        from mocap.data.sequence_io import write_sequence
        from mocap.data.sources import synthetic_sequence

        seq = synthetic_sequence(body=load_body("paper22"), cameras="ring4_small", motion="walk", frames=1,
                                 fps=25, seed=0, masks=True, images=False)
        cams = list(seq.rig.cameras)
        cams[1] = replace(cams[1], name=name)
        bad = replace(seq, rig=Rig(tuple(cams)))
        return lambda: write_sequence(bad, tmp / "out" / "seq")
    return act


def synthetic_fps(fps) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.body import load_body
        from mocap.data.sources import synthetic_sequence

        return synthetic_sequence(body=load_body("paper22"), cameras="ring4_small", motion="walk", frames=2,
                                  fps=fps, seed=0, masks=False, images=False)
    return act


def read_only_case(kind: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        import os

        from mocap.run_folder.read import write_json
        d = tmp / "out"
        d.mkdir()
        os.chmod(d, 0o500)
        try:
            if os.access(d, os.W_OK):          # (root writes anyway: nothing to check)
                return NOT_APPLICABLE
            write_json(d / "metrics.json", {"a": 1})
            return ""
        finally:
            os.chmod(d, 0o700)
    return act


# --- the catalogue --------------------------------------------------------------------------

BAD_NAMES = ["../x", "../../x", "/tmp/x", "a/b", "a\\b", "..", ".hidden", "x" * 300, "a:b", "cam\n1"]


def cases() -> list[Case]:
    out: list[Case] = []
    add = out.append
    # calibration files: camera names that are paths, in every format
    for suffix in (".json", ".yaml", ".toml", ".xml"):
        for bad in BAD_NAMES:
            add(Case("calibration", f"{suffix} camera {bad[:12]!r}", load_calib(["cam_a", bad], suffix),
                     (f"calib{suffix}", "camera name")))
    add(Case("calibration", "image side 10^6 px", load_calib_size(10 ** 6), ("calib.json", "image size")))
    # sequence.json: every field's type and range
    seqj = "sequence.json"
    for field, value, words in [
            ("frames", None, ("frames",)), ("frames", "3", ("frames",)), ("frames", -1, ("frames",)),
            ("frames", 2.5, ("frames",)), ("frames", 10 ** 12, ("frames",)), ("frames", True, ("frames",)),
            ("frames", 5, ("frames", "5")), ("fps", 0, ("fps",)), ("fps", -25, ("fps",)),
            ("fps", math.nan, ("fps",)), ("fps", 1e308, ("fps",)), ("fps", "25", ("fps",)),
            ("fps", None, ("fps",)),
            ("fps", math.inf, ("fps",)), ("views", "cam_00", ("views",)), ("views", [1, 2, 3, 4], ("views",)),
            ("views", ["cam_00", "../../x", "cam_02", "cam_03"], ("views", "../../x")),
            ("views", ["cam_00", "/etc", "cam_02", "cam_03"], ("views", "/etc")),
            ("views", ["cam_00", "cam_00", "cam_02", "cam_03"], ("views", "cam_00")),
            ("image_size", [0, 0], ("image_size",)), ("image_size", [-1, 5], ("image_size",)),
            ("image_size", "640x480", ("image_size",)), ("image_size", [10 ** 9, 10 ** 9], ("image_size",)),
            ("image_size", [640], ("image_size",)), ("image_size", [64.5, 48], ("image_size",)),
            ("content", ["masks"], ("content",)), ("content", "masks", ("content",)),
            ("content", {"masks": "yes"}, ("content",)), ("name", 123, ("name",)), ("meta", [1], ("meta",)),
            ("format", "other", ("format",))]:
        add(Case("sequence folder", f"{field} = {value!r}"[:50], load_variant(seqj, setter(field, value)),
                 (seqj, *words)))
    add(Case("sequence folder", "sequence.json a list", load_variant(seqj, lambda d: d.clear()),
             (seqj,)))
    add(Case("sequence folder", "mask folder of a view missing", missing_masks, ("masks", "cam_01")))
    # detections.json
    detj = "detections.json"
    for field, value, words in [
            ("labels", 5, ("labels",)), ("labels", [1, 2], ("labels",)),
            ("labels", ["../x"], ("labels", "../x")),
            ("labels", None, ("labels",)), ("columns", ["frame"], ("columns",)), ("rows", "none", ("rows",)),
            ("rows", [[0, 0, 0, 1.0]], ("rows",)), ("rows", [[0, 9, 0, 1, 1, 1]], ("rows", "view")),
            ("rows", [[7, 0, 0, 1, 1, 1]], ("rows", "frame")),
            ("rows", [[0, 0, 99, 1, 1, 1]], ("rows", "label")),
            ("rows", [[0, 0, 0, math.nan, 1, 1]], ("rows", "nan")),
            ("rows", [[0.5, 0, 0, 1, 1, 1]], ("rows",))]:
        add(Case("detections", f"{field} = {value!r}"[:50], load_variant(detj, setter(field, value)),
                 (detj, *words)))
    # ground truth: person names
    for bad in ("../x", "/abs", "a/b"):
        add(Case("several people", f"gt.npz person {bad!r}", gt_person_names(["p0", bad]),
                 ("gt.npz", "person_names")))
    add(Case("several people", "gt.npz person names repeated", gt_person_names(["p0", "p0"]),
             ("gt.npz", "person_names")))
    # security: code from a run folder's metrics.json
    for what in evil_configs(Path("/x")):
        for command in ("rescore --dry-run", "rescore", "export gltf"):
            add(Case("security", f"{command}: {what}", security_case(what, command),
                     ("metrics.json", "refused"), watch=True))
    # security: paths from names (detect, convert, write_sequence)
    for bad in ("../x", "../../x", ABS_NAME):
        add(Case("detect", f"detect camera {bad!r}", detect_case(["cam_a", bad, "cam_c"]),
                 ("calib.toml", "camera name"), watch=True))
        add(Case("import", f"convert camera {bad!r}", convert_case(["cam_a", bad, "cam_c"]),
                 ("calib.toml", "camera name"), watch=True))
        add(Case("folders", f"write_sequence camera {bad!r}", write_sequence_case(bad),
                 ("camera name", bad), watch=True))
    # manifests
    for name, change, words in [
            ("entry ../outside.bin", add_entry("../outside.bin"), ("manifest.json", "../outside.bin")),
            ("entry absolute", add_entry("{tmp}/outside.bin"), ("manifest.json", "outside.bin")),
            ("entry a/b", add_entry("a/b"), ("manifest.json", "a/b")),
            ("entry a list", lambda t, m: m["files"].update({"motion.npz": [1]}),
             ("manifest.json", "motion.npz")),
            ("files a list", lambda t, m: m.update(files=[]), ("manifest.json",)),
            ("format other", lambda t, m: m.update(format="x"), ("manifest.json",)),
            ("size changed", lambda t, m: m["files"]["motion.npz"].update(bytes=9), ("motion.npz", "bytes")),
            ("checksum changed", lambda t, m: m["files"]["motion.npz"].update(sha256="0"), ("motion.npz",)),
            ("metrics.json not listed", lambda t, m: m["files"].pop("metrics.json"), ("metrics.json",))]:
        add(Case("folders", f"manifest {name}", manifest_case(change), words, expect="flagged"))
    add(Case("folders", "manifest entry a symlink out", manifest_symlink, ("motion.npz", "link"),
             expect="flagged"))
    # imported motion (BVH)
    for name, text, words in [
            ("NaN channel", bvh_text(value="nan"), ("frame 1", "chest", "nan")),
            ("Inf channel", bvh_text(value="inf"), ("frame 1", "chest", "inf")),
            ("-Inf channel", bvh_text(value="-inf"), ("frame 1", "chest")),
            ("NaN OFFSET", bvh_text(offset="nan"), ("chest", "offset")),
            ("Frame Time 0", bvh_text(frame_time="0"), ("frame time",)),
            ("Frame Time -1", bvh_text(frame_time="-1"), ("frame time",)),
            ("Frame Time inf", bvh_text(frame_time="inf"), ("frame time",)),
            ("Frame Time nan", bvh_text(frame_time="nan"), ("frame time",)),
            ("value not a number", bvh_text(value="abc"), ("not a number",)),
            ("Frames says 3, 2 lines", bvh_text().replace("Frames: 2", "Frames: 3"), ("frames: 3",)),
            ("Frames says 10^12", bvh_text().replace("Frames: 2", "Frames: 1000000000000"), ("frames",))]:
        add(Case("import", f"BVH {name}", read_bvh_text(text), ("clip.bvh", *words)))
    for fps in ("0", "-30", "nan", "inf"):
        add(Case("import", f"import-motion --fps {fps}", import_fps(fps), ("--fps",)))
        add(Case("import", f"convert --fps {fps}",
                 convert_case(["cam_a", "cam_b", "cam_c"], "--fps", fps, watch=False),
                 ("fps",)))
    # fps wherever a sequence is made
    for fps in (0, -25, math.nan, math.inf, 1e308):
        add(Case("folders", f"synthetic fps {fps!r}", synthetic_fps(fps), ("fps",)))
    # kills at fixed points: what an interrupted run left, at the next start
    for kind in ("temporary .motion.npz.1234.tmp", "temporary .metrics.json.x1.tmp",
                 "temporary metrics.json.tmp",
                 "temporary manifest.json.tmp", "half-moved 1", "half-moved 2", "half-moved 3",
                 "previous_run beside complete"):
        add(Case("kills", kind, leftover_case(kind), ("leftover",), expect="flagged"))
    # concurrency
    add(Case("concurrency", "second writer", lock_case("second writer"), ("pid", "refused")))
    add(Case("concurrency", "manifest by a non-holder", lock_case("manifest"), ("pid", "manifest")))
    # disk full / failing write of the recording
    add(Case("disk full", "recording flush blocks", recording_fault("blocks"), ("recording.rrd", "within")))
    add(Case("disk full", "recording flush ENOSPC", recording_fault("enospc"), ("recording.rrd", "no space")))
    add(Case("read-only", "write_json into a read-only folder", read_only_case("json"), ("out",)))
    return out


def load_calib_size(side: int) -> Callable[[Path], object]:
    def act(tmp: Path):
        from mocap.cameras import load_calibration, ring_rig
        from mocap.cameras.calibration_io import write_mocap_calibration

        rig = ring_rig(2, 3.5, 1.5, side, 48, fov_deg=45.0)
        write_mocap_calibration(rig, tmp / "calib.json")
        data = json.loads((tmp / "calib.json").read_text())
        for cam in data["cameras"]:
            cam["K"][0][2] = side / 2
        (tmp / "calib.json").write_text(json.dumps(data))
        return load_calibration(tmp / "calib.json")
    return act


def missing_masks(tmp: Path):
    from mocap.data.sequence_io import load_sequence

    d = seq_variant(tmp, "sequence.json", lambda data: None)
    shutil.rmtree(d / "masks" / "cam_01")
    return load_sequence(d, images=False)


def manifest_symlink(tmp: Path):
    from mocap.run_folder.manifest import manifest_problem

    run = complete_run(tmp / "out" / "run")
    outside = tmp / "outside.npz"
    (run / "motion.npz").replace(outside)
    (run / "motion.npz").symlink_to(outside)
    return manifest_problem(run) or ""


def import_fps(fps: str) -> Callable[[Path], object]:
    def act(tmp: Path):
        p = tmp / "clip.bvh"
        p.write_text(bvh_text())
        return cli("import-motion", str(p), "--out", str(tmp / "out" / "run"), "--fps", fps, "--unit", "cm",
                   "--up", "y")
    return act


def main() -> int:
    """Run every case; print the outcome of each and the counts per category."""
    import collections
    import tempfile

    counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    root = Path(tempfile.mkdtemp(prefix="mocap_catalogue_run_"))
    rows = []
    for i, case in enumerate(cases()):
        outcome, line = classify(case, root / f"case{i:03d}")
        counts[case.category][outcome] += 1
        counts["all"][outcome] += 1
        rows.append({"category": case.category, "case": case.name, "expect": case.expect, "outcome": outcome,
                     "line": line[:300]})
        print(f"{outcome:8s} {case.category:16s} {case.name[:60]:60s} {line[:150]!r}", flush=True)
    print()
    for cat, c in counts.items():
        print(f"{cat:16s} " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))
    if len(sys.argv) > 1:
        Path(sys.argv[1]).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

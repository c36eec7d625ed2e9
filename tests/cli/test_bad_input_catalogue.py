"""The catalogue of bad inputs (issue 27): each one is refused with a non-zero exit and one
line ``mocap <command>: error: ...`` naming the setting / file and its value, or flagged (a
WARNING or a problem line, exit 1), and no run folder is left looking complete (a valid
manifest.json) for it. Commands run in-process (``mocap_cli.main.main``); the data are tiny
synthetic sequence folders (3 frames, no images) and hand-made run folders."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mocap.run_folder.manifest import MANIFEST, manifest_problem, write_manifest
from mocap_cli.main import main

FAST = ["tracker=apf", "data=walk_small", "data.frames=3", "tracker.particles=4", "tracker.layers=2",
        "recording.enabled=false"]


@pytest.fixture(scope="module")
def seq_folder(tmp_path_factory, body) -> Path:
    """A 3-frame synthetic sequence folder with ground truth and labelled detections."""
    from mocap.data.sequence_io import write_sequence
    from mocap.data.sources import synthetic_sequence

    seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=3, fps=25, seed=0,
                             name="tiny", shape_scale=0.8, masks=False, images=False,
                             detections={"enabled": True, "detection_rate": 1.0, "false_positive_rate": 0.0,
                                         "noise_px": 1.0, "labelled": True, "occlusion": False})
    return write_sequence(seq, tmp_path_factory.mktemp("seq") / "tiny")


def variant(seq_folder: Path, tmp: Path, what: str) -> Path:
    """A copy of the sequence folder with one bad value."""
    d = tmp / f"seq_{what}"
    shutil.copytree(seq_folder, d)
    if what in ("gt_nan", "gt_inf_chi"):
        with np.load(d / "gt.npz") as z:
            arrays = dict(z)
        if what == "gt_nan":
            arrays["joints"][1, 4, 2] = np.nan
        else:
            arrays["chi"][0, 3] = np.inf
        np.savez_compressed(d / "gt.npz", **arrays)
    else:
        det = json.loads((d / "detections.json").read_text())
        row, col, value = {"det_nan": (5, 3, float("nan")), "det_label": (7, 2, 99),
                           "det_view": (2, 1, 9), "det_frame": (4, 0, 17)}[what]
        det["rows"][row][col] = value
        (d / "detections.json").write_text(json.dumps(det))
    return d


def complete_run(d: Path, motion: bytes = b"motion") -> Path:
    """A hand-made run folder that is complete (files + manifest)."""
    (d / ".hydra").mkdir(parents=True, exist_ok=True)
    (d / ".hydra" / "overrides.yaml").write_text("- seed=0\n")
    (d / "motion.npz").write_bytes(motion)
    (d / "metrics.json").write_text(json.dumps({"tracker": "apf", "data": "walk_small", "seed": 0,
                                                "sec_per_frame": 1.0, "mpjpe_mm": 20.0, "config": {}}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


def incomplete_run(d: Path) -> Path:
    """A run folder whose run was interrupted: results but no manifest."""
    complete_run(d)
    (d / MANIFEST).unlink()
    return d


def corrupt_run(d: Path) -> Path:
    complete_run(d)
    (d / "motion.npz").write_bytes(b"motiom")          # same size, another checksum
    return d


def stored_config_run(d: Path, overrides: list[str]) -> Path:
    """A complete run folder whose metrics.json holds the config ``overrides`` compose to."""
    from mocap.threads import resolve_threads
    from mocap_cli.hydra_edge import compose, plain

    config = plain(compose("track", overrides))
    complete_run(d)
    (d / "metrics.json").write_text(json.dumps({"tracker": "apf", "seed": 0, "sec_per_frame": 1.0,
                                                "threads": resolve_threads("auto"), "config": config}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


def rrd_without_manifest(d: Path) -> Path:
    """A run folder left by a failed run: recording.failed.rrd, no manifest."""
    import rerun as rr

    d.mkdir(parents=True)
    rec = rr.RecordingStream("mocap")
    rec.save(d / "recording.failed.rrd")
    rec.log("run/config", rr.TextDocument("x"), static=True)
    rec.flush()
    rec.disconnect()
    return d


def sweep(d: Path, kind: str) -> Path:
    """A sweep folder of two runs: one without a manifest, or the same seed twice (mixed)."""
    a = complete_run(d / "apf_walk_small_s0_aaaa")
    b = complete_run(d / "apf_walk_small_s0_bbbb" if kind == "mixed" else d / "apf_walk_small_s1_bbbb")
    if kind == "incomplete":
        (b / MANIFEST).unlink()
    else:
        for r, layers in ((a, 2), (b, 3)):
            m = json.loads((r / "metrics.json").read_text())
            m["config"] = {"seed": 0, "tracker": {"layers": layers}}
            (r / "metrics.json").write_text(json.dumps(m))
            write_manifest(r, ["motion.npz", "metrics.json"])
    return d


def folder(tmp, what):
    return ["track", *FAST[:1], "data=folder", f"data.path={variant(SEQ[0], tmp, what)}",
            "recording.enabled=false"]


SEQ: list[Path] = []        # the module's sequence folder (set by the autouse fixture)

# (case, argv(tmp) -> command line, exit status, words the one line must hold, run folder checked)
CASES = [
    ("frames=0", lambda t: ["track", *FAST, "frames=0"], 2, ["frames", "0", ">= 1"]),
    ("frames=-1", lambda t: ["track", *FAST, "frames=-1"], 2, ["frames", "-1", ">= 1"]),
    ("frames=abc", lambda t: ["track", *FAST, "frames=abc"], 2, ["frames", "'abc'"]),
    ("frames beyond the data", lambda t: ["track", *FAST, "frames=50"], 2,
     ["frames = 50", "3 frames", "frames=all"]),
    ("seed=abc", lambda t: ["track", *FAST, "seed=abc"], 2, ["seed", "'abc'", ">= 0"]),
    ("seed=-1", lambda t: ["track", *FAST, "seed=-1"], 2, ["seed", "-1", ">= 0"]),
    ("particles=-5", lambda t: ["track", *FAST, "tracker.particles=-5"], 2, ["particles", "-5", ">= 2"]),
    ("layers=0", lambda t: ["track", *FAST, "tracker.layers=0"], 2, ["layers", "0", ">= 1"]),
    ("threads=-2", lambda t: ["track", *FAST, "threads=-2"], 2, ["threads", "-2"]),
    ("init.mode=bogus", lambda t: ["track", *FAST, "init.mode=bogus"], 2, ["init.mode", "bogus"]),
    ("recording.every=0", lambda t: ["track", *FAST, "recording.enabled=true", "recording.every=0"], 2,
     ["recording.every", "0"]),
    ("recording.every=0, recording off", lambda t: ["track", *FAST, "recording.every=0"], 2,
     ["recording.every", "0"]),
    ("unknown tracker", lambda t: ["track", "tracker=no_such"], 2, ["tracker/no_such", "apf"]),
    ("unknown tracker key", lambda t: ["track", *FAST, "tracker.no_such_key=1"], 2,
     ["tracker.no_such_key"]),
    ("missing data folder", lambda t: ["track", *FAST[:1], "data=folder", f"data.path={t / 'nope'}"], 2,
     ["data path not found", "nope"]),
    ("NaN ground-truth joint", lambda t: folder(t, "gt_nan"), 2,
     ["gt.npz", "'joints'", "NaN", "frame 1", "nonfinite=drop"]),
    ("Inf ground-truth pose chi", lambda t: folder(t, "gt_inf_chi"), 2, ["gt.npz", "'chi'", "NaN/Inf"]),
    ("NaN detection x", lambda t: folder(t, "det_nan"), 2, ["detections.json", "row 5", "x = nan"]),
    ("detection label out of range", lambda t: folder(t, "det_label"), 2,
     ["detections.json", "row 7", "label = 99", "[-1,"]),
    ("detection view out of range", lambda t: folder(t, "det_view"), 2,
     ["detections.json", "row 2", "view = 9"]),
    ("detection frame out of range", lambda t: folder(t, "det_frame"), 2,
     ["detections.json", "row 4", "frame = 17"]),
    ("data.nonfinite=maybe", lambda t: ["track", *FAST[:1], "data=folder", f"data.path={SEQ[0]}",
                                        "data.nonfinite=maybe"], 2, ["nonfinite", "'maybe'", "drop"]),
    ("changed config, resume_on_change=fail",
     lambda t: ["track", *FAST, "tracker.layers=3", "resume_on_change=fail"], 2,
     ["another configuration", "tracker.layers"]),
    ("export: no manifest", lambda t: ["export", str(incomplete_run(t / "run")), "--format", "bvh"], 2,
     ["not a complete run", "no manifest.json"]),
    ("export: motion.npz changed", lambda t: ["export", str(corrupt_run(t / "run")), "--format", "bvh"], 2,
     ["not a complete run", "motion.npz", "checksum"]),
    ("export: --out in a missing folder", lambda t: ["export", str(complete_run(t / "run")), "--format",
                                                     "bvh", "--out", str(t / "no" / "m.bvh")], 2,
     ["folder", "does not exist"]),
    ("export: c3d to a name without .c3d", lambda t: ["export", str(complete_run(t / "run")), "--format",
                                                      "c3d", "--out", str(t / "markers")], 2,
     [".c3d", "without suffix"]),
    ("export: trc to .bvh", lambda t: ["export", str(complete_run(t / "run")), "--format", "trc",
                                       "--out", str(t / "m.bvh")], 2, [".trc", ".bvh"]),
    ("export: unknown format", lambda t: ["export", str(complete_run(t / "run")), "--format", "obj"], 2,
     ["'obj'", "bvh"]),
    ("export: no run folder", lambda t: ["export", str(t / "nothing"), "--format", "bvh"], 2,
     ["no motion.npz"]),
    ("rescore: no manifest", lambda t: ["rescore", str(incomplete_run(t / "run"))], 1,
     ["skipped", "not a complete run"]),
    ("replay: failed run, no manifest", lambda t: ["replay", str(rrd_without_manifest(t / "run")),
                                                   "--summary"], 1, ["WARNING", "not a complete run"]),
    ("ablate --strict: a run without manifest", lambda t: ["ablate", str(sweep(t / "sweep", "incomplete")),
                                                           "--strict"], 1,
     ["s1_bbbb", "not a complete run"]),
    ("ablate --strict: a folder mixing configs", lambda t: ["ablate", str(sweep(t / "sweep", "mixed")),
                                                            "--strict"], 1,
     ["mixes configs", "tracker.layers"]),
    ("ablate: no sweep folder", lambda t: ["ablate", str(t / "nothing")], 2, ["sweep directory not found"]),
]


@pytest.fixture(autouse=True)
def _seq(seq_folder):
    SEQ[:] = [seq_folder]


def test_the_catalogue_has_thirty_cases():
    assert len(CASES) >= 30


@pytest.mark.parametrize("case, argv, status, words", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_refused_or_flagged(case, argv, status, words, tmp_path, capsys):
    run_dir = tmp_path / "out"
    args = argv(tmp_path)
    if args[0] == "track":
        if "resume_on_change=fail" in args:          # a complete run of another configuration
            stored_config_run(run_dir, FAST)
        args.append(f"hydra.run.dir={run_dir}")
    before = {p.name for p in run_dir.iterdir()} if run_dir.is_dir() else set()
    got = main(args)
    err = capsys.readouterr().err
    assert got == status, err
    assert "Traceback" not in err
    if status == 2:                      # refused: one line, naming the thing
        (line,) = [ln for ln in err.splitlines() if "error:" in ln]
        assert line.startswith(f"mocap {args[0]}: error:"), line
    else:                                # flagged: a WARNING or a problem line
        line = " ".join(ln for ln in (err + _markdown(tmp_path)).splitlines()
                        if "WARNING" in ln or "skipped" in ln or "`" in ln)
    for word in words:
        assert word in line, (word, line)
    # no folder is left looking complete for the bad input; a refused track wrote nothing
    if args[0] == "track":
        after = {p.name for p in run_dir.iterdir()} if run_dir.is_dir() else set()
        assert after - before <= {".hydra", "track.log"}, after - before
        if "resume_on_change=fail" in args:      # the old run is still what the folder says
            assert manifest_problem(run_dir) is None
            assert "layers: 2" in (run_dir / ".hydra" / "config.yaml").read_text()
        else:
            assert manifest_problem(run_dir) is not None
    for tmp in tmp_path.rglob(".*.tmp*"):
        pytest.fail(f"temporary file left: {tmp}")


def _markdown(tmp: Path) -> str:
    md = tmp / "sweep" / "ablation.md"
    return md.read_text() if md.is_file() else ""


def test_flagged_ablate_runs_are_not_rows(tmp_path, capsys):
    """A run folder without a manifest is listed under the problems, never as a table row."""
    from mocap.run_folder.sweep import collect

    got = collect(sweep(tmp_path / "sweep", "incomplete"))
    assert [r["_dir"] for r in got.runs] == [str(tmp_path / "sweep" / "apf_walk_small_s0_aaaa")]
    assert [p[0] for p in got.problems] == [str(tmp_path / "sweep" / "apf_walk_small_s1_bbbb")]


def test_a_read_only_run_folder_gives_one_line(tmp_path, capsys):
    run_dir = tmp_path / "ro"
    run_dir.mkdir()
    if subprocess.run(["chattr", "+i", str(run_dir)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i not available (a read-only folder for root)")
    try:
        got = main(["track", *FAST, f"hydra.run.dir={run_dir}"])
    finally:
        subprocess.run(["chattr", "-i", str(run_dir)], check=True)
    err = capsys.readouterr().err
    assert got == 2
    (line,) = [ln for ln in err.splitlines() if ln.strip()]
    assert line.startswith("mocap track: error: cannot write") and str(run_dir) in line
    assert "not writable" in line and not list(run_dir.iterdir())


def test_nonfinite_drop_is_reported_in_metrics(seq_folder, tmp_path, body):
    """data.nonfinite=drop loads the folder, leaving out what is not finite, and says so."""
    from mocap.data.sequence_io import load_sequence

    d = variant(seq_folder, tmp_path, "gt_nan")
    with pytest.warns(UserWarning, match="1 ground-truth joints"):
        seq = load_sequence(d, nonfinite="drop")
    assert seq.meta["dropped_nonfinite"] == {"ground-truth joints": 1}
    assert not seq.gt.joint_valid[1, 4] and seq.gt.joint_valid.sum() == seq.gt.joint_valid.size - 1
    d = variant(seq_folder, tmp_path, "det_nan")
    with pytest.warns(UserWarning, match="1 detection rows"):
        seq = load_sequence(d, nonfinite="drop")
    full = load_sequence(seq_folder)
    assert len(seq.detections.frame) == len(full.detections.frame) - 1


def test_frames_settings_checked_before_work():
    from mocap.run_folder.tracking import check_settings

    assert check_settings({"seed": 3, "frames": None}) is None
    assert check_settings({"seed": 0, "frames": "all"}) is None
    assert check_settings({"seed": 0, "frames": 7}) == 7
    for bad in ({"frames": 0}, {"frames": True}, {"frames": 2.5}, {"seed": "abc"}, {"seed": 1.0}):
        with pytest.raises(ValueError, match="setting (frames|seed) = "):
            check_settings({"seed": 0, **bad})


def test_nonfinite_drop_runs_and_says_so_in_metrics(tmp_path, body):
    """A folder with a NaN ground-truth joint, tracked with data.nonfinite=drop (frames=all):
    metrics.json reports what was left out, and the run is complete."""
    from mocap.data.sequence_io import write_sequence
    from mocap.data.sources import synthetic_sequence

    seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=2, fps=25, seed=0,
                             name="tiny_masks", shape_scale=0.8, images=False)
    d = write_sequence(seq, tmp_path / "seq")
    with np.load(d / "gt.npz") as z:
        arrays = dict(z)
    arrays["joints"][1, 4, 2] = np.nan
    np.savez_compressed(d / "gt.npz", **arrays)
    run_dir = tmp_path / "run"
    args = ["track", "tracker=apf", "data=folder", f"data.path={d}", "data.nonfinite=drop", "frames=all",
            "tracker.particles=4", "tracker.layers=2", "recording.enabled=false", f"hydra.run.dir={run_dir}"]
    assert main(args) == 0
    m = json.loads((run_dir / "metrics.json").read_text())
    assert m["dropped_nonfinite"] == {"ground-truth joints": 1} and m["frames"] == 2
    assert np.isfinite(m["mpjpe_mm"]) and manifest_problem(run_dir) is None

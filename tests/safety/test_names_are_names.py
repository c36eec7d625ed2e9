"""Names from files are names, not paths (issue 36, S2): a camera named ``../x`` (or any name
that is not one plain path component) in a recording's ``Calib.toml`` is refused in one line
naming the file and the name by ``mocap detect``, ``segment``, ``convert`` and ``track``
before any file is touched (the whole temporary tree, parent folders included, is listed
before and after); the same for view names of ``sequence.json``, and for the name checks
themselves (:func:`mocap.safe_files.name_problem`)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from mocap.cameras import ring_rig, write_pose2sim_calibration
from mocap.safe_files import UnsafeNameError, check_name, inside, name_problem, temporary_beside
from mocap_cli.main import main
from tests.safety.helpers import tree

BAD_NAMES = ["../x", "../../x", "../../../x", "/tmp/x", "a/b", "a\\b", "..", ".", ".hidden", "",
             "x" * 200, "nul\0byte", "cam 1 ", "a:b", "a\nb", '"quoted"', "a*b", "$HOME"]
GOOD_NAMES = ["cam_00", "int_cam01_img", "Camera-2", "cam 1", "c.3", "view(4)", "a+b@c=d", "x" * 128,
              "kamera_ü", "-"]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_a_name_that_is_not_one_plain_component_is_refused(name):
    assert name_problem(name) is not None
    with pytest.raises(UnsafeNameError, match="Calib.toml: camera name"):
        check_name(name, "camera name", "Calib.toml")


@pytest.mark.parametrize("name", GOOD_NAMES)
def test_plain_names_pass(name):
    assert name_problem(name) is None


def test_a_path_that_leaves_its_folder_is_refused(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "link").symlink_to(tmp_path)
    assert inside(tmp_path / "out" / "a" / "b", tmp_path / "out") == tmp_path / "out" / "a" / "b"
    for p in (tmp_path / "out" / ".." / "x", tmp_path / "out" / "link" / "x", Path("/etc/passwd")):
        with pytest.raises(UnsafeNameError, match="outside its output folder"):
            inside(p, tmp_path / "out")


def test_a_temporary_file_never_follows_a_planted_link(tmp_path):
    """Temporary names are unpredictable and created exclusively: a link planted at the old
    predictable name is left alone, its target untouched."""
    from mocap.run_folder.read import write_json

    target = tmp_path / "elsewhere.txt"
    target.write_text("keep")
    (tmp_path / "metrics.json.tmp").symlink_to(target)
    write_json(tmp_path / "metrics.json", {"a": 1})
    assert target.read_text() == "keep" and json.loads((tmp_path / "metrics.json").read_text()) == {"a": 1}
    with temporary_beside(tmp_path / "m.npz") as a, temporary_beside(tmp_path / "m.npz") as b:
        assert a != b and a.parent == tmp_path and a.name.startswith(".m.npz.")
    assert not a.exists() and not b.exists()


def bad_recording(root: Path, bad: str) -> Path:
    """A Pose2Sim-style recording (Calib.toml, videos/, pose/) whose second camera is named ``bad``."""
    names = ["cam_a", bad, "cam_c", "cam_d"]
    rig = ring_rig(4, 4.0, 1.8, 64, 48, fov_deg=40.0, names=names)
    root.mkdir(parents=True)
    write_pose2sim_calibration(rig, root / "Calib.toml")
    (root / "videos").mkdir()
    (root / "pose").mkdir()
    for i, _ in enumerate(names):
        (root / "videos" / f"cam{i}.mp4").write_bytes(b"")
        d = root / "pose" / f"cam{i}_json"
        d.mkdir()
        (d / f"cam{i}.000000.json").write_text(json.dumps({"people": []}))
    return root


COMMANDS = {
    "detect": lambda rec, out: ["detect", str(rec), "--out", str(out), "--no-progress"],
    "convert": lambda rec, out: ["convert", str(rec), str(out)],
    "segment": lambda rec, out: ["segment", f"data.path={rec}", f"out={out}"],
    "track": lambda rec, out: ["track", "data=pose2sim_demo", f"data.path={rec}", f"hydra.run.dir={out}",
                               "tracker=marker_apf", "init.mode=tracker", "recording.enabled=false"],
}


@pytest.mark.parametrize("bad", ["../x", "../../x", "/tmp/mocap_i36_abs"])
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_camera_named_like_a_path_is_refused_before_any_file_is_touched(command, bad, tmp_path, capsys,
                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    work = tmp_path / "work" / "deeper"
    rec = bad_recording(work / "rec", bad)
    out = work / "out" / "inner"
    (work / "out").mkdir()
    (work / "victim.txt").write_text("keep")
    (tmp_path / "x_json").mkdir()                       # what ../../x of pose/<name>_json would reach
    before = tree(tmp_path)
    code = main(COMMANDS[command](rec, out))
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code != 0
    assert len(err) == 1 and "Calib.toml" in err[0] and repr(bad) in err[0], err
    after = tree(tmp_path)
    # only Hydra's own record of the command inside the output folder may appear; nothing else
    new = {k for k in set(after) - set(before)
           if not k.startswith(str((out / ".hydra_run").relative_to(tmp_path)))
           and not k.startswith(str((out / ".hydra").relative_to(tmp_path)))
           and k != str(out.relative_to(tmp_path)) and k != str(out.parent.relative_to(tmp_path))
           and k != str((out / "track.log").relative_to(tmp_path))}
    assert new == set()
    assert {k: v for k, v in after.items() if k in before} == before
    assert not Path("/tmp/mocap_i36_abs_json").exists() and not Path("/tmp/mocap_i36_abs").exists()


def test_a_view_named_like_a_path_in_sequence_json_is_refused(tmp_path, body):
    from mocap.data.sequence_io import SequenceFormatError, load_sequence, write_sequence
    from mocap.data.sources import synthetic_sequence

    seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=2, fps=25, seed=0,
                             name="tiny", masks=True, images=False)
    folder = write_sequence(seq, tmp_path / "seq")
    info = json.loads((folder / "sequence.json").read_text())
    info["views"][1] = "../../outside"
    (folder / "sequence.json").write_text(json.dumps(info))
    (tmp_path / "outside").mkdir()
    with pytest.raises(SequenceFormatError, match=r"sequence.json: field 'views': view name '../../outside'"):
        load_sequence(folder)
    shutil.rmtree(tmp_path / "outside")


def test_writing_a_sequence_with_a_path_like_camera_name_writes_nothing(tmp_path, body):
    from dataclasses import replace

    from mocap.cameras import Rig
    from mocap.data.sequence_io import write_sequence
    from mocap.data.sources import synthetic_sequence

    seq = synthetic_sequence(body=body, cameras="ring4_small", motion="walk", frames=2, fps=25, seed=0,
                             name="tiny", masks=True, images=False)
    cams = list(seq.rig.cameras)
    cams[0] = replace(cams[0], name="../../escaped")
    bad = replace(seq, rig=Rig(tuple(cams)))
    before = tree(tmp_path)
    with pytest.raises(UnsafeNameError, match="camera name '../../escaped'"):
        write_sequence(bad, tmp_path / "a" / "seq")
    assert tree(tmp_path) == before


def test_writers_never_follow_a_link_at_their_old_fixed_temporary_names(tmp_path):
    """The body-model file, the pose prior, gt.npz, an exported motion and the calibration folder
    used to be written through fixed names (``X.tmp.npz``, ``.gt.tmp.npz``, ``out.partial``): a
    link planted there (by whoever can write the folder) would have been written through. Each
    writer now goes through :func:`mocap.safe_files.temporary_beside` / ``mkdtemp``: the links'
    targets are untouched and what was written reads back equal."""
    import numpy as np

    from mocap.body.model_file import load_body_model_data, save_body_model_data
    from mocap.calibration.pipeline import _write
    from mocap.energy.prior import ParzenPrior
    from mocap.safe_files import write_npz_atomic

    target = tmp_path / "elsewhere.txt"
    target.write_text("keep")
    planted = ["body.npz.tmp.npz", "prior.npz.tmp.npz", ".gt.tmp.npz", "calib.partial", "m.npz.tmp"]
    for name in planted:
        (tmp_path / name).symlink_to(target)
    data = load_body_model_data()
    save_body_model_data(data, tmp_path / "body.npz")
    assert np.array_equal(load_body_model_data(tmp_path / "body.npz").faces, data.faces)
    prior = ParzenPrior(samples=np.ones((3, 2)), dof_names=("a", "b"), sigma=0.5)
    prior.save(tmp_path / "prior.npz")
    assert np.array_equal(ParzenPrior.load(tmp_path / "prior.npz").samples, prior.samples)
    write_npz_atomic(tmp_path / "m.npz", {"x": np.arange(3)})
    assert np.load(tmp_path / "m.npz")["x"].tolist() == [0, 1, 2]
    rig = ring_rig(2, 3.0, 1.5, 64, 48, fov_deg=40.0)
    _write(tmp_path / "calib", rig, {"ok": 1}, [], overwrite=False)
    assert json.loads((tmp_path / "calib" / "report.json").read_text()) == {"ok": 1}
    assert target.read_text() == "keep"
    assert all((tmp_path / n).is_symlink() for n in planted)
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".") and not p.is_symlink()) == []

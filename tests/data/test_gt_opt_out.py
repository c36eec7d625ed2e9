"""Ground truth that blocks or misleads (issue 37): a folder's gt.npz that cannot be read names
the way out (``data.gt=none``) and that setting tracks the folder without it; ``gt-from-joints``
refuses without ``--skeleton``; ``convert`` reads the frame rate from the videos or asks for
``--fps``; every data config that reads the shared data honours MOCAP_SHARED_DATA."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

import mocap
from mocap.data.sequence_io import SequenceFormatError, load_sequence, write_sequence
from mocap_cli.main import main

REPO = Path(__file__).resolve().parents[2]
DEMO = Path(os.environ.get("MOCAP_SHARED_DATA") or REPO.parent / "shared" / "data") / "pose2sim-demo"


@pytest.fixture(scope="module")
def folder_with_foreign_gt(tmp_path_factory, body) -> Path:
    """A sequence folder whose gt.npz is in another format (no joint names)."""
    seq = mocap.synthetic_sequence(body, cameras="ring4_small", motion="walk", frames=2, seed=0)
    out = write_sequence(seq, tmp_path_factory.mktemp("seq") / "seq")
    np.savez(out / "gt.npz", positions=np.zeros((2, 15, 3)))
    return out


def test_a_foreign_gt_npz_names_the_opt_out_and_the_opt_out_reads_the_folder(folder_with_foreign_gt):
    with pytest.raises(SequenceFormatError, match="gt.npz.*data.gt=none tracks the data without it"):
        load_sequence(folder_with_foreign_gt, images=False)
    for off in ("none", "None", ""):
        seq = load_sequence(folder_with_foreign_gt, images=False, gt=off)
        assert seq.gt is None and seq.masks is not None and "gt" not in seq.meta


def test_the_cli_tracks_a_folder_with_data_gt_none(folder_with_foreign_gt, tmp_path, capsys):
    run = ["track", f"hydra.run.dir={tmp_path}", "data=folder", f"data.path={folder_with_foreign_gt}",
           "tracker=local", "tracker.iterations=2", "recording.enabled=false"]
    assert main([*run, "frames=1"]) == 2
    assert "data.gt=none" in capsys.readouterr().err
    # the tracker's own start at a small search (what is checked is that the run goes through)
    start = ["init.mode=tracker", "++tracker.initialization.rounds=0",
             "++tracker.initialization.hypotheses=0", "++tracker.initialization.pose_particles=8",
             "++tracker.initialization.pose_layers=2"]
    assert main([*run, "data.gt=none", *start, "frames=1"]) == 0


def test_gt_from_joints_refuses_without_a_skeleton(tmp_path, capsys):
    assert main(["gt-from-joints", str(tmp_path / "joints"), str(tmp_path / "seq")]) == 2
    err = capsys.readouterr().err
    assert "--skeleton" in err and "required" in err and not (tmp_path / "seq").exists()


def test_convert_without_videos_asks_for_the_fps(tmp_path, capsys):
    (tmp_path / "rec").mkdir()
    assert main(["convert", str(tmp_path / "rec"), str(tmp_path / "out")]) == 2
    assert "pass --fps" in capsys.readouterr().err and not (tmp_path / "out").exists()


@pytest.mark.skipif(not (DEMO / "videos").is_dir(), reason="Pose2Sim demo data not present")
def test_convert_reads_the_fps_of_the_videos(tmp_path, capsys):
    from mocap.video.frames import video_info

    assert main(["convert", str(DEMO), str(tmp_path / "out"), "--frames", "2"]) == 0
    seq = load_sequence(tmp_path / "out", images=False)
    assert seq.fps == video_info(sorted((DEMO / "videos").glob("*"))[0]).fps == 60


def test_every_data_config_reading_shared_data_honours_mocap_shared_data(monkeypatch, tmp_path):
    from mocap_cli import CONF_DIR
    from mocap_cli.hydra_edge import compose

    monkeypatch.setenv("MOCAP_SHARED_DATA", str(tmp_path))
    checked = 0
    for yaml in sorted((Path(CONF_DIR) / "data").glob("*.yaml")):
        text = yaml.read_text()
        if "shared" not in text.split("_target_")[1]:       # settings (not comments above them)
            continue
        cfg = compose("track", [f"data={yaml.stem}"])
        path = OmegaConf.select(cfg, "data.path")
        assert path.startswith(str(tmp_path)), f"{yaml.name}: data.path = {path}"
        checked += 1
    assert checked >= 2                     # pose2sim_demo, pose2sim_demo_video

"""Every option of every config group composes and instantiates."""

from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate

from mocap_cli import CONF_DIR as CONF  # reading it registers ${mocap_data:} and the Python-registered nodes

REPO = Path(__file__).resolve().parents[2]


def options(group: str) -> list[str]:
    """A group's options: conf/<group>, the package's presets (mocap/presets/<group>) and the
    nodes registered from Python (mocap_cli/conf_schema.py: the tracker presets)."""
    from mocap import presets
    from mocap_cli.conf_schema import options as registered

    packaged = presets.names(group) if group in presets.KINDS else []
    return sorted({p.stem for p in (CONF / group).glob("*.yaml")} | set(packaged) | set(registered(group)))


def test_every_group_has_options():
    for group in ("body", "cameras", "data", "tracker"):
        assert options(group), group


@pytest.mark.parametrize("name", options("body"))
def test_body_options(name):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=[f"body={name}"])
    body = instantiate(cfg.body)
    assert body.num_dofs == 6 + len(cfg.body.dofs)
    assert np.isfinite(body.shaped().pose(body.zero_pose(2)).vertices).all()


@pytest.mark.parametrize("name", options("cameras"))
def test_camera_options(name):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("make_dataset", overrides=[f"cameras={name}"])
    rig = instantiate(cfg.cameras)
    assert len(rig) == cfg.cameras.num_cameras


SHARED = REPO.parent / "shared" / "data"


@pytest.mark.parametrize("name", [o for o in options("data") if o != "folder"])
def test_data_options(name, body):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=[f"data={name}"])
    synthetic = cfg.data._target_.endswith("synthetic_sequence")
    if not synthetic and not SHARED.is_dir():
        pytest.skip(f"{name} reads ../shared/data, which is absent here")
    if synthetic:
        cfg.data.frames = 2
    if cfg.data._target_.endswith("video_sequence"):
        cfg.data.stop = cfg.data.start + 2 * cfg.data.step     # two frames: segmentation is slow
    seq = instantiate(cfg.data, _partial_=True)(body=body)
    assert seq.masks is not None or seq.detections is not None
    if synthetic:
        assert seq.num_frames == 2 and seq.gt is not None


def test_folder_data_option_needs_an_existing_path(body):
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=["data=folder", "data.path=/nonexistent/sequence"])
    with pytest.raises(FileNotFoundError, match="data path not found: /nonexistent/sequence"):
        instantiate(cfg.data, _partial_=True)(body=body)


@pytest.mark.parametrize("name", options("tracker"))
def test_tracker_options(name, body):
    from mocap.cameras import rig_from_config

    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=[f"tracker={name}"])
    tracker = instantiate(cfg.tracker, _partial_=True)(body=body, rig=rig_from_config("ring4_small"),
                                                        rng=np.random.default_rng(0))
    assert tracker.name == name


def test_slurm_launcher_config_composes():
    with initialize_config_dir(str(CONF), version_base="1.3"):
        cfg = compose("track", overrides=["hydra/launcher=slurm"], return_hydra_config=True)
    launcher = cfg.hydra.launcher
    assert launcher._target_.endswith("SlurmLauncher")
    assert launcher.cpus_per_task == 2 and launcher.timeout_min == 240

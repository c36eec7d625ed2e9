"""A run folder is data (issue 36, S1): the ``_target_`` names in its ``metrics.json`` are looked
up in a closed registry (:data:`mocap.presets.TARGETS`); a name that is not registered, a setting
the builder does not take, or a nested unregistered target is refused in one line by ``mocap
rescore`` (also ``--dry-run``) and ``mocap export --format gltf`` before anything is written
(the whole temporary tree is listed, with sizes and checksums, before and after), and no function
outside the registry is reached (the callable each path would reach is replaced by one that
records the call, and ``importlib.import_module`` is watched)."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pytest

from mocap import presets
from mocap.run_folder.manifest import write_manifest
from mocap_cli.main import main
from tests.safety.catalogue import GOOD_BODY, GOOD_DATA, evil_configs
from tests.safety.helpers import tree


def fake_run(d: Path, config: dict) -> Path:
    """A run folder whose motion.npz is not one: the config must be refused before it is read."""
    d.mkdir(parents=True)
    (d / "motion.npz").write_bytes(b"not read before the config is checked")
    (d / "metrics.json").write_text(json.dumps({"tracker": "apf", "mpjpe_mm": 20.0, "config": config}))
    write_manifest(d, ["motion.npz", "metrics.json"])
    return d


@pytest.fixture
def watch(monkeypatch):
    """Record every module imported by name (``importlib.import_module``) and make the demonstrated
    functions fail loudly if reached. A package importing its own submodules (OpenCV's loader does,
    the first time a command imports it) is not a stored name being reached: not recorded."""
    imported: list[str] = []
    real = importlib.import_module

    def recording(name, package=None):
        caller = sys._getframe(1).f_globals.get("__name__", "")
        if name.split(".")[0] != caller.split(".")[0]:
            imported.append(name)
        return real(name, package)

    monkeypatch.setattr(importlib, "import_module", recording)
    reached: list[str] = []
    import mocap.run_folder.metadata
    import mocap.run_folder.read
    import mocap.run_folder.resume
    for module, attr in ((mocap.run_folder.read, "write_json"), (mocap.run_folder.resume, "drop_previous"),
                         (mocap.run_folder.metadata, "git_revision")):
        monkeypatch.setattr(module, attr, lambda *a, _n=attr, **k: reached.append(_n))
    return imported, reached


ALLOWED_MODULES = {m for _, m, _ in presets.TARGETS.values()}


@pytest.mark.parametrize("case", sorted(evil_configs(Path("/x"))))
@pytest.mark.parametrize("command", ["rescore-dry", "rescore", "export-gltf"])
def test_a_stored_target_outside_the_registry_is_refused_and_nothing_is_written(
        case, command, tmp_path, watch, capsys):
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "keep.txt").write_text("precious")
    (victim / "previous_run").mkdir()
    run = fake_run(tmp_path / "run", evil_configs(victim)[case])
    before = tree(tmp_path)
    argv = {"rescore-dry": ["rescore", str(run), "--dry-run"], "rescore": ["rescore", str(run)],
            "export-gltf": ["export", str(run), "--format", "gltf"]}[command]
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0
    assert len(err) == 1 and "refused" in err[0] and "metrics.json" in err[0], err
    assert tree(tmp_path) == before                     # nothing written, moved or deleted anywhere
    imported, reached = watch
    assert reached == []
    outside = [m for m in imported if m not in ALLOWED_MODULES and not m.startswith("mocap_cli.commands.")]
    assert outside == []


def test_a_registered_config_still_builds(tmp_path):
    """The registry is not a wall: the shipped presets and a stored config of registered names
    build (the body and a two-frame synthetic sequence)."""
    from mocap.run_folder.read import run_body, run_sequence

    body = run_body({"body": GOOD_BODY, "data": GOOD_DATA})
    seq = run_sequence({"body": GOOD_BODY, "data": GOOD_DATA}, body)
    assert body.num_dofs == 22 and seq.num_frames == 2
    for name in presets.names("cameras"):
        assert len(presets.build(presets.read("cameras", name), kind="cameras").cameras) > 0


def test_every_target_in_the_shipped_configs_is_registered():
    """conf/, the presets and the tracker presets' config nodes name only registered builders (else
    the command line would refuse them); the only other targets are Hydra's own callbacks under
    ``hydra.callbacks`` (built by Hydra from the shipped config, never from a run folder's), and
    those are this package's :class:`hydra.experimental.callback.Callback` classes."""
    from hydra.experimental.callback import Callback
    from omegaconf import OmegaConf

    def targets(node, out):
        if isinstance(node, dict):
            if "_target_" in node:
                out.add(str(node["_target_"]))
            for value in node.values():
                targets(value, out)
        elif isinstance(node, list):
            for value in node:
                targets(value, out)
        return out

    root = Path(__file__).resolve().parents[2]
    found, callbacks = set(), set()
    for path in [*root.glob("mocap_cli/conf/**/*.yaml"), *root.glob("conf/**/*.yaml"),
                 *root.glob("mocap/presets/**/*.yaml")]:
        cfg = OmegaConf.to_container(OmegaConf.load(path), resolve=False)
        if not isinstance(cfg, dict):
            continue
        hydra = cfg.pop("hydra", None) or {}
        targets(cfg, found)
        targets(hydra.get("callbacks") or {}, callbacks)
        assert not targets({k: v for k, v in hydra.items() if k != "callbacks"}, set()), path
    from mocap.trackers.presets import PRESETS
    from mocap_cli.conf_schema import preset_node  # the tracker presets, registered from Python

    found |= {preset_node(name)["_target_"] for name in PRESETS}
    assert callbacks == {"mocap_cli.hydra_edge.RunFolderLock"}, callbacks
    for name in callbacks:
        module, _, attr = name.rpartition(".")
        assert issubclass(getattr(importlib.import_module(module), attr), Callback), name
    assert len(found) >= 8 and found <= set(presets.TARGETS), found - set(presets.TARGETS)

"""Shared fixtures: the shipped body model in both DOF configurations. The order the suite runs
its files in: the longest first (:data:`DURATIONS`)."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import pytest

from mocap.body import BodyModel, load_body_model

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


def pytest_configure(config):
    """The configs' resolvers (``${mocap_data:}``, ``${run_hash:...}``) registered in every test
    process (each pytest-xdist worker too), so a test composing configs with Hydra directly does
    not depend on an earlier test having imported :mod:`mocap_cli.hydra_edge`."""
    from mocap_cli import register_resolvers

    register_resolvers()


#: seconds each test file took in a past run of the whole suite (``bash scripts/test.sh
#: --store-durations`` rewrites it). The files run longest first: under pytest-xdist each file runs
#: on one worker, and a long file dealt last (xdist's own order is by number of tests, which puts
#: the one-test files that take minutes at the end) keeps one worker busy while the others idle.
#: Files not listed run after those listed, in collection order. Only the order depends on it.
DURATIONS = Path(__file__).with_name("file_durations.json")
_SECONDS: dict[str, float] = defaultdict(float)


def pytest_addoption(parser):
    parser.addoption("--store-durations", action="store_true",
                     help=f"write each test file's seconds (setup + call + teardown) this run to {DURATIONS}")


def pytest_collection_modifyitems(config, items):
    seconds = json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        first.setdefault(item.nodeid.split("::")[0], i)

    def key(item):
        file = item.nodeid.split("::")[0]
        return -seconds.get(file, 0.0), first[file]

    items.sort(key=key)                      # stable: a file's tests keep their order


def pytest_runtest_logreport(report):
    """Each test's phases summed per file (under xdist the controller receives every worker's)."""
    _SECONDS[report.nodeid.split("::")[0]] += report.duration


def pytest_sessionfinish(session):
    import os

    config = session.config
    stem = os.environ.get("MOCAP_RECORD_KERNELS")
    if stem:     # the kernels' argument types this process compiled (docs/results/speed.md)
        from mocap import kernel_cache

        kernel_cache.record(f"{stem}.{os.environ.get('PYTEST_XDIST_WORKER', 'main')}.json")
    if config.getoption("store_durations", False) and not hasattr(config, "workerinput") and _SECONDS:
        seconds = json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}
        seconds.update({f: round(s, 1) for f, s in _SECONDS.items()})
        longest_first = dict(sorted(seconds.items(), key=lambda kv: -kv[1]))
        DURATIONS.write_text(json.dumps(longest_first, indent=0) + "\n")


def body_config(name: str) -> dict:
    """The body preset (DOF list, name, dtype) shipped with the package."""
    from mocap import presets

    return presets.read("body", name)


@pytest.fixture(scope="session")
def body() -> BodyModel:
    """The paper's 22-DOF body, float32."""
    return load_body_model(body_config("paper22")["dofs"], name="paper22")


@pytest.fixture(scope="session")
def body64() -> BodyModel:
    return load_body_model(body_config("paper22")["dofs"], dtype="float64", name="paper22")


@pytest.fixture(scope="session")
def body_full() -> BodyModel:
    return load_body_model(body_config("full")["dofs"], dtype="float64", name="full")


@pytest.fixture(scope="session")
def short_run(tmp_path_factory) -> Path:
    """A short tracked run directory (apf_prior on walk_small, 4 frames, tiny budget,
    recording on): motion.npz, metrics.json, recording.rrd. Used by the export and recording
    tests, which only read it. Under pytest-xdist the workers share one run: the first to need
    it tracks it (in its own process: :mod:`tests.cli.in_process`) under a lock in the session's
    common temporary folder, the others wait and reuse it."""
    import fcntl
    import os

    from tests.cli.in_process import mocap

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent                  # the folder above every worker's own (popen-gwN)
    out, done = root / "short_run", root / "short_run.done"
    with open(root / "short_run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)    # released when the file closes
        if not done.is_file():
            r = mocap("track", f"hydra.run.dir={out}", "tracker=apf_prior", "frames=4", "data=walk_small",
                      "tracker.particles=6", "tracker.layers=2")
            assert r.returncode == 0, r.stderr[-3000:]
            done.touch()
    return out


#: the several-people run of :func:`people_run`: the synthetic crowd's first 6 frames (people 0-2
#: from the start, one entering at frame 3 picked up by frame 5), a tiny search budget
PEOPLE_RUN = ["tracker=marker_people", "data=crowd", "data.frames=20", "frames=6", "init.mode=tracker",
              "tracker.particles=20", "tracker.layers=3", "tracker.init.particles=60",
              "tracker.init.passes=2", "tracker.init.layers=5"]


@pytest.fixture(scope="session")
def people_run(tmp_path_factory) -> Path:
    """A short several-people run directory (:data:`PEOPLE_RUN`, recording on; ~50 s): a
    ``mocap-people-v1`` motion.npz, metrics.json with per-person scores, recording.rrd. Read only
    (the export, replay and rescore tests copy it to change it); shared by xdist workers (and
    tracked in the process) as :func:`short_run` is."""
    import fcntl
    import os

    from tests.cli.in_process import mocap

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    out, done = root / "people_run", root / "people_run.done"
    with open(root / "people_run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.is_file():
            r = mocap("track", f"hydra.run.dir={out}", *PEOPLE_RUN)
            assert r.returncode == 0, r.stderr[-3000:]
            done.touch()
    return out

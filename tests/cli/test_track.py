"""mocap track end to end: every tracker for two frames, and its metrics.json."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocap.trackers.presets import PRESETS
from tests.cli.in_process import mocap

REPO = Path(__file__).resolve().parents[2]
# several people (marker_people) write other metrics: tests/cli/test_track_people.py
TRACKERS = sorted(name for name in PRESETS if name != "marker_people")
REQUIRED = {"tracker", "seed", "frames", "mpjpe_mm", "mpjpe_std_mm", "per_joint_mm",
            "sec_per_frame", "energy_evals_per_frame", "per_frame_mm"}


def run_track(tmp_path: Path, *overrides: str, process: bool = False) -> subprocess.CompletedProcess:
    """``mocap track hydra.run.dir=tmp_path *overrides`` from the checkout's root: in this process
    (``mocap_cli.main.main``, the entry point's own function: what the command runs, without a new
    interpreter importing the numeric stack and loading the compiled kernels for each of these
    runs), or as a process of its own (``process``)."""
    args = ["track", f"hydra.run.dir={tmp_path}", *overrides]
    if process:
        return subprocess.run([sys.executable, "-m", "mocap_cli", *args],
                              capture_output=True, text=True, cwd=REPO, timeout=600)
    return mocap(*args)


# small budgets per tracker family, and the energy evaluations per frame they imply
FAST = {
    "apf": (["tracker.particles=8", "tracker.layers=2"], 16),
    "local": (["tracker.iterations=2"], 0),
    "hybrid": (["tracker.apf.particles=8", "tracker.apf.layers=2", "tracker.local.iterations=2"], None),
    "marker_apf": (["tracker.particles=8", "tracker.layers=2"], 16),
    "hybrid_kp": (["tracker.apf.particles=8", "tracker.apf.layers=2", "tracker.local.iterations=2",
                   "data.masks=true"], None),
}
# marker trackers need 2D detections
DATA = {"marker_apf": "walk_markers_small", "hybrid_kp": "walk_markers_small"}   # + masks


def fast_overrides(tracker: str) -> tuple[list[str], int | None]:
    family = next(f for f in ("apf", "hybrid_kp", "hybrid", tracker) if tracker.startswith(f))
    return FAST[family]


@pytest.mark.parametrize("tracker", TRACKERS)
def test_each_tracker_runs_two_frames_and_writes_metrics(tracker, tmp_path):
    overrides, evals = fast_overrides(tracker)
    data = DATA.get(tracker, "walk_small")
    r = run_track(tmp_path, f"tracker={tracker}", f"data={data}", "frames=2", *overrides)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert REQUIRED <= m.keys()
    assert m["tracker"] == tracker and m["frames"] == 2 and len(m["per_frame_mm"]) == 2
    assert len(m["per_joint_mm"]) == 15
    # frame 0 is ground truth + 3 deg / 2 cm noise (26 mm here); with these tiny budgets every
    # tracker stays within 35 mm on frame 1 (measured 24-35 mm); a tracker that diverges fails
    assert 15 < m["per_frame_mm"][0] < 40, m["per_frame_mm"]
    assert m["per_frame_mm"][1] < 50 and m["mpjpe_mm"] < 45, m["per_frame_mm"]
    assert m["pcp"] == 1.0
    assert isinstance(m["threads"], int) and m["threads"] >= 1       # the budget, to reproduce it
    if evals is not None:
        assert m["energy_evals_per_frame"] == evals


def test_unknown_tracker_fails_at_configuration_time(tmp_path):
    r = run_track(tmp_path, "tracker=nonexistent", process=True)        # the command as a process
    assert r.returncode != 0
    assert "Could not find 'tracker/nonexistent'" in r.stderr
    assert not (tmp_path / "metrics.json").exists()


SWEEPS = sorted(p.stem for p in (REPO / "conf" / "sweep").glob("*.yaml"))


@pytest.mark.slow
@pytest.mark.parametrize("sweep", SWEEPS)
def test_each_sweep_composes_and_one_of_its_points_runs_two_frames(sweep, tmp_path):
    """conf/sweep/<name>: its swept keys exist in the composed config, and a run at the sweep's
    last value of each key (tiny budget, 2 frames) writes metrics with that value."""
    from omegaconf import OmegaConf

    from mocap_cli.hydra_edge import compose  # as `mocap track` composes (tracker schemas included)

    cfg = compose("track", [f"+sweep={sweep}"], return_hydra_config=True)
    params = dict(cfg.hydra.sweeper.params)
    assert params
    point = {}
    for key, values in params.items():
        assert OmegaConf.select(cfg, key) is not None or key == "seed", key
        point[key] = str(values).split(",")[-1]
    overrides = [f"{k}={v}" for k, v in point.items() if k != "seed"]
    tracker = point.get("tracker", cfg.hydra.runtime.choices.tracker)
    search = "tracker.apf." if tracker.startswith("hybrid") else "tracker."      # the hybrid's APF
    budget = [o for o in (f"++{search}particles=8", f"++{search}layers=2")
              if o.split("=")[0][2:] not in point]
    if tracker == "local":
        budget = []
    budget.append("oracle.enabled=false")     # the oracles' fits are tested on their own (tests/eval)
    if cfg.init.mode == "tracker":           # a self-initialising sweep: a cheap initialisation
        budget += [f"init.cache={tmp_path / 'cache'}", f"oracle.cache={tmp_path / 'oracles'}"]
        if not tracker.startswith("marker"):  # the marker tracker starts from its detections
            budget += ["++tracker.initialization.rounds=0", "++tracker.initialization.hypotheses=0",
                       "++tracker.initialization.pose_particles=8", "++tracker.initialization.pose_layers=2",
                       # the hybrid start's later stages (its limbs anew, its shape with the pose)
                       "++tracker.initialization.limb_particles=8", "++tracker.initialization.limb_layers=2",
                       "++tracker.initialization.shape_pose_particles=8",
                       "++tracker.initialization.shape_pose_layers=2"]
    r = run_track(tmp_path, f"+sweep={sweep}", "frames=2", *budget, *overrides)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["tracker"] == tracker and m["frames"] == 2 and np.isfinite(m["mpjpe_mm"])
    stored = OmegaConf.load(tmp_path / ".hydra" / "config.yaml")
    for k, v in point.items():
        if k in ("data", "tracker"):                       # config groups: chosen as swept
            assert f"{k}={v}" in OmegaConf.load(tmp_path / ".hydra" / "overrides.yaml"), k
        elif k != "seed":
            assert str(OmegaConf.select(stored, k)) == v, k
    assert (tmp_path / "recording.rrd").exists() == bool(cfg.recording.enabled)


@pytest.mark.slow
def test_the_full_body_tracks_two_frames(tmp_path):
    """body=full (36 DOFs) through the whole harness, with its own pose prior."""
    r = run_track(tmp_path, "body=full", "tracker=apf_prior", "data=walk_small", "frames=2",
                  "tracker.particles=8", "tracker.layers=2", "recording.enabled=false")
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["frames"] == 2 and m["per_frame_mm"][1] < 60, m["per_frame_mm"]
    from mocap.export.motion import load_motion

    assert load_motion(tmp_path).chi.shape == (2, 36)

"""mocap recovery end to end: the track.py harness (motion.npz, metrics.json,
recording.rrd) with a frame skip and a perturbation injected, and recovery figures that agree
with the per-frame errors it wrote."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.cli.in_process import mocap

REPO = Path(__file__).resolve().parents[2]


def naive_frames_to_recover(errors, at, skipped, window, factor):
    seen = [f for f in range(len(errors)) if f not in skipped]
    i = seen.index(at)
    before = sum(errors[f] for f in seen[max(0, i - window):i]) / len(seen[max(0, i - window):i])
    for k, f in enumerate(seen[i:]):
        if errors[f] < factor * before:
            return before, k
    return before, None


def test_recovery_writes_the_track_outputs_and_consistent_figures(tmp_path):
    r = mocap("recovery", f"hydra.run.dir={tmp_path}",           # in this process: its outputs are the point
              "data=walk_small", "frames=8", "tracker=local", "tracker.iterations=3",
              "++tracker.sift.enabled=false", "recording.particles=false",
              "recovery.skip_at=2", "recovery.skip=2", "recovery.perturb_at=5",
              "recovery.window=2", "recovery.perturb_deg=20")
    assert r.returncode == 0, r.stderr[-3000:]
    for name in ("metrics.json", "motion.npz", "recording.rrd"):
        assert (tmp_path / name).is_file(), name
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["tracker"] == "local" and m["frames"] == 8 and len(m["per_frame_mm"]) == 8
    rec = m["recovery"]
    assert rec["skipped_frames"] == [2, 3]
    assert rec["frame_skip"]["at_frame"] == 4 and rec["perturbation"]["at_frame"] == 5
    errors = m["per_frame_mm"]
    for name in ("frame_skip", "perturbation"):
        f = rec[name]
        before, k = naive_frames_to_recover(errors, f["at_frame"], {2, 3}, 2, 2.0)
        assert np.isclose(f["error_before_mm"], before) and f["error_at_mm"] == errors[f["at_frame"]]
        assert f["frames_to_recover"] == k
    # the skipped frames hold the last estimate; the perturbed frame was tracked from elsewhere
    motion = np.load(tmp_path / "motion.npz")
    chi = motion["chi"]
    assert np.array_equal(chi[2], chi[1]) and np.array_equal(chi[3], chi[1])
    assert not np.array_equal(chi[4], chi[1])


def test_a_recovery_sweep_resumes_and_is_tabulated(tmp_path):
    """mocap recovery --multirun: a second launch of the same sweep with skip_complete=true skips
    every finished run (their metrics.json untouched), and mocap ablate tabulates it with the
    recovery columns (recovered share and error at the failure, from each run's figures)."""
    sweep = tmp_path / "sweep"
    args = [sys.executable, "-m", "mocap_cli", "recovery", "--multirun", "data=walk_small", "frames=6",
            "tracker=local", "tracker.iterations=2", "++tracker.sift.enabled=false", "seed=0,1",
            "recording.enabled=false", "recovery.skip=0", "recovery.perturb_at=3", "recovery.window=2",
            "skip_complete=true", f"hydra.sweep.dir={sweep}"]
    first = subprocess.run(args, capture_output=True, text=True, cwd=REPO, timeout=600)
    assert first.returncode == 0, first.stderr[-3000:]
    metrics = sorted(sweep.rglob("metrics.json"))
    assert len(metrics) == 2
    stamps = [p.stat().st_mtime_ns for p in metrics]
    again = subprocess.run(args, capture_output=True, text=True, cwd=REPO, timeout=600)
    assert again.returncode == 0, again.stderr[-3000:]
    assert again.stdout.count("already complete") == 2
    assert [p.stat().st_mtime_ns for p in metrics] == stamps
    table = subprocess.run([sys.executable, "-m", "mocap_cli", "ablate", str(sweep)],
                           capture_output=True, text=True, cwd=REPO, timeout=300)
    assert table.returncode == 0, table.stderr[-3000:]
    md = (sweep / "ablation.md").read_text()
    header = next(line for line in md.splitlines() if line.startswith("| tracker"))
    row = next(line for line in md.splitlines() if line.startswith("| local"))
    cells = dict(zip([c.strip() for c in header.split("|")], [c.strip() for c in row.split("|")],
                     strict=True))
    runs = [json.loads(p.read_text())["recovery"]["perturbation"] for p in metrics]
    want = np.mean([r["frames_to_recover"] is not None for r in runs])
    assert float(cells["recovered"].split(" ")[0]) == round(want, 2)
    at = [r["error_at_mm"] for r in runs]
    assert float(cells["error at the failure (mm)"].split(" ")[0]) == round(float(np.mean(at)), 1)

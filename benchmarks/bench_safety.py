"""Issue 36's figures: the run-folder lock's overhead per run, and Ctrl-C latency at start-up.

    PYTHONPATH=$PWD python benchmarks/bench_safety.py lock [N]      # own_run_folder enter + exit
    PYTHONPATH=$PWD python benchmarks/bench_safety.py ctrl-c [N]    # N tries of mocap track + SIGINT

Lock: what a run pays for the lock: :func:`mocap.run_folder.attempt.own_run_folder` (open, flock,
holder line, the leftover check on a complete run folder, unlink, close) plus the holder check of
write_manifest, timed N times. Ctrl-C: ``mocap track`` started N times, SIGINT sent when the
process reaches a start-up state (a library it has loaded, read from /proc/<pid>/maps, cycling
through STAGES), latency from the signal to the exit; each try must end with code 130 and one line.
"""

from __future__ import annotations

import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STAGES = ["yaml/_yaml", "numpy/_core/_multiarray_umath", "llvmlite/binding", "numba/_dispatcher",
          "cv2/cv2", "scipy/sparse", "numpy/fft", "scipy/spatial", "numpy/random", "numba/np"]


def lock(n: int) -> None:
    from mocap.run_folder.attempt import own_run_folder
    from mocap.run_folder.lock import require_held
    from mocap.run_folder.manifest import write_manifest

    run = Path(tempfile.mkdtemp()) / "run"
    run.mkdir()
    (run / "motion.npz").write_bytes(b"m" * 1000)
    (run / "metrics.json").write_text(json.dumps({"config": {}}))
    write_manifest(run, ["motion.npz", "metrics.json"])
    times = []
    for _ in range(n):
        t = time.perf_counter()
        with own_run_folder(run):
            require_held(run)
        times.append(time.perf_counter() - t)
    print(f"lock per run: median {statistics.median(times) * 1e3:.3f} ms, max {max(times) * 1e3:.3f} ms "
          f"over {n} runs")


def ctrl_c(n: int) -> None:
    repo = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    worst = 0.0
    for i in range(n):
        stage = STAGES[i % len(STAGES)]
        run = Path(tempfile.mkdtemp()) / "run"
        p = subprocess.Popen([sys.executable, "-m", "mocap_cli", "track", f"hydra.run.dir={run}",
                              "tracker=apf",
                              "data=walk_small", "data.frames=2", "recording.enabled=false"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=repo)
        while p.poll() is None:
            try:
                if stage in Path(f"/proc/{p.pid}/maps").read_text():
                    break
            except OSError:
                pass
            time.sleep(0.001)
        t = time.monotonic()
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
        latency = time.monotonic() - t
        worst = max(worst, latency)
        lines = [line for line in err.splitlines() if line.strip()]
        print(f"try {i + 1}: at {stage:32s} exit {p.returncode}, {len(lines)} line(s), {latency * 1e3:.0f} ms"
              f"  {lines[-1] if lines else ''}")
    print(f"Ctrl-C at start-up: worst latency {worst * 1e3:.0f} ms over {n} tries")


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "lock"
    count = int(sys.argv[2]) if len(sys.argv) > 2 else (200 if what == "lock" else 10)
    {"lock": lock, "ctrl-c": ctrl_c}[what](count)

"""What a user waits for before a command does its work (issue 38): wall seconds of whole
``mocap`` processes, medians of ``--repeat`` runs, under three bytecode conditions.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_startup.py [--repeat 5] [--run DIR] \
        [--commands floor,help,bad,export,track] [--modes cached,dontwrite,nopyc] [--out FILE]

Commands: ``floor`` (``python -c pass``: the interpreter alone), ``help`` (``mocap --help``),
``bad`` (``mocap export`` without its arguments: an argument error), ``trackhelp`` / ``trackbad``
(``mocap track --help`` / ``mocap track bogus=1``: a Hydra command's help and override error,
which compose its config), ``calhelp`` (``mocap calibrate --help``), ``help:CMD`` /
``bad:CMD`` (``mocap CMD --help`` / ``mocap CMD --no-such-flag``, any command; ``help:all`` /
``bad:all``: every command), ``export`` (``mocap export RUN --format bvh`` of a 60-frame run;
``--run`` names one, else one is tracked first with ``tracker=marker_apf data=walk_markers_small
data.frames=60``) and ``track`` (``mocap track tracker=hybrid data=walk_small frames=2``,
recording on, into a temporary folder).

Modes: ``cached`` (the usual: bytecode cached beside the sources, written by an untimed warm-up
run), ``dontwrite`` (``PYTHONDONTWRITEBYTECODE=1`` with the bytecode that
``scripts/setup_env.sh`` compiles at install time: read, never written) and ``nopyc``
(``PYTHONDONTWRITEBYTECODE=1`` and an empty ``PYTHONPYCACHEPREFIX``: no bytecode at all, every
module compiled at every start: an environment installed without compiling its bytecode, as the
issue measured). The numba cache is warm in every mode (the warm-up run fills it).

Absolute times follow the machine's load (printed: ``os.getloadavg``); compare ratios measured
in one session, e.g. this file run with PYTHONPATH on two checkouts in turn.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TARGETS = {"help": 0.3, "export": {"cached": 1.5, "dontwrite": 3.0}, "track": 4.0}


def mocap_argv() -> list[str]:
    """The ``mocap`` console script beside this interpreter, else ``python -m mocap_cli``."""
    script = Path(sys.executable).with_name("mocap")
    return [sys.executable, str(script)] if script.is_file() else [sys.executable, "-m", "mocap_cli"]


def make_run(folder: Path) -> Path:
    """A complete 60-frame run folder (the marker tracker on synthetic walking: seconds)."""
    r = subprocess.run([*mocap_argv(), "track", f"hydra.run.dir={folder}", "tracker=marker_apf",
                        "data=walk_markers_small", "data.frames=60", "recording.enabled=false"],
                       capture_output=True, text=True, cwd=REPO, env={**os.environ, "TQDM_DISABLE": "1"})
    if r.returncode != 0:
        raise SystemExit(f"could not track the 60-frame run: {r.stderr[-2000:]}")
    return folder


def commands(run: Path, tmp: Path, i: int) -> dict[str, tuple[list[str], int]]:
    """name -> (argv, the exit status it must end with); ``i`` numbers the track's run folder."""
    from mocap_cli.main import COMMANDS

    m = mocap_argv()
    return {
        **{f"help:{c}": ([*m, c, "--help"], 0) for c in COMMANDS},
        **{f"bad:{c}": ([*m, c, "--no-such-flag"], 2) for c in COMMANDS},
        "floor": ([sys.executable, "-c", "pass"], 0),
        "help": ([*m, "--help"], 0),
        "bad": ([*m, "export"], 2),
        "trackhelp": ([*m, "track", "--help"], 0),
        "trackbad": ([*m, "track", "bogus=1"], 2),
        "calhelp": ([*m, "calibrate", "--help"], 0),
        "export": ([*m, "export", str(run), "--format", "bvh", "--out", str(tmp / "run60.bvh"),
                    "--overwrite"], 0),
        "track": ([*m, "track", "tracker=hybrid", "data=walk_small", "frames=2",
                   f"hydra.run.dir={tmp / f'track2_{i}'}"], 0),
    }


def environment(mode: str, empty: Path) -> dict[str, str]:
    env = {**os.environ, "TQDM_DISABLE": "1"}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.pop("PYTHONPYCACHEPREFIX", None)
    if mode in ("dontwrite", "nopyc"):
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    if mode == "nopyc":
        env["PYTHONPYCACHEPREFIX"] = str(empty)
    return env


def timed(argv: list[str], env: dict[str, str], status: int) -> tuple[float, float]:
    """(wall seconds, CPU seconds: user + system of the process and its children). On a loaded
    machine the CPU time is the steadier figure: it is what the wall time is on an idle one."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(argv, capture_output=True, text=True, cwd=REPO, env=env)
    seconds = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != status:
        raise SystemExit(f"{' '.join(argv)} exited {r.returncode} (expected {status}): {r.stderr[-2000:]}")
    return seconds, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--run", type=Path, default=None, help="a complete run folder to export (60 frames)")
    p.add_argument("--commands", default="floor,help,bad,export,track")
    p.add_argument("--modes", default="cached,dontwrite,nopyc")
    p.add_argument("--label", default=str(REPO))
    p.add_argument("--out", type=Path, default=None, help="append one JSON line per command and mode")
    args = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_startup_") as tmp_name:
        tmp = Path(tmp_name)
        empty = tmp / "no_pycache"
        empty.mkdir()
        run = args.run or make_run(tmp / "run60")
        names = args.commands.split(",")
        for every in ("help:all", "bad:all"):
            if every in names:
                from mocap_cli.main import COMMANDS

                at = names.index(every)
                names[at:at + 1] = [f"{every[:-3]}{c}" for c in COMMANDS]
        calls = iter(range(10**6))
        for name in names:                           # warm-up: bytecode and numba caches filled
            argv, status = commands(run, tmp, next(calls))[name]
            timed(argv, environment("cached", empty), status)
        print(f"{'command':<22} {'mode':<10} {'median s':>9} {'min s':>7} {'cpu s':>6}  target   load")
        for name in names:
            for mode in args.modes.split(","):
                load = os.getloadavg()[0]
                times, cpus = [], []
                for _ in range(args.repeat):
                    argv, status = commands(run, tmp, next(calls))[name]
                    wall, cpu = timed(argv, environment(mode, empty), status)
                    times.append(wall)
                    cpus.append(cpu)
                target = TARGETS.get(name)
                if isinstance(target, dict):
                    target = target.get(mode)
                med, cpu = statistics.median(times), statistics.median(cpus)
                print(f"{name:<22} {mode:<10} {med:9.2f} {min(times):7.2f} {cpu:6.2f}  "
                      f"{'' if target is None else f'<= {target}':<7} {load:5.1f}", flush=True)
                if args.out:
                    with args.out.open("a") as f:
                        f.write(json.dumps({"label": args.label, "command": name, "mode": mode,
                                            "median_s": med, "times_s": times, "cpu_s": cpus,
                                            "target_s": target,
                                            "load": [load, os.getloadavg()[0]]}) + "\n")


if __name__ == "__main__":
    main()

"""``mocap replay``: review a run: open its recording in the Rerun viewer where a display exists, otherwise
print a headless summary (frames, entities, final metrics) read from the file itself, and the
run's motion.npz (frames, APF calls, misaligned limbs) when the run directory has one. A run
directory that is not a complete run (no valid manifest.json) is flagged: a WARNING line,
the summary of what is there (e.g. recording.failed.rrd), and exit status 1.

    mocap replay outputs/track/<run>            # a run directory
    mocap replay path/to/recording.rrd [--summary]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

from mocap_cli.errors import ArgumentParser


def find_recording(target: Path) -> Path:
    if target.is_dir():
        for name in ("recording.rrd", "recording.failed.rrd"):
            if (target / name).is_file():
                return target / name
        raise FileNotFoundError(f"{target}: no recording.rrd in this run directory")
    if not target.is_file():
        raise FileNotFoundError(f"{target}: no such run directory or .rrd file")
    return target


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap replay", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("target", type=Path, help="run directory or .rrd file")
    p.add_argument("--summary", action="store_true", help="print the summary, never open a viewer")
    args = p.parse_args(argv)
    from mocap.recording.reader import read_recording, summary_text

    rrd = find_recording(args.target)
    problem = None
    if args.target.is_dir():
        from mocap.run_folder.manifest import manifest_problem

        problem = manifest_problem(args.target)
        if problem is not None:
            print(f"WARNING: {args.target}: not a complete run ({problem}); {rrd.name} is not a finished "
                  "run's recording", file=sys.stderr)
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    viewer = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    if has_display and not args.summary and Path(viewer).exists():
        return subprocess.call([viewer, str(rrd)])
    print(summary_text(read_recording(rrd)))
    motion = rrd.parent / "motion.npz"
    if motion.is_file():
        from mocap.export.motion import MotionFileError, load_motion
        from mocap.export.motion import summary_text as motion_summary

        try:
            print(motion_summary(load_motion(motion)))
        except MotionFileError as exc:
            print(f"motion.npz unreadable: {exc}")
    return 1 if problem is not None else 0


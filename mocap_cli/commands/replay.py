"""``mocap replay``: review a run: open its recording in the Rerun viewer where a display exists, otherwise
print a headless summary (frames, entities, final metrics) read from the file itself, and the
run's motion.npz (frames, APF calls, misaligned limbs) when the run directory has one. A run
directory that is not a complete run (no valid manifest.json) is flagged: a WARNING line,
the summary of what is there (e.g. recording.failed.rrd), and exit status 1. A several-people
run's motion is summarised per person. A motion without a recording (``mocap import-motion``'s
folder or .npz) has nothing to open in the viewer: its motion's summary is printed.

    mocap replay outputs/track/<run>            # a run directory
    mocap replay path/to/recording.rrd [--summary]
    mocap replay runs/walk                      # an imported clip: its motion's summary
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


def motion_text(path: Path) -> str:
    """The summary of a motion.npz of either format (one person, several people), or why it
    cannot be read."""
    from mocap.export.motion import MotionFileError, load_motion
    from mocap.export.motion import summary_text as motion_summary
    from mocap.export.people_motion import load_people_motion, people_summary_text
    from mocap.run_folder.export import PEOPLE_FORMAT, motion_file_facts

    try:
        if motion_file_facts(path).get("format") == PEOPLE_FORMAT:
            return people_summary_text(load_people_motion(path))
        return motion_summary(load_motion(path))
    except MotionFileError as exc:
        return f"{path.name} unreadable: {exc}"


def replay_motion(target: Path) -> int:
    """A motion without a recording (an imported clip's folder or .npz): its summary; a run
    folder that should have a recording is flagged (exit status 1)."""
    from mocap.run_folder.export import motion_file_facts

    path = target if target.is_file() else target / "motion.npz"
    facts = motion_file_facts(path)
    if not facts:
        raise ValueError(f"{path}: not a readable motion file (.npz)")
    if not facts.get("imported"):
        print(f"WARNING: {target}: no recording.rrd (a run that recorded nothing, or not finished); the "
              "motion's summary only", file=sys.stderr)
    else:
        print(f"{target}: an imported clip (mocap import-motion), no recording to open: its motion")
    print(motion_text(path))
    return 0 if facts.get("imported") else 1


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap replay", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("target", type=Path, help="run directory or .rrd file")
    p.add_argument("--summary", action="store_true", help="print the summary, never open a viewer")
    args = p.parse_args(argv)
    target = args.target
    if (target.is_file() and target.suffix == ".npz") or (
            target.is_dir() and (target / "motion.npz").is_file()
            and not any((target / n).is_file() for n in ("recording.rrd", "recording.failed.rrd"))):
        return replay_motion(target)
    rrd = find_recording(args.target)
    from mocap.recording.reader import read_recording, summary_text  # (the numeric stack: once found)

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
        print(motion_text(motion))
    return 1 if problem is not None else 0


"""``mocap``: the command line. ``mocap <command> [arguments]``; ``mocap --help`` lists the
commands, ``mocap <command> --help`` explains one.

Hydra commands (track, recovery, video-check, make-dataset, segment) take Hydra overrides
after the command (``mocap track tracker=hybrid data=mismatch_box frames=20``, ``mocap track
--multirun tracker=apf,local seed=0,1``); the others take flags. A user error (an unknown
command, config key or option, a value out of range, a missing file) prints one line,
``mocap <command>: error: <message>``, and exits with 2; ``mocap --debug <command> ...`` (or
``HYDRA_FULL_ERROR=1``) shows the traceback instead. Programming errors always show theirs.
"""

from __future__ import annotations

import importlib
import os
import sys

from mocap_cli import interrupt  # (installed by mocap_cli/__init__.py, before any heavy import)
from mocap_cli.errors import user_error_message

#: command -> (module under mocap_cli.commands, one line of help)
COMMANDS: dict[str, tuple[str, str]] = {
    "track": ("track", "track a sequence with one tracker: motion.npz, metrics.json, recording.rrd (Hydra)"),
    "replay": ("replay", "review a run: open its recording, or print a summary of it"),
    "export": ("export", "export a run's motion to BVH, TRC, glTF (GLB) or C3D"),
    "ablate": ("ablate", "collect a sweep's metrics into ablation.md, ablation.csv and ablation.png"),
    "make-dataset": ("make_dataset", "render a synthetic multi-view sequence with ground truth (Hydra)"),
    "capture": ("capture", "videos -> motion in one command: detect, (calibrate), track, export; resumable"),
    "detect": ("detect", "calibrated videos -> 2D keypoints and person masks: a Pose2Sim-style folder"),
    "segment": ("segment", "segment a video recording into silhouettes: a sequence folder (Hydra)"),
    "video-check": ("video_check", "track a video and check it against its keypoints and masks (Hydra)"),
    "recovery": ("recovery", "track with injected failures and measure the recovery (Hydra)"),
    "rescore": ("rescore", "re-score finished runs with today's evaluation, without tracking again"),
    "calibrate": ("calibrate", "calibrate cameras: board intrinsics; extrinsics from a board or people"),
    "convert": ("convert", "turn a Pose2Sim folder (calibration + OpenPose JSON) into a sequence folder"),
    "gt-from-joints": ("gt_from_joints", "add ground truth to a sequence folder from named 3D joints"),
    "import-motion": ("import_motion", "retarget a BVH clip onto the body: a run's motion.npz"),
    "train-prior": ("train_prior", "train the Parzen pose prior on the training motions"),
    "build-body-model": ("build_body_model", "build the PCA body model from a database of bodies"),
    "show-body": ("show_body", "show the body model: mean, shape components, poses (recording + PNG)"),
}


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: mocap [--debug] <command> [arguments]", "", "commands:"]
    lines += [f"  {name:<{width}}  {text}" for name, (_, text) in COMMANDS.items()]
    lines += ["", "mocap <command> --help: the command's arguments. --debug: tracebacks for user errors.",
              "Hydra commands take overrides: mocap track tracker=hybrid data=walk_small frames=20"]
    return "\n".join(lines)


def run(command: str, argv: list[str]) -> int:
    """Run one command with its arguments (what ``mocap <command> <argv>`` does, errors raised)."""
    if command not in COMMANDS:
        raise ValueError(f"unknown command {command!r} (commands: {', '.join(COMMANDS)})")
    module = importlib.import_module(f"mocap_cli.commands.{COMMANDS[command][0]}")
    interrupt.check()           # a Ctrl-C swallowed by a library while it was imported
    return int(module.main(argv) or 0)


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    debug = bool(os.environ.get("HYDRA_FULL_ERROR"))
    while args and args[0] in ("--debug", "-h", "--help"):
        if args[0] != "--debug":
            print(usage())
            return 0
        debug = True
        args.pop(0)
    if not args:
        print(usage(), file=sys.stderr)
        return 2
    command, rest = args[0], args[1:]
    from mocap_cli import quiet

    if debug:
        os.environ[quiet.DEBUG_ENV] = "1"           # the commands keep native logs (mocap_cli/quiet.py)
    else:
        quiet.one_line_warnings()
    if command not in COMMANDS:
        print(f"mocap: error: unknown command {command!r} (commands: {', '.join(COMMANDS)}; "
              "mocap --help)", file=sys.stderr)
        return 2
    interrupt.set_command(f"mocap {command}")
    try:
        code = run(command, rest)
        interrupt.check()
        return code
    except KeyboardInterrupt:
        if debug:
            raise
        return _leave(f"mocap {command}: interrupted (Ctrl-C)", interrupt.EXIT_CODE, argv is None, now=True)
    except Exception as exc:
        message = None if debug else user_error_message(exc)
        if message is None and isinstance(exc, OSError) and not debug:
            return _leave(f"mocap {command}: error: {exc}", 1, argv is None)    # disk full, a failing write
        if message is None:
            raise
        return _leave(f"mocap {command}: error: {message}", 2, argv is None)


def _leave(line: str, code: int, program: bool, now: bool = False) -> int:
    """Print ``line`` and return ``code``. When ``mocap`` is the program (``program``: not called
    in-process), a process that gave up on a blocked recording writer leaves at once (its clean-up
    would wait on that writer), and so does an interrupted one (``now``: its run already cleaned
    up; the interpreter's own exit could report the interrupt again as death by SIGINT)."""
    print(" ".join(line.split("\n")), file=sys.stderr, flush=True)
    sink = sys.modules.get("mocap.recording.rerun_sink")       # (never imported here for this)
    if program and (now or (sink is not None and sink.ABANDONED)):
        import logging

        logging.shutdown()
        sys.stdout.flush()
        os._exit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())

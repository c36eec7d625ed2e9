"""``mocap import-motion``: retarget a motion-capture clip (BVH) onto the body and write it as a
run's ``motion.npz``, so that ``mocap export``, replay and rendering take it like a run.

    mocap import-motion CLIP.bvh --out runs/walk [--body paper22] [--step 2] [--fps 30]
    mocap import-motion other.bvh --out other.npz --unit cm --up y --frames 0:300

The clip's skeleton is recognised by a name map (mocap/clips/maps: bandai_namco, cmu, mocap) or
given with --map; a skeleton no map recognises needs --unit and --up. What the retargeting
does and how far it lands: docs/clips.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mocap_cli.errors import ArgumentParser

#: the length units of :data:`mocap.clips.bvh.UNITS`, written out here so that reading the arguments
#: imports no numeric stack (tests/cli/test_startup.py checks that they are the reader's)
UNIT_NAMES = ("cm", "inch", "m", "mm")


def frame_slice(text: str) -> slice:
    """``start:stop[:step]`` (any part may be empty) -> slice; a user error otherwise."""
    parts = text.split(":")
    if not 2 <= len(parts) <= 3:
        raise argparse.ArgumentTypeError(f"--frames {text!r}: start:stop or start:stop:step")
    try:
        return slice(*(int(p) if p else None for p in parts))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--frames {text!r}: integers, e.g. 0:300 or ::2") from None


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap import-motion", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("clip", type=Path, help="a BVH file")
    p.add_argument("--out", type=Path, required=True, help="motion.npz, or a folder for one")
    p.add_argument("--body", default="paper22", help="body preset (paper22, full, ...)")
    p.add_argument("--map", dest="name_map", default=None,
                   help="name map: a name in mocap/clips/maps or a YAML file (default: detected)")
    p.add_argument("--unit", default=None, choices=UNIT_NAMES, help="the file's length unit")
    p.add_argument("--up", default=None, choices=["y", "z"], help="the file's up axis")
    p.add_argument("--frames", type=frame_slice, default=None, help="start:stop[:step] of the file")
    p.add_argument("--fps", type=float, default=None, help="resample to this rate first")
    p.add_argument("--step", type=int, default=1, help="then keep every step-th frame")
    p.add_argument("--match", default="positions", choices=["positions", "segments"])
    p.add_argument("--overwrite", action="store_true")
    args = p.parse_args(argv)
    if not args.clip.is_file():
        raise FileNotFoundError(f"{args.clip}: no such BVH file")
    if args.step < 1:
        raise ValueError(f"--step {args.step}: a positive integer")
    if args.fps is not None:
        from mocap.checks import check_fps

        check_fps(args.fps, "--fps")
    out = args.out / "motion.npz" if args.out.is_dir() or not args.out.suffix else args.out
    if out.exists() and not args.overwrite:
        raise FileExistsError(f"{out} exists (--overwrite to replace it)")

    import numpy as np

    from mocap.body import load_body
    from mocap.clips import import_motion

    body = load_body(args.body)
    written = import_motion(args.clip, out, body, unit=args.unit, up=args.up, frames=args.frames,
                            name_map=args.name_map, step=args.step, fps=args.fps,
                            overwrite=args.overwrite, match=args.match)
    with np.load(written, allow_pickle=False) as z:
        res = z["retarget_residual_mm"]
    print(f"{args.clip.name} -> {written}: {res.shape[0]} frames on {args.body}, residual median "
          f"{np.nanmedian(res):.1f} mm, worst {np.nanmax(res):.1f} mm")
    return 0

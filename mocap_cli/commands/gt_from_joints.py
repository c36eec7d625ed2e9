"""``mocap gt-from-joints``: add ground truth to a sequence folder from a folder of named 3D
joints (CSV or NPZ).

    mocap gt-from-joints JOINTS_DIR SEQUENCE_DIR --skeleton shelf14 [--scale 0.001]

Layouts: mocap/data/named_joints.py. --skeleton is required: the joints' naming, one of the
skeletons of mocap/eval/by_name.py (humaneva15, shelf14, coco17, body25) or none (the body's own
joint names); tracking refuses ground truth whose names it cannot match.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mocap.body.skeletons import SKELETONS
from mocap_cli.errors import ArgumentParser


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap gt-from-joints", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("joints_dir", type=Path)
    p.add_argument("sequence_dir", type=Path)
    p.add_argument("--skeleton", required=True, choices=[*SKELETONS, "none"],
                   help="the joints' naming: a skeleton of mocap/eval/by_name.py, or none (the body's "
                        "own names)")
    p.add_argument("--scale", type=float, default=1.0, help="to metres (0.001 for mm)")
    p.add_argument("--overwrite", action="store_true")
    args = p.parse_args(argv)
    from mocap.data.named_joints import add_ground_truth, read_named_joints, sequence_info

    sequence_info(args.sequence_dir)        # a folder that is not a sequence folder: refused first
    names, joints, valid = read_named_joints(args.joints_dir, args.scale)
    out = add_ground_truth(args.sequence_dir, names, joints, valid,
                           "" if args.skeleton == "none" else args.skeleton, args.overwrite)
    print(f"wrote {out}: {joints.shape[0]} frames, {len(names)} joints, "
          f"{int((~valid).sum())} missing entries")
    return 0


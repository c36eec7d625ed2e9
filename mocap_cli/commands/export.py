"""``mocap export``: export a run's motion (its motion.npz) to BVH, TRC, glTF (GLB) or C3D.

    mocap export outputs/track/<run> --format bvh
    mocap export outputs/track/<run> --format gltf --out walk.glb --overwrite

    mocap export outputs/track/<people run> --format bvh      # one BVH per person: motion_p<id>.bvh
    mocap export runs/walk --format gltf                      # a clip from mocap import-motion

Default output: <run dir>/motion.<bvh|trc|glb|c3d>. The run folder must be a complete run (a
valid manifest.json); --accept-unverified exports one written before manifests, with a
WARNING. A several-people run: one BVH per person (<out stem>_p<id>.bvh), one TRC / C3D with
every person's markers (p<id>_<marker>), one GLB with a skinned body per person; --person ID
exports one of them alone. Axes and units per format: docs/data_formats.md ("Out: exports"),
mocap/export/axes.py.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mocap.export import FORMATS
from mocap_cli.errors import ArgumentParser


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap export", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run_dir", type=Path)
    p.add_argument("--format", required=True, help=f"one of: {', '.join(FORMATS)}")
    p.add_argument("--out", type=Path, default=None, help="output file (default: in the run directory)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.add_argument("--markers", default="landmarks", choices=["landmarks", "joints", "tracker"],
                   help="TRC/C3D points: the body's landmarks, its joints, or a marker tracker's own")
    p.add_argument("--person", type=int, default=None,
                   help="a several-people run: the person (track id, metrics.json's people) to export")
    p.add_argument("--influences", type=int, default=4, choices=[4, 8],
                   help="glTF: joints per vertex; 4 (default) every reader applies, 8 is mocap's "
                        "skinning exactly (readers that apply two attribute sets)")
    p.add_argument("--accept-unverified", action="store_true",
                   help="export a run folder without a valid manifest.json (written before manifests)")
    args = p.parse_args(argv)
    from mocap.run_folder.export import export_files  # (the numeric stack: after the arguments)

    t = time.perf_counter()
    if args.accept_unverified:
        from mocap.run_folder.manifest import manifest_problem

        problem = manifest_problem(args.run_dir)
        if problem is not None:
            print(f"WARNING: {args.run_dir}: exporting an unverified run ({problem})", file=sys.stderr)
    outs = export_files(args.run_dir, args.format, args.out, args.overwrite, markers=args.markers,
                        require_manifest=not args.accept_unverified, person=args.person,
                        influences=args.influences)
    print(f"wrote {', '.join(map(str, outs))} ({time.perf_counter() - t:.2f} s)")
    return 0


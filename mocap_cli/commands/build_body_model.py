"""``mocap build-body-model``: build the PCA body model from a database of registered bodies.

    # the shipped model: a few hundred adult bodies sampled from anny (build extra needed:
    # bash scripts/install_build_deps.sh)
    .venv-build/bin/python -m mocap_cli build-body-model --anny 600

    # your own database: a folder of registered rest-pose meshes of one topology, in the
    # body frame (metres, z up, front -y, A-pose); skinning and joints are transferred
    # from the shipped model
    mocap build-body-model --meshes path/to/folder --out my_model.npz

Writes the model atomically and prints the build report (held-out errors).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from mocap_cli.errors import ArgumentParser


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap build-body-model", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--anny", type=int, metavar="N", help="sample N adult bodies from anny")
    src.add_argument("--meshes", type=Path, help="folder of registered meshes of one topology")
    p.add_argument("--out", type=Path, default=None, help="model file (default: the packaged one, "
                   "mocap/body/assets/body_model.npz)")
    p.add_argument("--components", type=int, default=20)
    p.add_argument("--target-faces", type=int, default=10000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    from mocap.body.build.assemble import ANNY_ATTRIBUTION, BuildSettings, build_model
    from mocap.body.build.database import load_mesh_folder, sample_anny
    from mocap.body.model_file import default_model_path, load_body_model_data, save_body_model_data

    args.out = args.out or default_model_path()

    t0 = time.time()
    settings = BuildSettings(num_components=args.components, target_faces=args.target_faces,
                             seed=args.seed)
    if args.anny:
        print(f"[build] sampling {args.anny} bodies from anny ...", flush=True)
        db = sample_anny(args.anny, seed=args.seed)
        model, report = build_model(db, settings, attribution=ANNY_ATTRIBUTION)
    else:
        db = load_mesh_folder(args.meshes)
        reference = load_body_model_data()
        model, report = build_model(db, settings, reference=reference,
                                    attribution=f"Built from {db.description}; skeleton "
                                    f"transferred from: {reference.attribution}")
    save_body_model_data(model, args.out)
    report["build_seconds"] = round(time.time() - t0, 1)
    print(json.dumps(report, indent=2))
    print(f"[build] wrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB)")
    return 0


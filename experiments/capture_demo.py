"""Question: how long does each stage of ``mocap capture`` take on the Pose2Sim demo, and do
independent readers open what it exports?

    python -m experiments.capture_demo [--out outputs/capture_demo] [--stop N] [--demo FOLDER]
    python -m experiments.capture_demo --out outputs/capture_people --formats bvh \
        --capture-args "--calibrate people --height 1.72" --compare ../shared/data/pose2sim-demo/Calib.toml

Runs ``mocap capture DEMO --out OUT`` in a subprocess unless OUT already holds a finished
capture (then only reads it: the stage times are those recorded in its capture.json), then
opens the exports with packages that share no code with mocap's writers: ``bvhio`` (BVH),
``ezc3d`` (C3D), ``pygltflib`` (glTF/GLB), and a plain parse of the TRC's tab-separated text
(OpenSim's layout). Prints a table of stage wall times and one line per file; writes
OUT/capture_demo.json. --compare REF: the calibration the capture made (``--calibrate``)
against REF after a similarity alignment (:func:`mocap.calibration.compare.compare_rigs`).
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

DEMO = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "pose2sim-demo"


def read_bvh(path: Path) -> dict:
    import bvhio

    bvh = bvhio.readAsBvh(str(path))
    joints = []
    stack = [bvh.Root]
    while stack:
        j = stack.pop()
        joints.append(j.Name)
        stack += list(j.Children)
    return {"reader": "bvhio", "frames": int(bvh.FrameCount), "joints": len(joints),
            "frame_time_s": float(bvh.FrameTime)}


def read_c3d(path: Path) -> dict:
    import ezc3d

    c = ezc3d.c3d(str(path))
    pts = c["data"]["points"]                       # (4, markers, frames)
    return {"reader": "ezc3d", "frames": int(pts.shape[2]), "markers": int(pts.shape[1]),
            "rate_hz": float(c["parameters"]["POINT"]["RATE"]["value"][0]),
            "finite": bool(np.isfinite(pts[:3]).all())}


def read_glb(path: Path) -> dict:
    import pygltflib

    g = pygltflib.GLTF2().load(str(path))
    anim = g.animations[0] if g.animations else None
    frames = g.accessors[anim.samplers[0].input].count if anim is not None else 0
    return {"reader": "pygltflib", "frames": int(frames), "skins": len(g.skins),
            "joints": len(g.skins[0].joints) if g.skins else 0, "meshes": len(g.meshes),
            "animation_channels": len(anim.channels) if anim is not None else 0}


def read_trc(path: Path) -> dict:
    lines = path.read_text().split("\n")
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=False))
    data = np.loadtxt(path, skiprows=6, delimiter="\t", ndmin=2)
    return {"reader": "plain text (OpenSim layout)", "frames": int(data.shape[0]),
            "markers": int(header["NumMarkers"]), "header_frames": int(header["NumFrames"]),
            "units": header.get("Units")}


READERS = {".bvh": read_bvh, ".c3d": read_c3d, ".glb": read_glb, ".trc": read_trc}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("outputs/capture_demo"))
    ap.add_argument("--demo", type=Path, default=DEMO)
    ap.add_argument("--stop", type=int, default=None, help="capture's --stop (default: every frame)")
    ap.add_argument("--formats", default=None, help="capture's --formats (default: every format)")
    ap.add_argument("--capture-args", default="", help="more arguments of mocap capture, one string")
    ap.add_argument("--compare", type=Path, default=None, help="a reference calibration (with --calibrate)")
    args = ap.parse_args(argv)
    record_path = args.out / "capture.json"
    wall = None
    if not (record_path.is_file() and "summary" in json.loads(record_path.read_text())):
        cmd = [sys.executable, "-m", "mocap_cli", "capture", str(args.demo), "--out", str(args.out)]
        cmd += (["--stop", str(args.stop)] if args.stop is not None else []) + shlex.split(args.capture_args)
        cmd += ["--formats", args.formats] if args.formats else []
        t = time.perf_counter()
        subprocess.run(cmd, check=True)
        wall = time.perf_counter() - t
    record = json.loads(record_path.read_text())
    stages = {name: (r["seconds"], r.get("cpu_seconds")) for name, r in record["stages"].items()}
    files = {f: READERS[Path(f).suffix](args.out / f) for f in record["summary"]["files"]}
    result = {"command": " ".join(["mocap capture", str(args.demo), "--out", str(args.out)]
                                  + (["--stop", str(args.stop)] if args.stop is not None else [])
                                  + ([args.capture_args] if args.capture_args else [])),
              "stage_seconds": stages, "process_wall_s": wall, "summary": record["summary"], "files": files}
    made = args.out / "calibrate" / "Calib.toml"
    if args.compare is not None and made.is_file():
        from mocap.calibration.compare import compare_rigs
        from mocap.cameras import load_calibration

        cmp = compare_rigs(load_calibration(made), load_calibration(args.compare))
        per = {"centre_error_cm": 100 * cmp.centre_error, "rotation_error_deg": cmp.rotation_error}
        result["compare"] = {"reference": str(args.compare), "scale": cmp.scale,
                             **{k: dict(zip(cmp.names, v.tolist(), strict=True)) for k, v in per.items()}}
        print(f"calibration against {args.compare} (similarity alignment):\n{cmp.table()}")
    (args.out / "capture_demo.json").write_text(json.dumps(result, indent=1))
    print("| stage | wall s | CPU s |\n|---|---|---|")
    for name, (s, cpu) in stages.items():
        print(f"| {name} | {s:.1f} | {'' if cpu is None else f'{cpu:.1f}'} |")
    if wall is not None:
        print(f"| whole process (start-up and checks included) | {wall:.1f} | |")
    print()
    for f, info in files.items():
        print(f"{f}: " + ", ".join(f"{k} {v}" for k, v in info.items()))
    return result


if __name__ == "__main__":
    main()

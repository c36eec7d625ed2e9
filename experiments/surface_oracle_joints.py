"""The joint error of the surface oracle (our body's shape and poses fitted to the TRUE SURFACE,
:func:`mocap.eval.surface_oracle.fit_surface_oracle`) beside the joint oracle's, per sequence folder:
how close to the true joints a tracker can come that places our body's surface where the true one is
(a silhouette-only tracker at its best), i.e. the part of a silhouette tracker's joint error that
is our body's skeleton sitting elsewhere in the flesh than the true one (issue 34 item 4).

    python -m experiments.surface_oracle_joints data/real_motion/dev/walk_heavy_man ... [--frames 40]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mocap.body import load_body
from mocap.data.sources import folder_sequence
from mocap.eval.by_name import NameScorer
from mocap.eval.run_metrics import oracle_fit
from mocap.eval.surface_oracle import fit_surface_oracle


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="+", type=Path)
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--save", type=Path, help="keep the fits here (<data>.npz)")
    a = p.parse_args(argv)
    body = load_body("paper22")
    for path in a.sequences:
        seq = folder_sequence(body=body, path=str(path), name=f"real_{path.name}", seed=0)
        F = a.frames
        joint = oracle_fit(body, seq, F)
        surf = fit_surface_oracle(body, seq.gt.surface[:F], seq.gt.surface_faces, joint.alpha, joint.chi[:F])
        scorer = NameScorer(body, seq.gt.person(0))
        frames = surf.frames
        # score() reads consecutive frames: score the strided frames one by one
        def mpjpe(alpha, chi, f, scorer=scorer):
            return scorer.score(scorer.points(body.shaped(alpha), chi), int(f))["mpjpe_mm"]

        errs = [mpjpe(surf.alpha, surf.chi[i:i + 1], f) for i, f in enumerate(frames)]
        errs_j = [mpjpe(joint.alpha, joint.chi[f:f + 1], f) for f in frames]
        est = scorer.points(body.shaped(surf.alpha), surf.chi)
        names = [n for n in scorer.gt.joint_names if scorer.mapping.get(n) is not None
                 and n in (scorer.kwargs["only"] or scorer.gt.joint_names)]
        idx = [list(scorer.gt.joint_names).index(n) for n in names]
        d = 1e3 * (np.stack([np.asarray(est[scorer.mapping[n]]) for n in names], 1)
                   - np.asarray(scorer.gt.joints)[frames][:, idx])
        offsets = ", ".join(f"{n} {np.round(d[:, k].mean(0)).astype(int).tolist()}"
                            for k, n in enumerate(names))
        if a.save:
            a.save.mkdir(parents=True, exist_ok=True)
            np.savez(a.save / f"{seq.name}.npz", alpha=surf.alpha, chi=surf.chi, frames=frames,
                     joint_alpha=joint.alpha, joint_chi=joint.chi)
        print(f"{seq.name}: joints of the surface oracle {np.mean(errs):.1f} mm, of the joint oracle "
              f"{np.mean(errs_j):.1f} mm (frames {[int(f) for f in frames]}); surface oracle surface "
              f"{surf.metrics['surface_to_mesh_mm']:.1f} mm; mean offsets (surface oracle - truth, mm): "
              f"{offsets}", flush=True)


if __name__ == "__main__":
    main()

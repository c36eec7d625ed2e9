"""Is the silhouette-only start's error a search failure or an energy ambiguity (issue 34 item 4)?

On frame 0 of each sequence folder, the initialiser's own silhouette energy E_S (the energy that
ranks its hypotheses: ``select_resolution`` px, the full mesh, mean over valid views) of

- ``start``: the self-initialisation (read from ``--init-cache``, the random state ``mocap track``
  gives it at ``--seed``);
- ``joint``: the joint oracle's frame-0 pose and shape (our body fitted to the true joints);
- ``surface``: the surface oracle's frame-0 pose and shape (our body fitted to the true surface);
- ``surface+local``: the surface oracle's pose after the initialiser's last step on it (the contour
  local optimisation), so that a pose a few millimetres off a minimum of E_S is not counted against
  the oracle; ``joint+local`` the same from the joint oracle;

with the joint error of each (mean and per joint, mm) and E_S at the pose searches' resolution
(``resolution`` px on the energy mesh, ``E_S coarse``). If E_S(oracle) < E_S(start) the search
missed a better minimum; if not, one frame's silhouettes prefer the wrong pose (an ambiguity).

    python -m experiments.sil_start_energy data/real_motion/dev/* --init-cache outputs/init_cache \\
        [--seed 0] [--out outputs/start_energy.jsonl]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from experiments.sil_hybrid_diagnosis import joint_errors
from experiments.tools.jsonl import report
from mocap.body import load_body
from mocap.body.energy_mesh import energy_mesh_for
from mocap.data.sources import folder_sequence
from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
from mocap.eval.by_name import NameScorer
from mocap.eval.run_metrics import oracle_fit
from mocap.eval.surface_oracle import SurfaceOracleSettings, fit_surface_oracle
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.optimize import optimize_pose
from mocap.trackers.presets import make_tracker
from mocap.trackers.run import frame_of


class StartEnergies:
    """E_S of the initialiser on one frame's masks (C, H, W): ``fine(alpha, chis)`` at
    ``select_resolution`` on the full mesh, ``coarse(alpha, chis)`` at ``resolution`` on the
    energy mesh, both (P, D) -> (P,); ``local(alpha, chi)`` the initialiser's contour step."""

    def __init__(self, body, rig, masks, settings):
        self.body, self.rig, self.settings = body, rig, settings
        self.fine_scale = rig.scale_for(settings.select_resolution)
        self.scale = rig.scale_for(settings.resolution)
        names = tuple(rig.names)
        self.fine_target = silhouette_target(masks, self.fine_scale, view_names=names)
        self.target = silhouette_target(masks, self.scale, view_names=names)
        self.mesh = energy_mesh_for(body, settings.energy_mesh)
        self.obs = observed_contours(masks)
        self.matcher = ContourMatcher(body, rig)

    def fine(self, alpha, chis):
        e = SilhouetteEnergy(self.body.shaped(alpha), self.rig, self.fine_scale)
        return e(np.atleast_2d(chis), self.fine_target)

    def coarse(self, alpha, chis):
        e = SilhouetteEnergy(self.body.shaped(alpha), self.rig, self.scale, mesh=self.mesh)
        return e(np.atleast_2d(chis), self.target)

    def local(self, alpha, chi):
        out, _ = optimize_pose(self.body.shaped(alpha), chi, lambda v: self.matcher(v, self.obs),
                               self.settings.local_iterations)
        return out


def measure(seq_path: Path, seed: int, cache: str | None, frames: int) -> dict:
    body = load_body("paper22")
    seq = folder_sequence(body=body, path=str(seq_path), name=f"real_{seq_path.name}", seed=seed)
    tracker = make_tracker("hybrid", body=body, rig=seq.rig, rng=np.random.default_rng([seed, 1]))
    frame = frame_of(seq, 0)
    est, _ = tracker.initializer(cache).start(frame)
    poses = {"start": (np.asarray(est[0].alpha), np.asarray(est[0].chi))}
    joint = oracle_fit(body, seq, frames)
    poses["joint"] = (np.asarray(joint.alpha), np.asarray(joint.chi[0]))
    # the surface oracle on frame 0 alone (shape and pose fitted to its true surface)
    surf = fit_surface_oracle(body, seq.gt.surface[:1], seq.gt.surface_faces, joint.alpha, joint.chi[:1],
                              SurfaceOracleSettings())
    poses["surface"] = (np.asarray(surf.alpha), np.asarray(surf.chi[0]))
    E = StartEnergies(body, seq.rig, frame.masks, tracker.init_settings)
    for name in ("joint", "surface"):
        a, c = poses[name]
        poses[f"{name}+local"] = (a, E.local(a, c))
    scorer = NameScorer(body, seq.gt.person(0))
    out = {"data": seq.name, "seed": seed, "poses": {}}
    for name, (a, c) in poses.items():
        names, err, _, _ = joint_errors(scorer, a[None], c[None])
        out["poses"][name] = {"E_S_fine": float(E.fine(a, c)[0]), "E_S_coarse": float(E.coarse(a, c)[0]),
                              "mpjpe_mm": float(err[0].mean()),
                              "per_joint_mm": {n: round(float(err[0, k]), 1) for k, n in enumerate(names)},
                              "alpha": [round(float(x), 3) for x in a[:8]]}
    # the oracles' poses on the start's shape (is the shape or the pose the start's problem?)
    a_s = poses["start"][0]
    for name in ("joint", "surface"):
        c = E.local(a_s, poses[name][1])
        names, err, _, _ = joint_errors(scorer, a_s[None], c[None])
        out["poses"][f"{name} pose, start shape"] = {
            "E_S_fine": float(E.fine(a_s, c)[0]), "E_S_coarse": float(E.coarse(a_s, c)[0]),
            "mpjpe_mm": float(err[0].mean()),
            "per_joint_mm": {n: round(float(err[0, k]), 1) for k, n in enumerate(names)}}
    return out


def summary(r: dict) -> str:
    s = r["poses"]["start"]["E_S_fine"]
    parts = [f"{k} E {v['E_S_fine']:.4f} ({(v['E_S_fine'] / s - 1) * 100:+.1f}%) "
             f"coarse {v['E_S_coarse']:.4f} joints {v['mpjpe_mm']:.1f}" for k, v in r["poses"].items()]
    st = r["poses"]["start"]["per_joint_mm"]
    worst = ", ".join(f"{k} {v:.0f}" for k, v in sorted(st.items(), key=lambda kv: -kv[1])[:5])
    return f"{r['data']}: " + "; ".join(parts) + f"; start's worst joints {worst}"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequences", nargs="+", type=Path)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--frames", type=int, default=40, help="frames of the joint oracle's fit (as a run's)")
    p.add_argument("--init-cache", default="outputs/init_cache")
    p.add_argument("--out", type=Path)
    a = p.parse_args(argv)
    for s in a.sequences:
        r = measure(s, a.seed, a.init_cache, a.frames)
        report(r, summary(r), a.out)


if __name__ == "__main__":
    main()

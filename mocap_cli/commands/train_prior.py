"""``mocap train-prior``: train the Parzen pose prior (Zhang et al. 2013, Eq. 15) on poses of
the training motions (:func:`mocap.energy.train_prior.train_prior`).

    mocap train-prior [--body paper22] [--samples 100] [--seed 0] [--out PATH]

The default output is outputs/priors/pose_prior_<body>.npz under the current directory, never
the prior shipped inside the package (mocap/energy/assets/, a tracked file: replace it only by
naming it with --out); a run uses the new one with tracker.prior.prior_file=PATH.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mocap import presets
from mocap_cli.errors import ArgumentParser


def default_out(body_name: str) -> Path:
    """Where a prior trained without --out goes: outputs/ of the current directory (ignored by
    git), not the shipped prior's file."""
    return Path("outputs") / "priors" / f"pose_prior_{body_name}.npz"


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap train-prior", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--body", default="paper22", help="body preset (mocap/presets/body)")
    p.add_argument("--samples", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None,
                   help="the prior file to write (default: outputs/priors/pose_prior_<body>.npz)")
    args = p.parse_args(argv)
    from mocap.body import load_body_model
    from mocap.energy.train_prior import train_prior

    cfg = presets.read("body", args.body)
    body = load_body_model(cfg["dofs"], cfg.get("model_file"), name=cfg["name"])
    prior = train_prior(body, args.samples, args.seed)
    out = prior.save(args.out or default_out(body.name))
    print(f"wrote {out}: {len(prior.samples)} poses x {len(prior.dof_names)} DOFs, "
          f"sigma = {prior.sigma:.3f} rad; use it with tracker.prior.prior_file={out}")
    return 0

"""The body's joint limits against the motion library's TRAINING poses (issue 34 item 4): clips of the
training motion types (mocap/clips/split.yaml ``train``; never the held-out ones) retargeted onto our
body (:func:`mocap.clips.retarget.retarget`) with the chosen DOFs' limits opened wide, and per DOF the
share of poses past the shipped limit, the data's extremes, and the limits widened to contain them
(:func:`mocap.body.limits_from_data.widened_limits`), written as JSON {dof: [lo_deg, hi_deg]}.

    python -m experiments.joint_limits --every 3 --step 6 --out multirun/limits.json
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

#: the DOFs opened (lower limit, degrees) while retargeting: those the shipped library's poses pile on
WIDE = {"l_elbow_flex": -80.0, "r_elbow_flex": -80.0, "l_knee_flex": -40.0, "r_knee_flex": -40.0,
        "l_shoulder_abd": -90.0, "r_shoulder_abd": -90.0}


def opened_body(name: str = "paper22"):
    """The shipped body and a copy with :data:`WIDE`'s lower limits."""
    from mocap import presets
    from mocap.body import load_body
    from mocap.body.model import load_body_model

    cfg = presets.read("body", name)
    cfg.pop("_target_", None)
    for d in cfg["dofs"]:
        if d["name"] in WIDE:
            d["limits_deg"] = [WIDE[d["name"]], d["limits_deg"][1]]
    return load_body(name), load_body_model(**cfg)


def main(argv=None) -> None:
    from mocap.body.limits_from_data import widened_limits
    from mocap.clips.bvh import read_bvh
    from mocap.clips.retarget import retarget
    from mocap.clips.split import read_split

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=Path("/work/shared/data/real-motion"))
    p.add_argument("--every", type=int, default=3, help="every N-th training clip of the index")
    p.add_argument("--step", type=int, default=6, help="every N-th frame of a clip (at 30 fps)")
    p.add_argument("--margin", type=float, default=2.0, help="degrees past the data")
    p.add_argument("--out", type=Path)
    a = p.parse_args(argv)
    train = set(read_split().train)
    rows = [r for r in csv.DictReader((a.data / "index.csv").open()) if r["motion"] in train][::a.every]
    shipped, body = opened_body()
    chis = []
    for r in rows:
        chis.append(retarget(read_bvh(a.data / r["file"]), body, step=a.step, fps=30.0).chi)
    chi = np.concatenate(chis)
    opened = np.isin(np.asarray(body.dof_names), list(WIDE))      # the others are held by the shipped limits
    wide = widened_limits(shipped.limits, np.where(opened, chi, np.nan), margin=np.deg2rad(a.margin))
    print(f"{len(rows)} training clips, {len(chi)} poses")
    out = {}
    for j, n in enumerate(body.dof_names[6:], 6):
        deg = np.rad2deg(chi[:, j])
        lo, hi = np.rad2deg(shipped.limits[j])
        past = np.mean((deg < lo - 1e-6) | (deg > hi + 1e-6))
        new = np.rad2deg(wide[j])
        out[n] = [round(float(new[0]), 1), round(float(new[1]), 1)]
        print(f"{n:16s} shipped [{lo:6.1f}, {hi:6.1f}]  data [{deg.min():6.1f}, {deg.max():6.1f}]  "
              f"past the shipped {100 * past:4.1f} %  widened [{new[0]:6.1f}, {new[1]:6.1f}]")
    if a.out:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()

"""``mocap show-body``: show the body model: the mean body, +-3 sigma along the first three
shape components, and a few poses of the paper's 22 DOFs. Writes a Rerun recording and a PNG contact sheet.

    mocap show-body [--out outputs/body] [--png docs/body_model.png]
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from mocap_cli.errors import ArgumentParser

if TYPE_CHECKING:
    import numpy as np

    from mocap.body import BodyModel


def gallery(model: BodyModel) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(shapes (F, K), poses (F, D), labels): mean, +-3 sigma on components 1-3, 4 poses."""
    import numpy as np

    shapes, poses, labels = [], [], []
    K = model.num_shape
    shapes.append(np.zeros(K))
    labels.append("mean body")
    for k in range(3):
        for s in (-3, 3):
            a = np.zeros(K)
            a[k] = s
            shapes.append(a)
            labels.append(f"component {k + 1}: {s:+d} sigma")
    poses = [model.zero_pose() for _ in shapes]
    deg = np.deg2rad
    for label, dofs in [
        ("walking stride", {"l_hip_flex": deg(30), "r_hip_flex": deg(-20), "r_knee_flex": deg(40),
                            "l_shoulder_flex": deg(-25), "r_shoulder_flex": deg(25),
                            "l_elbow_flex": deg(20), "r_elbow_flex": deg(30)}),
        ("arms raised", {"l_shoulder_abd": deg(100), "r_shoulder_abd": deg(100)}),
        ("boxing guard", {"l_shoulder_flex": deg(70), "r_shoulder_flex": deg(40),
                          "l_elbow_flex": deg(110), "r_elbow_flex": deg(120),
                          "l_hip_flex": deg(15), "l_knee_flex": deg(20), "r_knee_flex": deg(20)}),
        ("sitting, turned 90 deg", {"root_w3": deg(90), "l_hip_flex": deg(90), "r_hip_flex": deg(90),
                                    "l_knee_flex": deg(90), "r_knee_flex": deg(90)}),
    ]:
        chi = model.zero_pose()
        for name, value in dofs.items():
            chi[model.dof_index(name)] = value
        shapes.append(np.zeros(K))
        poses.append(chi)
        labels.append(label)
    return np.stack(shapes), np.stack(poses), labels


def contact_sheet(model: BodyModel, shapes, poses, labels, path: Path) -> Path:
    """Shaded front views of every gallery body (matplotlib, no GPU)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    n = len(labels)
    cols = 6
    rows = int(np.ceil(n / cols))
    fig = plt.figure(figsize=(2.4 * cols, 4.0 * rows), dpi=80)
    light = np.array([0.3, -0.8, 0.5])
    light /= np.linalg.norm(light)
    for i, (a, chi, label) in enumerate(zip(shapes, poses, labels, strict=True)):
        V = model.shaped(a).pose(chi).vertices[0].astype(np.float64)
        tri = V[model.faces]
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True) + 1e-12
        shade = 0.35 + 0.65 * np.clip(nrm @ light, 0, 1)
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(tri, facecolors=np.c_[shade * 0.85, shade * 0.7,
                                                                   shade * 0.6, np.ones(len(shade))],
                                             linewidths=0))
        c = V.mean(0)
        ax.set_xlim(c[0] - 0.55, c[0] + 0.55)
        ax.set_ylim(c[1] - 0.55, c[1] + 0.55)
        ax.set_zlim(0, 2.0)
        ax.view_init(elev=5, azim=-60)
        ax.set_box_aspect((1.1, 1.1, 2.0), zoom=1.25)
        ax.set_axis_off()
        stature = V[:, 2].max() - V[:, 2].min()
        ax.set_title(f"{label}\n(stature {stature:.2f} m)" if i < 7 else label, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap show-body", description=__doc__)
    p.add_argument("--out", type=Path, default=Path("outputs") / "body",
                   help="output folder (relative: the working directory)")
    p.add_argument("--png", type=Path, default=None, help="also write the contact sheet here")
    p.add_argument("--body", default="paper22", help="body preset (mocap/presets/body)")
    args = p.parse_args(argv)
    from mocap import presets
    from mocap.body import load_body_model
    from mocap.recording.body_gallery import write_body_gallery

    cfg = presets.read("body", args.body)
    model = load_body_model(cfg["dofs"], cfg.get("model_file"))
    shapes, poses, labels = gallery(model)
    rrd = write_body_gallery(model, shapes, poses, labels, args.out / "body.rrd")
    png = contact_sheet(model, shapes, poses, labels, args.png or args.out / "body_model.png")
    print(f"wrote {rrd} ({rrd.stat().st_size / 1e6:.1f} MB) and {png}")
    return 0


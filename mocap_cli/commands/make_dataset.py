"""``mocap make-dataset``: generate a synthetic multi-view sequence with exact ground truth and
write it as a folder.

    mocap make-dataset motion=walk cameras=mpi08 frames=100
    mocap make-dataset motion=box cameras=humaneva images=true detections.enabled=true

The folder layout is documented in mocap/data/sequence_io.py. The sequence is written to a
temporary folder and moved into place only when complete.
"""

from __future__ import annotations

import time

from omegaconf import DictConfig, OmegaConf

from mocap_cli.hydra_edge import build, run_command


def task(cfg: DictConfig) -> None:
    # imported here: --help and argument errors import no numeric stack
    from tqdm import tqdm

    from mocap.data.generate import make_synthetic
    from mocap.data.sequence_io import write_sequence
    from mocap.viz.contact_sheet import contact_sheet, save_png

    body = build(cfg.body)
    rig = build(cfg.cameras)
    t0 = time.perf_counter()
    with tqdm(total=cfg.frames, desc=f"rendering {cfg.name}", unit="frame") as bar:
        seq = make_synthetic(
            body, rig, motion=cfg.motion, frames=cfg.frames, fps=cfg.fps, seed=cfg.seed,
            split=cfg.split, shape_scale=cfg.shape_scale, radius=cfg.radius, masks=cfg.masks,
            images=cfg.images, marker_spheres=cfg.marker_spheres,
            detections=OmegaConf.to_container(cfg.detections),
            silhouette_noise=OmegaConf.to_container(cfg.silhouette_noise), name=cfg.name,
            progress=lambda i, n: bar.update(1))
    t1 = time.perf_counter()
    out = write_sequence(seq, cfg.out, overwrite=cfg.overwrite)
    t2 = time.perf_counter()
    sheet = save_png(contact_sheet(seq, cfg.frames // 2, body.parents), out / "contact_sheet.png")
    print(f"wrote {out}: {seq.num_frames} frames x {seq.num_views} views "
          f"(render {t1 - t0:.1f} s, write {t2 - t1:.1f} s); contact sheet {sheet}")


def main(argv: list[str] | None = None) -> int:
    """Run ``mocap make-dataset`` with Hydra overrides ``argv``."""
    return run_command(task, "make_dataset", "mocap make-dataset", argv)

"""``mocap segment``: segment a recording into silhouettes and write a sequence folder with the
masks.

    mocap segment                                  # Pose2Sim demo (conf/segment.yaml)
    mocap segment segmentation.method=knn data.stop=100 data.step=1
    mocap segment background_clip=/path/to/empty_scene_videos segmentation.background=median

The folder (mocap/data/sequence_io.py layout) holds masks, the scaled calibration, the
keypoints and, in sequence.json's meta, the source frames and the segmentation's settings and
speed. Track it with its video images:
    mocap track data=pose2sim_demo_video data.masks=<folder> tracker=hybrid init.mode=tracker
"""

from __future__ import annotations

from dataclasses import replace

from omegaconf import DictConfig, OmegaConf

from mocap_cli.hydra_edge import build, run_command


def task(cfg: DictConfig) -> None:
    # imported here: --help and argument errors import no numeric stack
    from mocap.data.sequence_io import write_sequence
    from mocap.video.segmentation import segment_sequence
    from mocap.video.sequence import load_background_clip

    seq = build(cfg.data, body=None)
    clip = load_background_clip(cfg.background_clip, seq) if cfg.background_clip else None
    result = segment_sequence(seq, background_clip=clip, **OmegaConf.to_container(cfg.segmentation))
    out = replace(seq, images=None, masks=result.masks, meta={**seq.meta, "segmentation": result.info})
    folder = write_sequence(out, cfg.out, overwrite=cfg.overwrite)
    info = result.info
    print(f"{info['method']} ({info['background']}, keypoints={info['keypoints']}, "
          f"multiview={info['multiview']}): {seq.num_frames} frames x {seq.num_views} views at "
          f"{info['resolution'][0]}x{info['resolution'][1]}, "
          f"{1000 * info['seconds_per_frame_per_view']:.0f} ms per frame per view -> {folder}")


def main(argv: list[str] | None = None) -> int:
    """Run ``mocap segment`` with Hydra overrides ``argv``."""
    return run_command(task, "segment", "mocap segment", argv)

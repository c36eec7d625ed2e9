"""The synthetic crowd's first frames as a sequence folder whose gt.npz has a person axis (the
people in reverse order, named ``actor<p>`` after their index in the crowd): data another
recording would bring, scored per person from the file, not from the crowd's own truth."""

from pathlib import Path

import numpy as np


def crowd_gt_folder(body, folder: Path, frames: int = 6) -> Path:
    from mocap.data.crowd import crowd_sequence
    from mocap.data.sequence import Detections, GroundTruth, Sequence
    from mocap.data.sequence_io import write_sequence

    seq = crowd_sequence(body=body, frames=20)
    truth = seq.meta["people_truth"]
    d = seq.detections
    keep = d.frame < frames
    det = Detections(d.labels, d.frame[keep], d.view[keep], d.label[keep], d.xy[keep], d.confidence[keep],
                     d.person[keep])
    joints = truth.joints[:frames, ::-1]                                   # (F, P, J, 3), reversed
    P = joints.shape[1]
    gt = GroundTruth(alpha=None, chi=None, joints=np.nan_to_num(joints), markers=None, dof_names=(),
                     joint_names=truth.joint_names, marker_names=(),
                     person_names=tuple(f"actor{P - 1 - p}" for p in range(P)),
                     joint_valid=np.isfinite(joints).all(axis=-1))
    return write_sequence(Sequence(name="crowd_gt", rig=seq.rig, fps=seq.fps, detections=det, gt=gt,
                                   frames=frames), folder)

"""A Rerun recording of the body model: shape variations and poses on a ``frame`` timeline."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from mocap.body.model import BodyModel
from mocap.safe_files import temporary_beside


def _colors(model: BodyModel) -> np.ndarray:
    """Per-vertex colours by dominant joint (a fixed palette), uint8 (V, 3)."""
    rng = np.random.default_rng(7)
    palette = rng.integers(60, 230, size=(model.num_joints, 3)).astype(np.uint8)
    return palette[model.part_labels]


def write_body_gallery(model: BodyModel, shapes: np.ndarray, poses: np.ndarray,
                       labels: list[str], path: str | Path) -> Path:
    """Log one posed body per frame. shapes: (F, K); poses: (F, D); labels: F captions."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with temporary_beside(path, suffix=".rrd.part") as tmp:   # never a predictable name
        rec = rr.RecordingStream("mocap_body_model")
        rec.save(tmp)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        # positions only on the timeline: static positions would shadow them (Rerun)
        rec.log("world/body", rr.Mesh3D.from_fields(triangle_indices=model.faces,
                                                    vertex_colors=_colors(model)), static=True)
        parents = model.parents
        for f, (alpha, chi, label) in enumerate(zip(shapes, poses, labels, strict=True)):
            out = model.shaped(alpha).pose(chi)
            rec.set_time("frame", sequence=f)
            rec.log("world/body", rr.Mesh3D.from_fields(vertex_positions=out.vertices[0]))
            J = out.joints[0]
            strips = [np.stack([J[parents[j]], J[j]]) for j in range(1, len(parents))]
            rec.log("world/skeleton", rr.LineStrips3D(strips, colors=[255, 255, 255]))
            rec.log("world/joints", rr.Points3D(J, radii=0.015, labels=list(model.joint_names)))
            rec.log("caption", rr.TextLog(label))
        rec.flush()
        rec.disconnect()
        tmp.replace(path)
    return path

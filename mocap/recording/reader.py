"""Reading a ``.rrd`` back: a headless summary and the scalar series it holds."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import rerun as rr


def read_recording(path: str | Path) -> dict:
    """Entities, the frame range, scalar series per entity ({frame: value}) and the run's
    text documents (config, metadata, metrics) of a recording."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"recording not found: {path}")
    entities: set[str] = set()
    frames: set[int] = set()
    scalars: dict[str, dict[int, float]] = defaultdict(dict)
    texts: dict[str, str] = {}
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        entity = chunk.entity_path
        if entity.startswith("/__"):
            continue
        entities.add(entity)
        rb = chunk.to_record_batch()
        names = rb.schema.names
        if "frame" in names:
            fr = [v for v in rb.column("frame").to_pylist() if v is not None]
            frames.update(fr)
            if "Scalars:scalars" in names:
                for f, v in zip(rb.column("frame").to_pylist(), rb.column("Scalars:scalars").to_pylist(),
                                strict=True):
                    if f is not None and v:
                        scalars[entity][int(f)] = float(v[0])
        if "TextDocument:text" in names:
            texts[entity] = rb.column("TextDocument:text").to_pylist()[-1][0]
    metrics = None
    if "/run/metrics" in texts:
        metrics = json.loads(texts["/run/metrics"])
    return {"path": str(path), "entities": sorted(entities),
            "frames": (min(frames), max(frames)) if frames else None,
            "num_frames": len(frames), "scalars": dict(scalars), "texts": texts, "metrics": metrics}


def summary_text(info: dict) -> str:
    lines = [f"recording {info['path']}"]
    if info["frames"]:
        lines.append(f"  frames {info['frames'][0]}..{info['frames'][1]} ({info['num_frames']} logged)")
    lines.append(f"  {len(info['entities'])} entities:")
    lines += [f"    {e}" + (f"  ({len(info['scalars'][e])} samples)" if e in info["scalars"] else "")
              for e in info["entities"]]
    m = info["metrics"]
    if m:
        keys = ("tracker", "seed", "frames", "mpjpe_mm", "mpjpe_std_mm", "sec_per_frame",
                "energy_evals_per_frame", "mmta", "mmtp_mm")
        lines.append("  final metrics:")
        lines += [f"    {k}: {m[k]}" for k in keys if k in m]
    else:
        lines.append("  no final metrics (the run did not finish)")
    return "\n".join(lines)


def latest_at(path: str | Path, entity: str, component: str, frame: int,
              timeline: str = "frame") -> np.ndarray | None:
    """What a viewer shows for ``entity``'s ``component`` (e.g. ``"Mesh3D:vertex_positions"``)
    at ``frame``, following Rerun's latest-at rule: static data of the component, when there is
    any, shadows everything on the timeline; otherwise the last value logged at or before
    ``frame``. Returns the value as an array (None when nothing applies)."""
    entity = entity if entity.startswith("/") else "/" + entity
    static, best, best_frame = None, None, None
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        if chunk.entity_path != entity:
            continue
        rb = chunk.to_record_batch()
        if component not in rb.schema.names:
            continue
        values = rb.column(component).to_pylist()
        if chunk.is_static:
            static = next((v for v in reversed(values) if v is not None), static)
            continue
        if timeline not in rb.schema.names:
            continue
        for f, v in zip(rb.column(timeline).to_pylist(), values, strict=True):
            if v is not None and f is not None and f <= frame and (best_frame is None or f >= best_frame):
                best, best_frame = v, f
    value = static if static is not None else best
    return None if value is None else np.asarray(value, dtype=np.float64)

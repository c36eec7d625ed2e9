"""Reading a ``.rrd`` back: a headless summary and the scalar series it holds."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

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

"""Exporting a run: its ``motion.npz`` written as BVH, TRC, glTF/GLB or C3D
(:mod:`mocap.export` holds the writers)."""

from __future__ import annotations

import os
from pathlib import Path

from mocap.export import FORMATS
from mocap.run_folder.manifest import require_complete


def export_run(run_dir: str | Path, fmt: str, out: str | Path | None = None,
               overwrite: bool = False, body=None, markers: str = "landmarks",
               require_manifest: bool = True, person: int | None = None,
               influences: int = 4) -> Path:
    """Export a run directory's motion.npz to ``fmt`` (bvh, trc, gltf, c3d); default output
    ``<run dir>/motion.<ext>``. glTF needs the body model: ``body`` or the run's own config
    (its ``metrics.json``). ``markers`` (TRC, C3D): landmarks (the body's default set),
    joints, or tracker (a marker tracker's own landmarks). Written to a temporary file and
    renamed; an existing output is kept unless ``overwrite``. The run folder must be a
    complete run (a valid manifest.json, :mod:`mocap.run_folder.manifest`) unless
    ``require_manifest`` is False; the output path is checked (its folder exists, its suffix
    is the format's) before any work. ``person``: the track id to export of a several-people
    run (its motion.npz has a person axis; :func:`mocap.export.people_motion.person_motion`).
    ``influences`` (glTF): joints per vertex, 4 (default, what every reader applies) or 8
    (mocap's skinning exactly; :mod:`mocap.export.gltf`)."""
    if influences not in (4, 8):
        raise ValueError(f"setting influences = {influences!r} is out of range (4 or 8)")
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r} (known: {', '.join(FORMATS)})")
    run_dir = Path(run_dir)
    if not (run_dir / "motion.npz").is_file() and not (run_dir / "previous_run").is_dir():
        raise FileNotFoundError(f"{run_dir}: no motion.npz (is it a finished run directory?)")
    if require_manifest:        # (an interrupted re-run: says where the last complete run is)
        require_complete(run_dir)
    if not (run_dir / "motion.npz").is_file():
        raise FileNotFoundError(f"{run_dir}: no motion.npz (is it a finished run directory?)")
    out = Path(out) if out is not None else run_dir / f"motion{FORMATS[fmt]}"
    if not out.parent.is_dir():
        raise FileNotFoundError(f"output {out}: folder {out.parent} does not exist")
    if out.suffix.lower() != FORMATS[fmt]:
        raise ValueError(f"output {out}: a {fmt} export is written to a {FORMATS[fmt]} file, "
                         f"not {out.suffix or 'a name without suffix'}")
    if out.is_dir():
        raise ValueError(f"output {out} is a folder, not a {FORMATS[fmt]} file")
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out} exists (pass --overwrite / overwrite=True to replace it)")
    from mocap.export.motion import load_motion  # (numpy: after the checks)

    if fmt == "gltf" and body is None:      # the stored config is checked before anything is read
        from mocap.run_folder.read import run_config
        run_config(run_dir)
    if person is None:
        motion = load_motion(run_dir / "motion.npz")
    else:
        from mocap.export.people_motion import person_motion

        motion = person_motion(run_dir / "motion.npz", person)
    if fmt == "gltf" and body is None:      # the run's body, from its config: refused before any write
        body = motion_body(run_dir, motion)
    from mocap.safe_files import temporary_beside

    with temporary_beside(out, suffix=f".tmp{out.suffix}") as tmp:
        if fmt == "bvh":
            from mocap.export.bvh import write_bvh
            write_bvh(motion, tmp)
        elif fmt == "trc":
            from mocap.export.trc import write_trc
            write_trc(motion, tmp, which=markers, file_name=out.name)
        elif fmt == "c3d":
            from mocap.export.c3d import write_c3d
            write_c3d(motion, tmp, which=markers)
        else:
            from mocap.export.gltf import write_gltf
            write_gltf(motion, tmp, body, influences)
        os.replace(tmp, out)
    return out


def motion_body(run_dir: Path, motion=None):
    """The body model a run used, from the configuration its ``metrics.json`` stores
    (:func:`mocap.run_folder.read.run_body`); checked against the motion's model hash."""
    from mocap.export.motion import model_hash
    from mocap.run_folder.read import run_body as body_of
    from mocap.run_folder.read import run_config

    try:
        config = run_config(run_dir)
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{exc}; the glTF export needs the run's body model") from None
    body = body_of(config)
    want = (motion.info.get("model_hash") if motion is not None else None)
    if want and model_hash(body) != want:
        raise ValueError(f"{run_dir}: the body model in its config (hash {model_hash(body)}) is not the "
                         f"one the run used ({want})")
    return body

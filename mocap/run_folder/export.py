"""Exporting a run: its ``motion.npz`` written as BVH, TRC, glTF/GLB or C3D
(:mod:`mocap.export` holds the writers).

- One person (``mocap-motion-v1``): one file per format.
- Several people (``mocap-people-v1``, :mod:`mocap.export.people_motion`): one BVH per person
  (``<out stem>_p<id>.bvh``), one TRC / C3D with every person's markers named ``p<id>_<marker>``
  (blank / NaN where the person is not in the scene), one GLB with a skinned body per person
  (joint nodes ``p<id>_<joint>``, the root scaled to 0 where the person is not in the scene);
  ``person=ID`` exports one person as a one-person run.
- An imported clip (``mocap import-motion``: tracker ``retarget``, no metrics.json) is not a
  run and has no manifest: it is exported as it is (its folder, or the .npz itself); its glTF
  body is the body preset it names, checked against the model hash it records.

:func:`export_files` is the entry point (every file written); :func:`export_run` the
one-file form (refuses a several-people BVH, which is one file per person).
"""

from __future__ import annotations

import os
from pathlib import Path

from mocap.export import FORMATS
from mocap.run_folder.manifest import require_complete

PEOPLE_FORMAT = "mocap-people-v1"
IMPORTED_TRACKER = "retarget"


def motion_file_facts(path: Path) -> dict:
    """{"format", "tracker", "imported"} of a motion.npz, read without loading its arrays (a
    file that cannot be read: empty, the loaders say why)."""
    import zipfile

    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as z:
            facts = {k: str(z[k]) for k in ("format", "tracker") if k in z.files}
            facts["imported"] = (facts.get("tracker") == IMPORTED_TRACKER and "retarget_targets" in z.files)
            return facts
    except (OSError, ValueError, zipfile.BadZipFile):
        return {}


def export_run(run_dir: str | Path, fmt: str, out: str | Path | None = None,
               overwrite: bool = False, body=None, markers: str = "landmarks",
               require_manifest: bool = True, person: int | None = None,
               influences: int = 4) -> Path:
    """:func:`export_files` of a format written to one file (every case but the BVH of a
    several-people run without ``person``, refused here: use :func:`export_files`); returns it."""
    files = export_files(run_dir, fmt, out, overwrite, body, markers, require_manifest, person, influences,
                         one_file=True)
    return files[0]


def export_files(run_dir: str | Path, fmt: str, out: str | Path | None = None,
                 overwrite: bool = False, body=None, markers: str = "landmarks",
                 require_manifest: bool = True, person: int | None = None,
                 influences: int = 4, one_file: bool = False) -> list[Path]:
    """Export a run directory's motion.npz to ``fmt`` (bvh, trc, gltf, c3d); returns the files
    written. Default output ``<run dir>/motion.<ext>`` (several people's BVH:
    ``<run dir>/motion_p<id>.bvh``, one per person; with ``out``: ``<out stem>_p<id>.bvh``).
    ``run_dir`` may also be an imported clip's motion .npz (module docstring). glTF needs the
    body model: ``body`` or the run's own config (its ``metrics.json``). ``markers`` (TRC,
    C3D): landmarks (the body's default set), joints, or tracker (a marker tracker's own
    landmarks). Each file is written to a temporary file and renamed; an existing output is
    kept unless ``overwrite``. The run folder must be a complete run (a valid manifest.json,
    :mod:`mocap.run_folder.manifest`) unless ``require_manifest`` is False or it holds an
    imported clip; every output path is checked (its folder exists, its suffix is the
    format's, its name is a plain file name inside that folder) before any work. ``person``:
    the track id to export alone of a several-people run. ``influences`` (glTF): joints per
    vertex, 4 (default, what every reader applies) or 8 (mocap's skinning exactly;
    :mod:`mocap.export.gltf`). ``one_file``: refuse what would write several files."""
    if influences not in (4, 8):
        raise ValueError(f"setting influences = {influences!r} is out of range (4 or 8)")
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r} (known: {', '.join(FORMATS)})")
    ext = FORMATS[fmt]
    run_dir = Path(run_dir)
    if run_dir.is_file():               # a motion .npz of its own: an imported clip only
        motion_path, run_dir = run_dir, run_dir.parent
        facts = motion_file_facts(motion_path)
        if not facts.get("imported"):
            raise ValueError(f"{motion_path}: a motion file is exported by its run folder ({run_dir}); only "
                             "an imported clip's .npz (mocap import-motion) is exported by itself")
        default = motion_path.with_suffix(ext)
    else:
        motion_path = run_dir / "motion.npz"
        if not motion_path.is_file() and not (run_dir / "previous_run").is_dir():
            raise FileNotFoundError(f"{run_dir}: no motion.npz (is it a finished run directory?)")
        facts = motion_file_facts(motion_path) if motion_path.is_file() else {}
        if facts.get("imported") and (run_dir / "metrics.json").exists():
            facts["imported"] = False       # a run folder: its manifest says whether it is complete
        if require_manifest and not facts.get("imported"):  # (an interrupted re-run: says where the last is)
            require_complete(run_dir)
        if not motion_path.is_file():
            raise FileNotFoundError(f"{run_dir}: no motion.npz (is it a finished run directory?)")
        default = run_dir / f"motion{ext}"
    people = facts.get("format") == PEOPLE_FORMAT
    if person is not None and not people:
        raise ValueError(f"{motion_path}: holds one person; person={person} is for a several-people run")
    out = Path(out) if out is not None else default
    _check_output(out, fmt)
    from mocap.export.motion import load_motion  # (numpy: after the checks)
    from mocap.export.people_motion import load_people_motion, person_motion

    if fmt == "gltf" and body is None and not facts.get("imported"):   # the stored config, before reading
        from mocap.run_folder.read import run_config
        run_config(run_dir)
    arrays = load_people_motion(motion_path) if people else None
    outs = [out]
    if people and person is None and fmt == "bvh":       # one file per person
        if one_file:
            raise ValueError(f"{motion_path}: holds several people: a BVH per person (export_files writes "
                             "them all, or give person=ID)")
        outs = _person_outputs(out, arrays)
        for o in outs:
            _check_output(o, fmt)
    for o in outs:
        if o.exists() and not overwrite:
            raise FileExistsError(f"{o} exists (pass --overwrite / overwrite=True to replace it)")
    motion = None
    if not people:
        motion = load_motion(motion_path)
    elif person is not None:
        motion = person_motion(motion_path, person, arrays)
    if fmt == "gltf" and body is None:      # the run's body, from its config: refused before any write
        want = motion.info.get("model_hash") if motion is not None else str(arrays.get("model_hash", ""))
        body = (imported_body(motion_path, motion) if facts.get("imported")
                else motion_body(run_dir, want_hash=want))
    if motion is not None:
        _write(fmt, motion, out, markers, body, influences)
        return [out]
    return _write_people(fmt, motion_path, arrays, outs, markers, body, influences)


def _check_output(out: Path, fmt: str) -> None:
    ext = FORMATS[fmt]
    if not out.parent.is_dir():
        raise FileNotFoundError(f"output {out}: folder {out.parent} does not exist")
    if out.suffix.lower() != ext:
        raise ValueError(f"output {out}: a {fmt} export is written to a {ext} file, "
                         f"not {out.suffix or 'a name without suffix'}")
    if out.is_dir():
        raise ValueError(f"output {out} is a folder, not a {ext} file")


def _person_outputs(out: Path, arrays) -> list[Path]:
    """``<out stem>_p<id><suffix>`` per live person, each a plain file name inside out's folder."""
    from mocap.export.people_motion import live_people, person_label
    from mocap.safe_files import check_name, inside

    ids = live_people(arrays)
    if not ids:
        raise ValueError(f"{out}: the run tracked nobody (no person has an estimate): nothing to export")
    files = []
    for pid in ids:
        name = check_name(f"{out.stem}_{person_label(pid)}{out.suffix}", "person file", out.parent)
        files.append(inside(out.parent / name, out.parent))
    return files


def _write(fmt: str, motion, out: Path, markers: str, body, influences: int) -> None:
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


def _write_people(fmt: str, path: Path, arrays, outs: list[Path], markers: str, body,
                  influences: int) -> list[Path]:
    """Every person of a several-people motion (module docstring)."""
    from mocap.export.people_motion import (
        live_people,
        people_points,
        person_label,
        person_motion,
        person_timeline,
    )
    from mocap.safe_files import temporary_beside

    if fmt == "bvh":
        for pid, out in zip(live_people(arrays), outs, strict=True):
            _write(fmt, person_motion(path, pid, arrays), out, markers, body, influences)
        return outs
    out, = outs
    ids = live_people(arrays)
    if not ids:
        raise ValueError(f"{path}: the run tracked nobody (no person has an estimate): nothing to export")
    with temporary_beside(out, suffix=f".tmp{out.suffix}") as tmp:
        if fmt in ("trc", "c3d"):
            names, pts = people_points(arrays, markers)
            if fmt == "trc":
                from mocap.export.trc import write_points_trc
                write_points_trc(names, pts, float(arrays["fps"]), arrays["timestamps"], tmp,
                                 file_name=out.name)
            else:
                from mocap.export.c3d import write_points_c3d
                write_points_c3d(names, pts, float(arrays["fps"]), tmp)
        else:
            from mocap.export.gltf import write_people_gltf
            people = [(f"{person_label(pid)}_", *person_timeline(path, pid, arrays)) for pid in ids]
            write_people_gltf(people, tmp, body, influences)
        os.replace(tmp, out)
    return outs


def motion_body(run_dir: Path, motion=None, want_hash: str | None = None):
    """The body model a run used, from the configuration its ``metrics.json`` stores
    (:func:`mocap.run_folder.read.run_body`); checked against the motion's model hash
    (``motion.info``'s, or ``want_hash``)."""
    from mocap.export.motion import model_hash
    from mocap.run_folder.read import run_body as body_of
    from mocap.run_folder.read import run_config

    try:
        config = run_config(run_dir)
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{exc}; the glTF export needs the run's body model") from None
    body = body_of(config)
    want = want_hash or (motion.info.get("model_hash") if motion is not None else None)
    if want and model_hash(body) != want:
        raise ValueError(f"{run_dir}: the body model in its config (hash {model_hash(body)}) is not the "
                         f"one the run used ({want})")
    return body


def imported_body(path: Path, motion):
    """The body of an imported clip: the body preset its motion names, checked against the
    model hash it records."""
    from mocap.body import load_body
    from mocap.export.motion import model_hash

    name = motion.info.get("body", "")
    if not name:
        raise ValueError(f"{path}: names no body model; the glTF export needs one")
    body = load_body(name)
    if motion.info.get("model_hash") and model_hash(body) != motion.info["model_hash"]:
        raise ValueError(f"{path}: body {name!r} today (hash {model_hash(body)}) is not the one the clip was "
                         f"retargeted onto ({motion.info['model_hash']}): import it again")
    return body

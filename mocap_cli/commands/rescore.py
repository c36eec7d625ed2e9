"""``mocap rescore``: re-score finished runs with today's evaluation, without tracking them again.

When the scoring changes (a ground-truth skeleton's mapping to our points, the oracle), the
runs under ``multirun/`` keep the figures they were written with. This reads each run's
motion.npz (the poses and shape it produced) and the data of its stored configuration, and
rewrites the accuracy part of its metrics.json (:func:`mocap.eval.run_metrics.accuracy_metrics`:
with a true surface in the data, the surface metrics and the surface oracle too);
speed, effort and initialisation figures are kept. The figures it replaces are kept under
``rescored.previous``. The recording keeps the metrics it was written with. A several-people
run (``tracker=marker_people``) is scored per person with the best assignment of its tracks to
the true people (:func:`mocap.run_folder.people.people_accuracy_metrics`, as the run itself
was; joints only). An imported clip (``mocap import-motion``) has no data to score against and
is refused.

    mocap rescore multirun/mismatch           # every run below a folder
    mocap rescore outputs/track/<run> --dry-run
    mocap rescore multirun/recovery --oracle-cache outputs/oracle_cache   # each sequence's oracle fitted once
    mocap ablate multirun/mismatch            # the tables from the new figures
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

from mocap.run_folder.lock import RunFolderBusy, run_lock
from mocap.run_folder.manifest import PREVIOUS, read_manifest, require_complete, write_manifest
from mocap_cli import source_checkout
from mocap_cli.errors import ArgumentParser

SUMMARY = ("mpjpe_mm", "frames_lost", "pcp", "pcp_min", "identity_switches")
#: what a several-people run's rescore rewrites (mocap.run_folder.people.people_accuracy_metrics)
PEOPLE_ACCURACY = ("per_person", "identity_switches", "assignment", "mpjpe_mm", "pcp_min",
                   "people_in_ground_truth", "people_tracked", "frames_lost", "track_jumps")


def run_dirs(targets: list[Path]) -> list[Path]:
    out = []
    for t in targets:
        if not t.exists():
            raise FileNotFoundError(f"{t}: no such run directory")
        if t.is_file() or (t / "motion.npz").is_file() and not (t / "metrics.json").exists():
            raise ValueError(f"{t}: a motion without a run (mocap import-motion writes one): no data to "
                             "score it against; rescore takes run folders of mocap track")
        found = [t] if (t / "metrics.json").is_file() else sorted(p.parent for p in t.rglob("metrics.json"))
        out += [d for d in found if (d / "motion.npz").is_file() and d.name != PREVIOUS]
    return list(dict.fromkeys(out))


def rescore(run: Path, version: str, dry_run: bool = False,
            oracle_cache: Path | None = None) -> tuple[dict, dict]:
    """(old, new) accuracy figures of one run; metrics.json (and the manifest's checksum of it)
    rewritten unless ``dry_run``. A folder that is not a complete run is refused. The oracles are
    fitted as the run's stored ``oracle`` settings say, kept in ``oracle_cache`` where given."""
    from mocap.eval.run_metrics import oracle_settings
    from mocap.run_folder import run_body, run_sequence, write_json

    require_complete(run)
    metrics = json.loads((run / "metrics.json").read_text())
    if "config" not in metrics:
        raise ValueError(f"{run}: metrics.json holds no config (not a mocap track run)")
    where = str(run / "metrics.json")
    body = run_body(metrics["config"], where=where)
    seq = run_sequence(metrics["config"], body, where=where)
    from mocap.run_folder.export import PEOPLE_FORMAT, motion_file_facts

    if motion_file_facts(run / "motion.npz").get("format") == PEOPLE_FORMAT:
        new, F = _rescore_people(run, body, seq)
    else:
        oracle = oracle_settings(metrics["config"].get("oracle"))
        if oracle_cache is not None:
            oracle = replace(oracle, cache=str(oracle_cache))
        new, F = _rescore_person(run, body, seq, oracle)
    old = {k: metrics[k] for k in new if k in metrics}
    if not dry_run:
        previous = {k: old[k] for k in SUMMARY if k in old}
        for block in ("mismatch", "oracle"):
            if block in old:
                previous[block] = {k: v for k, v in old[block].items() if k != "offsets_mm"}
        metrics.update(new)
        metrics["rescored"] = {"by": version, "frames": F, "previous": previous}
        manifest = read_manifest(run) or {}
        write_json(run / "metrics.json", metrics)
        write_manifest(run, list(manifest["files"]), manifest.get("overrides"))
    return old, new


def _rescore_people(run: Path, body, seq) -> tuple[dict, int]:
    """The per-person accuracy of a several-people run, and its frames."""
    from mocap.data.people_truth import people_truth
    from mocap.export.people_motion import load_people_motion
    from mocap.run_folder.people import people_accuracy_metrics

    if seq.gt is None and people_truth(seq) is None:
        raise ValueError(f"{run}: its data {seq.name!r} has no ground truth to score against")
    arrays = load_people_motion(run)
    if arrays["chi"].shape[2] != body.num_dofs:
        raise ValueError(f"{run}: motion has {arrays['chi'].shape[2]} DOFs, body {body.name!r} "
                         f"{body.num_dofs}")
    scores = people_accuracy_metrics(body, seq, arrays)
    return {k: scores[k] for k in PEOPLE_ACCURACY if k in scores}, int(arrays["live"].shape[0])


def _rescore_person(run: Path, body, seq, oracle) -> tuple[dict, int]:
    """The accuracy of a one-person run (the oracles fitted as ``oracle`` says), and its frames."""
    from mocap.eval.run_metrics import accuracy_metrics
    from mocap.export.motion import load_motion

    if seq.gt is None:
        raise ValueError(f"{run}: its data {seq.name!r} has no ground truth to score against")
    motion = load_motion(run)
    F = motion.num_frames
    if motion.chi.shape[1] != body.num_dofs:
        raise ValueError(f"{run}: motion has {motion.chi.shape[1]} DOFs, body {body.name!r} {body.num_dofs}")
    return accuracy_metrics(body, seq, motion.chi, motion.alpha, oracle, motion.joint_offsets), F


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="mocap rescore", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("targets", nargs="+", type=Path, help="run directories or folders holding them")
    p.add_argument("--dry-run", action="store_true", help="print the new figures, write nothing")
    p.add_argument("--oracle-cache", type=Path, default=None,
                   help="keep the oracle fits in this folder (by the ground truth's content): runs of one "
                        "sequence fit it once (default: the runs' own oracle.cache setting)")
    args = p.parse_args(argv)
    runs = run_dirs(args.targets)
    if not runs:
        raise FileNotFoundError("no run directory with metrics.json and motion.npz found")
    source = source_checkout()
    version = "unknown" if source is None else subprocess.run(
        ["git", "-C", str(source), "describe", "--always", "--dirty"],
        capture_output=True, text=True).stdout.strip() or "unknown"
    failed = 0
    for i, run in enumerate(runs, 1):
        try:
            with contextlib.nullcontext() if args.dry_run else run_lock(run):     # one writer per folder
                old, new = rescore(run, version, args.dry_run, args.oracle_cache)
        except (ValueError, FileNotFoundError, RunFolderBusy) as exc:
            print(f"[{i}/{len(runs)}] {run}: skipped: {exc}", file=sys.stderr)
            failed += 1
            continue
        line = (f"[{i}/{len(runs)}] {run}: MPJPE {old.get('mpjpe_mm', float('nan')):.1f} -> "
                f"{new['mpjpe_mm']:.1f} mm")
        if "identity_switches" in new:
            line += f", identity switches {old.get('identity_switches', '?')} -> {new['identity_switches']}"
        if "oracle" in new:
            line += (f", oracle {old.get('oracle', {}).get('raw_mm', float('nan')):.1f} -> "
                     f"{new['oracle']['raw_mm']:.1f} mm")
        if "surface_to_mesh_mm" in new:
            line += (f", surface {old.get('surface_to_mesh_mm', float('nan')):.1f} -> "
                     f"{new['surface_to_mesh_mm']:.1f} mm (oracle "
                     f"{new.get('surface_oracle_mm', float('nan')):.1f}), IoU "
                     f"{new.get('silhouette_iou', float('nan')):.3f}")
        print(line, flush=True)
    return 1 if failed else 0


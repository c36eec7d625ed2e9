"""Silhouette self-initialisation alone: seconds and frame-0 joint error per sequence (issue 28).

    PYTHONPATH=$PWD OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_init.py \
        [--data mismatch_box,mismatch_walk,mismatch_gesture] [--seed 0] [--threads 1] \
        [--label new] [--out /tmp/init.jsonl] [--profile /tmp/init.prof] [--init '{"rounds": 1}']

For every data config (conf/data) the tracker config (``--tracker``, default
``apf_prior``: every silhouette tracker initialises with the same settings) is built as
``mocap track data=<name> init.mode=tracker seed=<seed>`` builds it, and
:func:`mocap.trackers.init_cache.initial_estimate` runs without a cache (so nothing stored is
reused). Printed and appended to ``--out`` (one JSON line per sequence): seconds, the
frame-0 error (raw MPJPE over the joints matched by name, what a run's ``per_frame_mm[0]``
holds), ``cpu_seconds`` (the process's CPU time over the initialisation: with one thread about
the seconds a quiet machine takes, and much less moved by other jobs than the wall time), the
winner's margin, the load (``os.getloadavg``) before and after, the start (``chi``, ``alpha``:
JSON floats round-trip exactly, so two checkouts' starts compare bit for bit), and the
``mocap`` package the run imported, so that two checkouts can be compared in one session by
running this file with PYTHONPATH pointing at each in turn::

    for d in mismatch_box mismatch_walk; do for root in /work/main $PWD; do \
        PYTHONPATH=$root .venv/bin/python benchmarks/bench_init.py --data $d \
        --label $root --out /tmp/ab.jsonl; done; done

``--rank '[[128, 500], [96, 500]]'``: instead of the starts, the rank agreement of cheaper E_S
(resolution px, mesh triangles) with the pose searches' own (256 px, the 2,000-triangle energy
mesh) on real particles: the batches of a start's pose searches (``rounds`` 1, ``keep`` 1) of the
first sequence, 60 of them drawn, scored by each; printed: CPU ms per particle (8 views), the
median Spearman rank correlation per batch (all, layers 1-7, layers 8-10), the overlap of the 15
lowest, and the search energy's rank of the cheap energy's best particle (issue 38, version 6).
A variant ``["points", triangles, samples]``: the point chamfer (:mod:`mocap.energy.point_chamfer`,
the mesh's vertices, that many contour samples per view) against the search's own masks (version 7).

``--profile FILE``: cProfile of the (first) initialisation in CPU seconds, its top lines printed. ``--init
JSON``: initialiser settings (:class:`~mocap.trackers.tracker_settings.InitSettings` fields)
changed for the run, e.g. ``'{"rounds": 1, "arm_abductions": [-0.6, 0.8]}'`` (the checkout
must know the fields: leave it out for an older one).
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import json
import os
import pstats
import subprocess
import time

import numpy as np

import mocap
from mocap.eval.run_metrics import accuracy_metrics
from mocap.threads import thread_budget
from mocap.trackers.init_cache import initial_estimate
from mocap.trackers.run import frame_of
from mocap_cli.hydra_edge import build, compose

MISMATCH = "mismatch_box,mismatch_walk,mismatch_gesture"
DEV = ("real_walk_heavy_man,real_bow_tall_man,real_bye_petite_woman,real_call_athletic_woman,"
       "real_slash_heavy_man,real_dance-short_petite_woman")
TEST = ("real_byebye_petite_woman,real_guide_athletic_woman,real_kick_athletic_woman,"
        "real_punch_tall_man,real_walk-left_heavy_man,real_walk-right_tall_man")


def _commit(path: str) -> str:
    try:
        return subprocess.run(["git", "-C", path, "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def run_one(data: str, seed: int, tracker: str, threads: int, profile: str | None,
            init: dict | None = None) -> dict:
    cfg = compose("track", [f"data={data}", f"tracker={tracker}", f"seed={seed}", "init.mode=tracker"])
    body = build(cfg.body)
    seq = build(cfg.data, body=body)
    trk = build(cfg.tracker, body=body, rig=seq.rig, rng=np.random.default_rng([seed, 1]),
                keep_particles=False)
    if init:                    # --init: initialiser settings changed for this run
        trk.init_settings = dataclasses.replace(trk.init_settings, **init)
    frame = frame_of(seq, 0)
    load = os.getloadavg()[0]
    # the profile in CPU seconds (process_time): on a loaded machine the wall clock mostly
    # measures the other jobs
    prof = cProfile.Profile(time.process_time) if profile else None
    with thread_budget(threads):
        t, cpu = time.perf_counter(), time.process_time()
        if prof is not None:
            prof.enable()
        chi, alpha, info = initial_estimate(trk, frame, cache=None)
        if prof is not None:
            prof.disable()
        seconds = time.perf_counter() - t
        cpu = time.process_time() - cpu
    if prof is not None:
        prof.dump_stats(profile)
        pstats.Stats(profile).sort_stats("cumulative").print_stats(30)
        pstats.Stats(profile).sort_stats("tottime").print_stats(20)
    acc = accuracy_metrics(body, seq, chi[None], alpha)
    root = os.path.dirname(os.path.dirname(os.path.abspath(mocap.__file__)))
    return {"data": data, "seed": seed, "label": "", "mocap": root, "commit": _commit(root),
            "seconds": round(seconds, 2), "cpu_seconds": round(cpu, 2),
            "frame0_mm": round(float(acc["per_frame_mm"][0]), 2),
            "margin": info.get("margin"), "load_before": round(load, 2),
            "load_after": round(os.getloadavg()[0], 2), "threads": threads,
            "hypotheses": info.get("hypotheses"),
            # the start itself (floats written exactly): two checkouts' starts compare bit for bit
            "chi": [float(x) for x in chi], "alpha": [float(x) for x in alpha]}


def rank_agreement(data: str, seed: int, variants: list) -> None:
    """Print how cheaper E_S variants (px, triangles) rank the particles of real pose searches."""
    from scipy.stats import spearmanr

    from mocap.body.energy_mesh import energy_mesh_for
    from mocap.energy.point_chamfer import PointChamferEnergy
    from mocap.energy.silhouette import SilhouetteEnergy, silhouette_target
    from mocap.trackers import initialization as init

    cfg = compose("track", [f"data={data}", "tracker=apf_prior", f"seed={seed}", "init.mode=tracker"])
    body = build(cfg.body)
    seq = build(cfg.data, body=body)
    rig, masks = seq.rig, frame_of(seq, 0).masks
    batches, run_apf = [], init.run_apf

    def recorded(energy, center, *args, **kw):
        layer = [0]

        def scored(x):
            batches.append((layer[0], x.copy()))
            layer[0] += 1
            return energy(x)
        return run_apf(scored, center, *args, **kw)

    init.run_apf = recorded
    settings = init.InitSettings(rounds=1, keep=1)
    with thread_budget(1):
        try:
            init.initialize_from_silhouettes(body, rig, masks, np.random.default_rng(seed), settings)
        finally:
            init.run_apf = run_apf
        pose = [b for b in batches if len(b[1]) == settings.pose_particles]
        drawn = np.random.default_rng(1).choice(len(pose), min(60, len(pose)), replace=False)
        picked = [pose[i] for i in drawn]
        shaped = body.shaped()

        def energy(px, faces, samples=None):
            """px "points": the point chamfer on the faces' mesh vertices, samples contour
            samples, against the search's own masks (version 7)"""
            if px == "points":
                scale = settings.resolution / float(np.max(rig.sizes))
                e = PointChamferEnergy(shaped, rig, scale, mesh=energy_mesh_for(body, faces),
                                       samples=samples)
            else:
                scale = px / float(np.max(rig.sizes))
                e = SilhouetteEnergy(shaped, rig, scale, mesh=energy_mesh_for(body, faces))
            target = silhouette_target(masks, scale)
            return lambda x: e(x, target)

        def timed(f):
            t = time.process_time()
            out = [f(x) for _, x in picked]
            return out, 1e3 * (time.process_time() - t) / (len(picked) * settings.pose_particles)

        ref, ms_ref = timed(energy(settings.resolution, settings.energy_mesh))
        print(f"{data}: {len(pose)} pose-search batches, {len(picked)} scored; the search's E_S "
              f"{ms_ref:.3f} ms per particle")
        for px, faces, *samples in variants:
            es, ms = timed(energy(px, faces, *samples))
            rho = np.array([spearmanr(a, b)[0] for a, b in zip(ref, es, strict=True)])
            early = np.array([m < 7 for m, _ in picked])
            overlap = np.mean([len(set(np.argsort(a)[:15]) & set(np.argsort(b)[:15])) / 15
                               for a, b in zip(ref, es, strict=True)])
            rank = np.median([np.argsort(np.argsort(a))[np.argmin(b)] for a, b in zip(ref, es, strict=True)])
            name = f"points, {faces} triangles, {samples[0]} samples" if px == "points" else \
                f"{px} px, {faces} triangles"
            print(f"  {name}: {ms:.3f} ms ({ms_ref / ms:.1f}x cheaper); Spearman median "
                  f"{np.median(rho):.3f} (layers 1-7 {np.median(rho[early]):.3f}, 8-10 "
                  f"{np.median(rho[~early]):.3f}); 15 lowest shared {overlap:.2f}; "
                  f"its best's rank {rank:.0f}", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=MISMATCH, help="data configs, comma-separated; or mismatch, dev, test")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--tracker", default="apf_prior")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--label", default="")
    p.add_argument("--out", default=None, help="append one JSON line per sequence to this file")
    p.add_argument("--profile", default=None, help="cProfile the first initialisation into this file")
    p.add_argument("--init", default=None, help='initialiser settings changed, JSON (e.g. \'{"rounds": 1}\')')
    p.add_argument("--rank", default=None, help="cheaper E_S variants [[px, triangles], ...], JSON: "
                   "their rank agreement with the search's E_S on the first sequence (no starts)")
    a = p.parse_args()
    init = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(a.init or "{}").items()}
    names = {"mismatch": MISMATCH, "dev": DEV, "test": TEST}
    data = [d for part in a.data.split(",") for d in names.get(part, part).split(",") if d]
    if a.rank:
        rank_agreement(data[0], a.seed, json.loads(a.rank))
        return
    for i, d in enumerate(data):
        row = run_one(d, a.seed, a.tracker, a.threads, a.profile if i == 0 else None, init)
        row["label"] = a.label
        row["init"] = init
        print(json.dumps(row), flush=True)
        if a.out:
            with open(a.out, "a") as fh:
                fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()

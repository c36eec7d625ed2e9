"""Silhouette rasterizer benchmark: 250 particles x 8 ring cameras, as in a tracker step.

Run: ``.venv/bin/python benchmarks/bench_rasterizer.py [--particles 250] [--repeats 3]``.

Poses: zero pose with joint angles ~ N(0, 0.3 rad), root at the origin. Cameras: 8 on a
circle of radius 3.5 m at height 1.5 m looking at (0, 0, 1), 500x500 px, focal 700 px;
silhouettes at 250x250 (scale 0.5). Times are the median over repeats of a whole batch,
divided by the number of particle-views. Alternatives (OpenCV fills, approximations) run
on a subset of views; their IoU is against the exact pixel-centre union (``reference``)
and against OpenCV's own exact union (``opencv`` loop over all triangles), since OpenCV's
fills cover ~1 px more along the outline.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from mocap import presets
from mocap.body import load_body_model
from mocap.render import distance_transform, get_rasterizer, rasterize_silhouettes
from mocap.render.reference import rasterize_opencv, rasterize_reference
from mocap.render.scaling import scale_pixels

REPO = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------- cameras (pinhole, local)
def ring_cameras(num: int, radius: float, height: float, focal: float,
                 size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K (C, 3, 3), R (C, 3, 3), t (C, 3) of OpenCV cameras looking at (0, 0, 1)."""
    Ks, Rs, ts = [], [], []
    for k in range(num):
        a = 2 * np.pi * k / num
        eye = np.array([radius * np.cos(a), radius * np.sin(a), height])
        z = np.array([0.0, 0.0, 1.0]) - eye
        z /= np.linalg.norm(z)
        x = np.cross(z, [0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        R = np.stack([x, np.cross(z, x), z])
        Ks.append([[focal, 0, (size - 1) / 2], [0, focal, (size - 1) / 2], [0, 0, 1]])
        Rs.append(R)
        ts.append(-R @ eye)
    return np.array(Ks), np.array(Rs), np.array(ts)


def project(verts: np.ndarray, K: np.ndarray, R: np.ndarray,
            t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """verts (P, V, 3) -> pixels (P, C, V, 2) float32, depth (P, C, V): one matrix product."""
    P, V, _ = verts.shape
    C = len(R)
    # Rows of KR and Kt give homogeneous pixels directly: (P*V, 3) @ (3, 3C).
    KR = (K @ R).astype(np.float32)
    Kt = np.einsum("cij,cj->ci", K, t).astype(np.float32)
    h = verts.reshape(P * V, 3) @ KR.transpose(2, 0, 1).reshape(3, 3 * C)
    h = h.reshape(P, V, C, 3) + Kt
    h = h.transpose(0, 2, 1, 3)                         # (P, C, V, 3)
    depth = np.ascontiguousarray(h[..., 2])
    return np.ascontiguousarray(h[..., :2]) / depth[..., None], depth


# ------------------------------------------------------------ alternative rasterizers
def front_facing(px: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) bool: projected clockwise in (x right, y down) = outward normal towards camera."""
    a, b, c = px[faces[:, 0]], px[faces[:, 1]], px[faces[:, 2]]
    return ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
            - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0


def fixed(px: np.ndarray, shift: int = 4) -> np.ndarray:
    return np.round(px * (1 << shift)).astype(np.int32)


def cv_loop_front(px, faces, h, w):
    return rasterize_opencv(px, faces, h, w, keep=front_facing(px, faces))


def cv_fillpoly_one_call(px, faces, h, w):
    m = np.zeros((h, w), np.uint8)
    cv2.fillPoly(m, list(fixed(px)[faces]), 1, shift=4)
    return m.view(bool)


def cv_fillpoly_per_part(px, faces, h, w, parts, front_only):
    out = np.zeros((h, w), np.uint8)
    tris = fixed(px)[faces]
    keep = front_facing(px, faces) if front_only else np.ones(len(faces), bool)
    m = np.empty((h, w), np.uint8)
    for ids in parts:
        m[:] = 0
        cv2.fillPoly(m, list(tris[ids[keep[ids]]]), 1, shift=4)
        out |= m
    return out.view(bool)


def cv_hull_per_part(px, faces, h, w, part_vertices):
    m = np.zeros((h, w), np.uint8)
    q = fixed(px)
    for ids in part_vertices:
        cv2.fillConvexPoly(m, cv2.convexHull(q[ids]), 1, shift=4)
    return m.view(bool)


# --------------------------------------------------------------------------- helpers
def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def timed(fn: Callable[[], object], repeats: int,
          warmup: int = 1) -> tuple[tuple[float, float], object]:
    """(median, min) wall time of ``repeats`` calls after ``warmup`` untimed ones; output."""
    for _ in range(warmup):
        fn()
    out, times = None, []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return (statistics.median(times), min(times)), out


def per(dt: tuple[float, float], n: int) -> tuple[float, float]:
    return dt[0] / n, dt[1] / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=250)
    ap.add_argument("--cameras", type=int, default=8)
    ap.add_argument("--size", type=int, default=500)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--subset", type=int, default=24, help="views for the slow alternatives")
    args = ap.parse_args()

    cfg = presets.read("body", "paper22")
    body = load_body_model(cfg["dofs"])
    rng = np.random.default_rng(0)
    chi = body.zero_pose(args.particles)
    chi[:, 6:] = rng.normal(0.0, 0.3, (args.particles, chi.shape[1] - 6))
    verts = body.shaped().pose(chi).vertices
    faces = body.faces
    K, R, t = ring_cameras(args.cameras, 3.5, 1.5, 700.0, args.size)
    S, P, C = args.size, args.particles, args.cameras
    n = P * C
    rows: list[tuple[str, tuple[float, float], str]] = []

    dt, (px, depth) = timed(lambda: project(verts, K, R, t), args.repeats)
    rows.append(("projection (P*V x 3 @ 3 x 3C)", per(dt, n), ""))

    t0 = time.perf_counter()
    get_rasterizer(faces, body.num_vertices)           # edge table, built once per topology
    rows.append(("edge table, once per topology (ms total)", (time.perf_counter() - t0,) * 2,
                 ""))
    h_int = round(S * args.scale)
    masks = np.empty((P, C, h_int, h_int), dtype=bool)
    dt, _ = timed(lambda: rasterize_silhouettes(px, faces, S, S, depth, scale=args.scale),
                  args.repeats)
    rows.append((f"scanline {h_int}px, threads=1, fresh output", per(dt, n), "exact"))
    for threads in (1, 2):
        dt, _ = timed(lambda th=threads: rasterize_silhouettes(
            px, faces, S, S, depth, scale=args.scale, threads=th, out=masks), args.repeats)
        rows.append((f"scanline {h_int}px, threads={threads}, out= reused", per(dt, n), "exact"))
    full = np.empty((P, C, S, S), dtype=bool)
    for threads in (1, 2):
        dt, _ = timed(lambda th=threads, o=full: rasterize_silhouettes(
            px, faces, S, S, depth, threads=th, out=o), args.repeats)
        rows.append((f"scanline {S}px, threads={threads}, out= reused", per(dt, n), "exact"))
    del full
    dist = np.empty(masks.shape, dtype=np.float32)
    for threads in (1, 2):
        dt, _ = timed(lambda th=threads: distance_transform(masks, threads=th, out=dist),
                      args.repeats)
        rows.append((f"distance transform {h_int}px (precise), threads={threads}", per(dt, n), ""))

    # Alternatives on a subset of views, at the internal resolution.
    flat_px = scale_pixels(px, S, S, args.scale)[0].reshape(n, -1, 2).astype(np.float64)
    views = rng.choice(n, min(args.subset, n), replace=False)
    small = masks.reshape(n, h_int, h_int)
    ref = [rasterize_reference(flat_px[v], faces, h_int, h_int) for v in views]
    ocv = [rasterize_opencv(flat_px[v], faces, h_int, h_int) for v in views]
    labels = body.part_labels
    part_faces = [np.flatnonzero(labels[faces[:, 0]] == j) for j in np.unique(labels)]
    part_verts = [np.flatnonzero(labels == j) for j in np.unique(labels)]
    alternatives: dict[str, Callable] = {
        "numpy reference (vectorised pixel tests)": rasterize_reference,
        "fillConvexPoly loop, all triangles": rasterize_opencv,
        "fillConvexPoly loop, front-facing only": cv_loop_front,
        "fillPoly per part, front-facing, OR": lambda *a: cv_fillpoly_per_part(
            *a, part_faces, True),
        "fillPoly per part, all triangles, OR": lambda *a: cv_fillpoly_per_part(
            *a, part_faces, False),
        "fillPoly one call (even-odd, wrong)": cv_fillpoly_one_call,
        "convex hull per part (approximation)": lambda *a: cv_hull_per_part(*a, part_verts),
    }
    iou_fast = min(iou(small[v], r) for v, r in zip(views, ref, strict=True))
    rows[2] = (rows[2][0], rows[2][1], f"exact: IoU vs reference min {iou_fast:.4f}")
    for name, fn in alternatives.items():
        t0 = time.perf_counter()
        out = [fn(flat_px[v], faces, h_int, h_int) for v in views]
        dt = (time.perf_counter() - t0) / len(views)
        i_ref = np.mean([iou(o, r) for o, r in zip(out, ref, strict=True)])
        i_cv = np.mean([iou(o, r) for o, r in zip(out, ocv, strict=True)])
        rows.append((f"alt {h_int}px: {name}", (dt, dt),
                     f"IoU ref {i_ref:.4f} / opencv {i_cv:.4f}"))

    # IoU against the exact union at full resolution.
    full_px = px.reshape(n, -1, 2).astype(np.float64)
    sub = views[: max(4, len(views) // 3)]
    ref_full = [rasterize_reference(full_px[v], faces, S, S) for v in sub]
    fast_full = rasterize_silhouettes(px.reshape(n, -1, 2)[sub], faces, S, S)
    up = [cv2.resize(small[v].view(np.uint8), (S, S), interpolation=cv2.INTER_NEAREST)
          .view(bool) for v in sub]
    cv_full = [rasterize_opencv(full_px[v], faces, S, S) for v in sub]
    print(f"{P} particles x {C} cameras = {n} particle-views; image {S}px, internal "
          f"{h_int}px; {len(views)} views for alternatives\n")
    print(f"{'what (ms per particle-view)':58s} {'median':>8s} {'min':>8s}  notes")
    for name, (med, low), note in rows:
        print(f"{name:58s} {med * 1e3:8.4f} {low * 1e3:8.4f}  {note}")
    print(f"\nIoU vs exact reference at {S}x{S} ({len(sub)} views, mean / min):")
    for name, out in (("scanline at full resolution", list(fast_full)),
                      (f"scanline at {h_int}px, nearest-upsampled", up),
                      ("fillConvexPoly loop (OpenCV fill convention)", cv_full)):
        vals = [iou(o, r) for o, r in zip(out, ref_full, strict=True)]
        print(f"  {name:50s} {np.mean(vals):.4f} / {np.min(vals):.4f}")


if __name__ == "__main__":
    main()

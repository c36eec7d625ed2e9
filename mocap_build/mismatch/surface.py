"""The true body surface the benchmarks keep (``gt.npz`` fields ``surface``, ``surface_faces``).

Storing anny's full posed mesh (~14k vertices) per frame would multiply the benchmarks' size,
so they keep a documented dense subset: anny's outer skin (the largest connected part of its
mesh: no eyes, no mouth interior) decimated ONCE, on the reference body (every phenotype at
0.5), by quadric decimation to :data:`TARGET_FACES` faces (~2000 vertices); each decimated
vertex is mapped to its exact closest point of that full mesh (triangle + barycentric
coordinates, :func:`mocap.eval.surface.closest_points_on_mesh`). Every subject shares anny's
topology, so in every frame the subset's points are the same barycentric combinations of the
posed full mesh: points ON the rendered surface, with the decimated mesh's faces. Stored as
float32 metres, world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TARGET_FACES = 4000
DESCRIPTION = (f"anny's outer skin decimated once to {TARGET_FACES} faces (reference body), each point "
               "a fixed barycentric combination of the posed full mesh (mocap_build/mismatch/surface.py)")


@dataclass(frozen=True)
class SurfaceSubset:
    """Points of anny's full mesh: triangle (N,) of the full faces and barycentric (N, 3);
    faces (M, 3) int32 over the N points."""

    triangle: np.ndarray
    bary: np.ndarray
    faces: np.ndarray

    def points(self, full_faces: np.ndarray, vertices: np.ndarray) -> np.ndarray:
        """Posed full meshes (F, V, 3) -> subset points (F, N, 3) float32."""
        corners = np.asarray(vertices, np.float64)[:, np.asarray(full_faces)[self.triangle]]   # (F, N, 3, 3)
        return np.einsum("nk,fnkc->fnc", self.bary, corners).astype(np.float32)


_SUBSETS: dict = {}


def surface_subset(model, target_faces: int = TARGET_FACES) -> SurfaceSubset:
    """The subset of anny's mesh (build extra): deterministic for one anny version; computed once
    per model in a process."""
    key = (id(model), target_faces)
    if key not in _SUBSETS:
        _SUBSETS[key] = _surface_subset(model, target_faces)
    return _SUBSETS[key]


def _surface_subset(model, target_faces: int) -> SurfaceSubset:
    import torch

    from mocap.body.build.topology import decimate, largest_component
    from mocap.eval.surface import closest_points_on_mesh

    pheno = {k: torch.tensor([0.5], dtype=model.dtype) for k in model.phenotype_labels}
    with torch.no_grad():
        rest = model(phenotype_kwargs=pheno)["rest_vertices"][0].double().numpy()
    faces = model.get_triangular_faces().numpy().astype(np.int64)
    skin, kept = largest_component(faces, len(rest))
    skin_ids = np.flatnonzero(np.isin(faces[:, 0], kept))      # the skin's faces among the full ones
    assert (kept[skin] == faces[skin_ids]).all()
    v, f = decimate(rest[kept], skin, target_faces)
    _, tri, bary = closest_points_on_mesh(v, rest, faces[skin_ids])
    return SurfaceSubset(triangle=skin_ids[tri], bary=bary, faces=f.astype(np.int32))


def surface_meta(subset: SurfaceSubset) -> dict:
    """What sequence.json's meta says about the stored surface."""
    return {"points": int(len(subset.bary)), "faces": int(len(subset.faces)), "dtype": "float32",
            "description": DESCRIPTION}


def add_surface(folder, vertices: np.ndarray, joints: np.ndarray, full_faces: np.ndarray,
                subset: SurfaceSubset) -> dict:
    """The surface-only build mode: an existing sequence folder's gt.npz gets ``surface`` and
    ``surface_faces`` from the posed full meshes (F, V, 3), nothing re-rendered. Refused unless
    the folder's ground-truth joints equal ``joints`` (F, J, 3) (the same posing) to 1e-6 m.
    Every other array of gt.npz is kept as it was (checked after writing); sequence.json's meta
    gets ``surface`` (:func:`surface_meta`). -> a report: the largest joint difference and
    the kept arrays."""
    import json
    from pathlib import Path

    folder = Path(folder)
    gt_path = folder / "gt.npz"
    with np.load(gt_path, allow_pickle=False) as z:
        old = {k: z[k] for k in z.files if k not in ("surface", "surface_faces")}
    diff = float(np.abs(old["joints"] - joints).max())
    if diff > 1e-6:
        raise ValueError(f"{gt_path}: field 'joints' differs from the re-posed body by {diff:.3g} m: "
                         "regenerate the sequence fully instead")
    new = dict(old, surface=subset.points(full_faces, vertices), surface_faces=subset.faces)
    tmp = folder / ".gt.npz.tmp.npz"
    np.savez_compressed(tmp, **new)
    tmp.replace(gt_path)
    with np.load(gt_path, allow_pickle=False) as z:
        for k, v in old.items():
            if not np.array_equal(z[k], v):
                raise AssertionError(f"{gt_path}: field {k!r} changed while adding the surface")
    info_path = folder / "sequence.json"
    info = json.loads(info_path.read_text())
    info["meta"]["surface"] = surface_meta(subset)
    info_path.write_text(json.dumps(info, indent=2))
    return {"joints_max_diff_m": diff, "kept": sorted(old)}

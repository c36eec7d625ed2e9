"""The synthetic multi-view generator: render a body-model motion into every view, with
exact ground truth (shape, poses, 3D joints, 3D markers)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mocap.body.landmarks import LandmarkSet
from mocap.body.model import BodyModel
from mocap.cameras import Rig, project
from mocap.data.corruption import DetectionModel, SilhouetteNoise
from mocap.data.sequence import Detections, GroundTruth, Sequence
from mocap.data.source_settings import SyntheticSource
from mocap.render import rasterize_silhouettes

Progress = Callable[[int, int], None]


def marker_visibility(vertices: np.ndarray, faces: np.ndarray, markers: np.ndarray,
                      rig: Rig, tolerance: float = 0.02, face_parts: np.ndarray | None = None,
                      own_parts: list[set[int]] | None = None) -> np.ndarray:
    """(C, L) bool: markers not hidden by the body from each camera centre (ray casting).

    Without ``own_parts`` a marker is hidden by any surface in front of it (a physical marker
    on or in the body, as rendered). With ``face_parts`` (F,) and ``own_parts`` (a set of
    part ids per marker), a surface of the marker's own parts in front of it does not hide it:
    the semantics of a keypoint detector, which sees a joint inside its own limb.
    """
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    out = np.ones((len(rig), len(markers)), dtype=bool)
    for c, center in enumerate(rig.centers):
        d = markers - center
        dist = np.linalg.norm(d, axis=1)
        loc, ray_idx, tri = mesh.ray.intersects_location(np.repeat(center[None], len(markers), 0),
                                                         d / dist[:, None], multiple_hits=False)
        if len(ray_idx):
            hit_dist = np.linalg.norm(loc - center, axis=1)
            visible = hit_dist >= dist[ray_idx] - tolerance
            if own_parts is not None and face_parts is not None:
                own = np.array([face_parts[t] in own_parts[r] for t, r in zip(tri, ray_idx, strict=True)])
                visible |= own
            out[c, ray_idx] = visible
    return out


def landmark_parts(body: BodyModel, landmarks: LandmarkSet) -> list[set[int]]:
    """Parts whose surface may cover each landmark without hiding it from a keypoint detector:
    its carrier joint, the joint it sits at, and their parents and children."""
    out = []
    for lm, j in zip(landmarks.landmarks, landmarks.joint, strict=True):
        joints = {int(j)} | ({body.joint_index(lm.at)} if lm.at is not None else set()) \
            | {body.joint_index(n) for n in lm.between}
        near = set(joints)
        for k in joints:
            if body.parents[k] >= 0:
                near.add(int(body.parents[k]))
            near |= {int(ch) for ch in np.flatnonzero(body.parents == k)}
        out.append(near)
    return out


def generate_sequence(body: BodyModel, rig: Rig, chi: np.ndarray, alpha: np.ndarray, *,
                      name: str = SyntheticSource.name, fps: float = SyntheticSource.fps,
                      seed: int = SyntheticSource.seed, landmarks: LandmarkSet | None = None,
                      masks: bool = SyntheticSource.masks, images: bool = SyntheticSource.images,
                      marker_spheres: bool = SyntheticSource.marker_spheres,
                      detections: DetectionModel | None = None,
                      silhouette_noise: SilhouetteNoise | None = None,
                      occlusion: bool = True, progress: Progress | None = None,
                      meta: dict | None = None) -> Sequence:
    """Render ``chi`` (F, D) of the body of shape ``alpha`` (K,) into ``rig``.

    Silhouettes come from the project's rasterizer (the trackers' own, as STACK.md advises);
    RGB images from pyrender. Randomness (detections, noise, texture) flows from ``seed``.
    """
    chi = np.asarray(chi, dtype=body.dtype)
    if chi.ndim != 2 or chi.shape[1] != body.num_dofs:
        raise ValueError(f"chi must be (F, {body.num_dofs}), got {chi.shape}")
    rng = np.random.default_rng(seed)
    landmarks = landmarks or LandmarkSet(body)
    shaped = body.shaped(alpha)
    F, C = len(chi), len(rig)
    w, h = (int(x) for x in rig.sizes[0])
    gt_joints = np.zeros((F, body.num_joints, 3))
    gt_markers = np.zeros((F, len(landmarks), 3))
    mask_arr = np.zeros((F, C, h, w), dtype=bool) if masks else None
    img_arr = np.zeros((F, C, h, w, 3), dtype=np.uint8) if images else None
    det_rows: list[tuple] = []
    renderer = None
    if images:
        from mocap.render.pyrender_rgb import RenderMesh, RGBRenderer, body_texture, marker_meshes

        renderer = RGBRenderer(w, h)
        texture = body_texture(body.part_labels, body.joint_names, seed=seed)
    rest_pts = landmarks.rest_points(shaped)
    face_parts = body.part_labels[body.faces[:, 0]]
    own_parts = landmark_parts(body, landmarks)
    try:
        for f in range(F):
            out = shaped.pose(chi[f])
            verts = out.vertices[0]
            gt_joints[f] = out.joints[0]
            gt_markers[f] = landmarks.from_transforms(out.transforms, rest_pts)[0]
            if masks:
                px, depth = project(rig, verts, return_depth=True)
                sil = rasterize_silhouettes(px, body.faces, h, w, depth, near=0.05)
                if silhouette_noise is not None and silhouette_noise.active:
                    sil = np.stack([silhouette_noise.apply(s, rng) for s in sil])
                mask_arr[f] = sil
            if renderer is not None:
                meshes = [RenderMesh(verts, body.faces, texture)]
                if marker_spheres:
                    meshes += marker_meshes(gt_markers[f])
                for c, cam in enumerate(rig):
                    img_arr[f, c] = renderer.render(cam, meshes)[0]
            if detections is not None:
                mpx, mdepth = project(rig, gt_markers[f], return_depth=True)
                vis = mdepth > 0.05
                if occlusion:
                    vis &= marker_visibility(verts, body.faces, gt_markers[f], rig, face_parts=face_parts,
                                             own_parts=own_parts)
                for c in range(C):
                    lab, xy, conf = detections.sample(mpx[c], vis[c], w, h, rng)
                    det_rows += [(f, c, int(lb), x, y, cf)
                                 for lb, (x, y), cf in zip(lab, xy, conf, strict=True)]
            if progress is not None:
                progress(f + 1, F)
    finally:
        if renderer is not None:
            renderer.close()
    det = None
    if detections is not None:
        arr = np.array(det_rows, dtype=np.float64).reshape(-1, 6)
        det = Detections(labels=landmarks.names, frame=arr[:, 0].astype(np.int64),
                         view=arr[:, 1].astype(np.int64), label=arr[:, 2].astype(np.int64),
                         xy=arr[:, 3:5], confidence=arr[:, 5])
    gt = GroundTruth(alpha=np.asarray(alpha, np.float64), chi=chi.astype(np.float64),
                     joints=gt_joints, markers=gt_markers, dof_names=body.dof_names,
                     joint_names=body.joint_names, marker_names=landmarks.names, body=body.name)
    return Sequence(name=name, rig=rig, fps=fps, masks=mask_arr, images=img_arr,
                    detections=det, gt=gt, meta=dict(meta or {}))

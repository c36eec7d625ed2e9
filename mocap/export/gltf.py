"""glTF 2.0 binary (GLB) export, written with ``pygltflib``: the run's body as a skinned mesh
(rest mesh of the run's shape, mocap's skinning weights) and one animation with F keyframes:
a rotation per joint and the root's translation. Y up (``axes.GLTF_FROM_WORLD``), metres.

Skinning: 4 influences per vertex by default (JOINTS_0 + WEIGHTS_0, the 4 largest of mocap's
weights, renormalised to sum to 1): every glTF reader applies them, whereas a reader that takes
only the first set (many engines) would see weights summing below 1 on the vertices that mocap
blends over more than 4 joints (166 of 5002 for paper22, up to 6). ``influences=8``
(JOINTS_0/1 + WEIGHTS_0/1) keeps mocap's LBS exactly for readers that apply both sets
(Blender, three.js).

Joint node j sits at its rest position (local translation: the rest bone offset), so the
skeleton looks right in Blender and three.js; its inverse bind matrix is T(-rest_j).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib as gl
from scipy.spatial.transform import Rotation

from mocap.export.axes import GLTF_FROM_WORLD, points_to, rotations_to
from mocap.export.motion import Motion

#: influences per vertex: the default and the allowed (a glTF attribute set holds 4)
INFLUENCES = 4
ALLOWED_INFLUENCES = (4, 8)


class _Blob:
    def __init__(self):
        self.data = bytearray()
        self.views: list[gl.BufferView] = []
        self.accessors: list[gl.Accessor] = []

    def add(self, arr: np.ndarray, kind: str, ctype: int, target: int | None = None,
            minmax: bool = False) -> int:
        arr = np.ascontiguousarray(arr)
        while len(self.data) % 4:
            self.data.append(0)
        self.views.append(gl.BufferView(buffer=0, byteOffset=len(self.data), byteLength=arr.nbytes,
                                        target=target))
        self.data += arr.tobytes()
        count = arr.shape[0]
        acc = gl.Accessor(bufferView=len(self.views) - 1, componentType=ctype, count=count, type=kind)
        if minmax:
            flat = arr.reshape(count, -1)
            acc.min, acc.max = flat.min(axis=0).tolist(), flat.max(axis=0).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1


def skin_influences(weights: np.ndarray, k: int = INFLUENCES) -> tuple[np.ndarray, np.ndarray]:
    """(V, J) weights -> the k largest per vertex: joints (V, k) uint16, weights (V, k) float32
    summing to 1."""
    idx = np.argsort(-weights, axis=1)[:, :k]
    w = np.take_along_axis(weights, idx, axis=1).astype(np.float64)
    w /= w.sum(axis=1, keepdims=True)
    idx = np.where(w > 0, idx, 0)
    return idx.astype(np.uint16), w.astype(np.float32)


def write_gltf(motion: Motion, path: str | Path, body, influences: int = INFLUENCES) -> Path:
    """body: the run's :class:`mocap.body.model.BodyModel` (rest mesh, faces, weights);
    influences: joints per vertex, 4 or 8 (see the module docstring)."""
    return write_people_gltf([("", motion, None)], path, body, influences)


def write_people_gltf(people, path: str | Path, body, influences: int = INFLUENCES) -> Path:
    """One GLB with a skinned body per person: ``people`` [(name prefix, motion over the same
    F frames, visible (F,) bool or None)]; each person has its own joint nodes (named
    ``<prefix><joint>``), mesh and skin, and one animation drives them all. A person not
    visible in a frame has its root joint scaled to 0 there (STEP interpolation; the pose
    held is the nearest visible frame's, :func:`mocap.export.people_motion.person_timeline`)."""
    if influences not in ALLOWED_INFLUENCES:
        raise ValueError(f"setting influences = {influences!r} is out of range (one of {ALLOWED_INFLUENCES})")
    if not people:
        raise ValueError("a glTF export needs at least one person")
    F, fps = people[0][1].num_frames, people[0][1].fps
    b = _Blob()
    parts: dict = {"nodes": [], "meshes": [], "skins": [], "samplers": [], "channels": [], "scene": []}
    times = b.add((np.arange(F) / fps).astype(np.float32), "SCALAR", gl.FLOAT, minmax=True)
    for prefix, motion, visible in people:
        if motion.num_frames != F:
            raise ValueError(f"person {prefix!r}: {motion.num_frames} frames, the others {F}")
        _add_person(b, parts, motion, body, influences, times, prefix, visible)
    doc = gl.GLTF2(
        asset=gl.Asset(generator="mocap", version="2.0"),
        scene=0, scenes=[gl.Scene(nodes=parts["scene"])], nodes=parts["nodes"], meshes=parts["meshes"],
        skins=parts["skins"],
        animations=[gl.Animation(name="motion", samplers=parts["samplers"], channels=parts["channels"])],
        accessors=b.accessors, bufferViews=b.views, buffers=[gl.Buffer(byteLength=len(b.data))])
    doc.set_binary_blob(bytes(b.data))
    path = Path(path)
    doc.save_binary(str(path))
    return path


def _add_person(b: _Blob, parts: dict, motion: Motion, body, influences: int, times: int, prefix: str,
                visible: np.ndarray | None) -> None:
    """Append one person's joint nodes, mesh, skin and animation channels to ``parts``."""
    F, J = motion.num_frames, len(motion.joint_names)
    par = motion.joint_parents
    shaped = body.shaped(motion.alpha[-1])
    rest_v = points_to(GLTF_FROM_WORLD, shaped.rest_vertices).astype(np.float32)
    rest_j = points_to(GLTF_FROM_WORLD, motion.rest_joints)
    R = rotations_to(GLTF_FROM_WORLD, motion.joint_rotations)               # (F, J, 3, 3)
    local = R.copy()
    nonroot = par >= 0
    local[:, nonroot] = np.swapaxes(R[:, par[nonroot]], -1, -2) @ R[:, nonroot]
    quat = Rotation.from_matrix(local.reshape(-1, 3, 3)).as_quat().reshape(F, J, 4).astype(np.float32)
    root_t = points_to(GLTF_FROM_WORLD, motion.joints[:, 0]).astype(np.float32)

    pos = b.add(rest_v, "VEC3", gl.FLOAT, gl.ARRAY_BUFFER, minmax=True)
    ind = b.add(np.asarray(body.faces, np.uint32).ravel(), "SCALAR", gl.UNSIGNED_INT, gl.ELEMENT_ARRAY_BUFFER)
    jnt, wts = skin_influences(np.asarray(body.weights, np.float64), influences)
    attrs = {"POSITION": pos}
    for s in range(influences // 4):
        attrs[f"JOINTS_{s}"] = b.add(jnt[:, 4 * s:4 * s + 4], "VEC4", gl.UNSIGNED_SHORT, gl.ARRAY_BUFFER)
        attrs[f"WEIGHTS_{s}"] = b.add(wts[:, 4 * s:4 * s + 4], "VEC4", gl.FLOAT, gl.ARRAY_BUFFER)
    ibm = np.tile(np.eye(4, dtype=np.float32), (J, 1, 1))
    ibm[:, :3, 3] = -rest_j
    ibm_acc = b.add(np.transpose(ibm, (0, 2, 1)).reshape(J, 16), "MAT4", gl.FLOAT)  # column-major

    nodes, samplers, channels = parts["nodes"], parts["samplers"], parts["channels"]
    base = len(nodes)
    for j, name in enumerate(motion.joint_names):
        t = rest_j[j] if par[j] < 0 else rest_j[j] - rest_j[par[j]]
        nodes.append(gl.Node(name=f"{prefix}{name}", translation=[float(v) for v in t],
                             children=[base + int(c) for c in np.flatnonzero(par == j)]))
    mesh_node = len(nodes)
    nodes.append(gl.Node(name=f"{prefix}body", mesh=len(parts["meshes"]), skin=len(parts["skins"])))
    root = int(np.flatnonzero(par < 0)[0])
    parts["meshes"].append(gl.Mesh(name=f"{prefix}body", primitives=[
        gl.Primitive(attributes=gl.Attributes(**attrs), indices=ind)]))
    parts["skins"].append(gl.Skin(name=f"{prefix}skin" if prefix else None,
                                  joints=list(range(base, base + J)), inverseBindMatrices=ibm_acc,
                                  skeleton=base + root))
    parts["scene"] += [base + root, mesh_node]

    def channel(node: int, what: str, values: np.ndarray, kind: str, interpolation: str = "LINEAR") -> None:
        samplers.append(gl.AnimationSampler(input=times, output=b.add(values, kind, gl.FLOAT),
                                            interpolation=interpolation))
        channels.append(gl.AnimationChannel(sampler=len(samplers) - 1,
                                            target=gl.AnimationChannelTarget(node=node, path=what)))

    for j in range(J):
        channel(base + j, "rotation", quat[:, j], "VEC4")
    channel(base + root, "translation", root_t, "VEC3")
    if visible is not None:
        scale = np.repeat(np.asarray(visible, np.float32)[:, None], 3, axis=1)
        channel(base + root, "scale", scale, "VEC3", "STEP")

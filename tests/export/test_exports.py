"""Exports read back by readers that do not share our writing code: a BVH reader written from
the format's definition (forward kinematics with scipy's Euler angles) and bvhio's parser,
a TRC reader following OpenSim's layout, pygltflib + an independent skinning of the GLB and
trimesh, and ezc3d."""

import subprocess
import sys

import bvhio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocap.export.axes import BVH_FROM_WORLD, GLTF_FROM_WORLD, OPENSIM_FROM_WORLD
from mocap.export.motion import load_motion
from mocap.run_folder.export import export_run, motion_body


def read_bvh_joints(path) -> tuple[list[str], np.ndarray, float]:
    """A BVH reader from the format's definition: names, world joint positions (F, J, 3)
    by forward kinematics (channels in file order, rotations intrinsic in channel order)."""
    tokens = path.read_text().split()
    i, stack, joints = 0, [], []          # joints: (name, parent, offset, channels)
    while tokens[i] != "MOTION":
        t = tokens[i]
        if t in ("ROOT", "JOINT"):
            joints.append([tokens[i + 1], stack[-1] if stack else -1, None, []])
            stack.append(len(joints) - 1)
            i += 2
        elif t == "End":
            stack.append(None)
            i += 2
        elif t == "OFFSET":
            if stack[-1] is not None:
                joints[stack[-1]][2] = np.array([float(x) for x in tokens[i + 1:i + 4]])
            i += 4
        elif t == "CHANNELS":
            n = int(tokens[i + 1])
            joints[stack[-1]][3] = tokens[i + 2:i + 2 + n]
            i += 2 + n
        elif t == "}":
            stack.pop()
            i += 1
        else:
            i += 1
    frames = int(tokens[i + 2])
    dt = float(tokens[i + 5])
    values = np.array(tokens[i + 6:], float).reshape(frames, -1)
    out = np.zeros((frames, len(joints), 3))
    for f in range(frames):
        col, Rw = 0, [None] * len(joints)
        for j, (_, parent, offset, channels) in enumerate(joints):
            pos, order, angles = offset.copy(), "", []
            for c in channels:
                v = values[f, col]
                col += 1
                if c.endswith("position"):
                    pos["XYZ".index(c[0])] = v
                else:
                    order += c[0]
                    angles.append(v)
            R = Rotation.from_euler(order, angles, degrees=True).as_matrix()
            if parent < 0:
                out[f, j], Rw[j] = pos, R
            else:
                out[f, j] = out[f, parent] + Rw[parent] @ offset
                Rw[j] = Rw[parent] @ R
    return [j[0] for j in joints], out, dt


@pytest.fixture(scope="module")
def motion(short_run):
    return load_motion(short_run)


def test_bvh_reproduces_the_run_joints(short_run, motion, tmp_path):
    out = export_run(short_run, "bvh", tmp_path / "m.bvh")
    names, pos, dt = read_bvh_joints(out)
    assert names == list(motion.joint_names) and dt == pytest.approx(1 / motion.fps)
    want = motion.joints.astype(np.float64) @ BVH_FROM_WORLD.T
    err_mm = 1e3 * np.abs(pos - want).max()
    assert err_mm < 1.0, err_mm                              # measured ~1e-3 mm
    parsed = bvhio.readAsBvh(str(out))                        # an existing parser agrees on the layout
    assert parsed.FrameCount == motion.num_frames and parsed.Root.Name == motion.joint_names[0]
    # the rest pose stands upright in BVH axes (Y up): head above pelvis
    assert parsed.Root.Children[0].Offset.y > 0


def read_trc(path):
    """OpenSim's TRC layout: 3 header lines, marker names, X/Y/Z labels, then numbered rows."""
    lines = path.read_text().split("\n")
    keys, vals = lines[1].split("\t"), lines[2].split("\t")
    header = dict(zip(keys, vals, strict=True))
    names = [n for n in lines[3].split("\t")[2:] if n]
    data = np.loadtxt(path, skiprows=6, delimiter="\t", ndmin=2)
    return header, names, data


def test_trc_follows_opensim_layout(short_run, motion, tmp_path):
    out = export_run(short_run, "trc", tmp_path / "m.trc")
    header, names, data = read_trc(out)
    F, L = motion.num_frames, len(motion.landmark_names)
    assert header["Units"] == "mm" and int(header["NumFrames"]) == F and int(header["NumMarkers"]) == L
    assert float(header["DataRate"]) == motion.fps and names == list(motion.landmark_names)
    assert out.read_text().split("\n")[0].split("\t")[3] == "m.trc"
    np.testing.assert_array_equal(data[:, 0], np.arange(1, F + 1))
    np.testing.assert_allclose(data[:, 1], np.arange(F) / motion.fps, atol=1e-6)
    want = 1e3 * motion.landmarks.astype(np.float64) @ OPENSIM_FROM_WORLD.T
    np.testing.assert_allclose(data[:, 2:].reshape(F, L, 3), want, atol=1e-3)


def glb_accessors(path):
    """The GLB read back with pygltflib, and its accessor reader (index -> (count, width) array)."""
    import pygltflib

    g = pygltflib.GLTF2().load(str(path))
    blob = g.binary_blob()

    def acc(i):
        a = g.accessors[i]
        v = g.bufferViews[a.bufferView]
        dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[a.componentType]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a.type]
        start = v.byteOffset + (a.byteOffset or 0)
        return np.frombuffer(blob, dtype, a.count * width, start).reshape(a.count, width)
    return g, acc


def test_glb_has_4_influences_by_default_summing_to_1(short_run, tmp_path):
    g, acc = glb_accessors(export_run(short_run, "gltf", tmp_path / "m.glb"))
    prim = g.meshes[0].primitives[0]
    assert getattr(prim.attributes, "JOINTS_1", None) is None                # one set: 4 influences
    assert getattr(prim.attributes, "WEIGHTS_1", None) is None
    W = acc(prim.attributes.WEIGHTS_0).astype(np.float64)
    assert W.shape[1] == 4 and (W >= 0).all()
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-6)
    J = acc(prim.attributes.JOINTS_0)
    assert J.max() < len(g.skins[0].joints)


@pytest.mark.parametrize(("influences", "max_mm"), [(8, 1.0), (4, 10.0)])     # 4: measured 4.9 mm
def test_glb_skins_to_the_run_mesh(short_run, motion, tmp_path, influences, max_mm):
    """8 influences: mocap's skinning (within 1 mm, float32); 4: the 4 largest weights
    renormalised move the few vertices blended over more joints by a few mm."""
    import trimesh

    out = export_run(short_run, "gltf", tmp_path / "m.glb", influences=influences)
    g, acc = glb_accessors(out)

    F = motion.num_frames
    anim = g.animations[0]
    assert {len(acc(s.input)) for s in anim.samplers} == {F}
    # skin the rest mesh with the animated node transforms, independently of mocap
    prim = g.meshes[0].primitives[0]
    rest = acc(prim.attributes.POSITION).astype(np.float64)
    sets = range(influences // 4)
    J = np.hstack([acc(getattr(prim.attributes, f"JOINTS_{k}")) for k in sets]).astype(int)
    W = np.hstack([acc(getattr(prim.attributes, f"WEIGHTS_{k}")) for k in sets]).astype(np.float64)
    skin = g.skins[0]
    ibm = acc(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    parent = {c: i for i, n in enumerate(g.nodes) for c in n.children}
    f = F - 1
    local = {}
    for i, n in enumerate(g.nodes[:len(skin.joints)]):
        local[i] = np.eye(4)
        local[i][:3, 3] = n.translation
    for ch in anim.channels:
        val = acc(anim.samplers[ch.sampler].output)[f].astype(np.float64)
        if ch.target.path == "rotation":
            local[ch.target.node][:3, :3] = Rotation.from_quat(val).as_matrix()
        else:
            local[ch.target.node][:3, 3] = val
    world = {}
    for i in range(len(skin.joints)):                     # parents come first
        world[i] = local[i] if i not in parent else world[parent[i]] @ local[i]
    M = np.stack([world[j] @ ibm[k] for k, j in enumerate(skin.joints)])
    hom = np.c_[rest, np.ones(len(rest))]
    skinned = np.einsum("vk,vkab,vb->va", W, M[J], hom)[:, :3]
    body = motion_body(short_run, motion)
    want = body.shaped(motion.alpha[f]).pose(motion.chi[f]).vertices[0].astype(np.float64) @ GLTF_FROM_WORLD.T
    print(f"{influences} influences: {1e3 * np.abs(skinned - want).max():.2f} mm")
    assert 1e3 * np.abs(skinned - want).max() < max_mm
    scene = trimesh.load(str(out))                          # and trimesh opens it
    (geom,) = scene.geometry.values()
    assert len(geom.vertices) == body.num_vertices and len(geom.faces) == len(body.faces)


def test_trc_axes_are_the_bvh_axes_turned_90_degrees_about_the_vertical():
    """docs/data_formats.md: both Y up; a TRC point is the BVH point rotated by -90 degrees about
    Y (X_trc = -Z_bvh, Z_trc = X_bvh); glTF has the BVH axes, C3D the world's."""
    turn = Rotation.from_euler("y", -90, degrees=True).as_matrix()
    np.testing.assert_allclose(OPENSIM_FROM_WORLD @ BVH_FROM_WORLD.T, turn, atol=1e-12)
    np.testing.assert_array_equal(GLTF_FROM_WORLD, BVH_FROM_WORLD)
    up = np.array([0.0, 0.0, 1.0])                       # mocap's world: Z up
    np.testing.assert_array_equal(BVH_FROM_WORLD @ up, [0, 1, 0])
    np.testing.assert_array_equal(OPENSIM_FROM_WORLD @ up, [0, 1, 0])


def test_c3d_reads_back_with_ezc3d(short_run, motion, tmp_path):
    import ezc3d

    out = export_run(short_run, "c3d", tmp_path / "m.c3d")
    c = ezc3d.c3d(str(out))
    assert c["parameters"]["POINT"]["LABELS"]["value"] == list(motion.landmark_names)
    assert c["parameters"]["POINT"]["RATE"]["value"][0] == pytest.approx(motion.fps)
    pts = c["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_allclose(pts, 1e3 * motion.landmarks, atol=1e-2)


def test_export_refuses_bad_input(short_run, tmp_path):
    def cli(*args):
        return subprocess.run([sys.executable, "-m", "mocap_cli", "export", *map(str, args)],
                              capture_output=True, text=True, timeout=120)

    r = cli(tmp_path, "--format", "bvh")
    assert r.returncode == 2 and "no motion.npz" in r.stderr
    r = cli(short_run, "--format", "fbx", "--out", tmp_path / "x.fbx")
    assert r.returncode == 2 and "unknown export format 'fbx'" in r.stderr
    existing = tmp_path / "exists.trc"
    existing.write_text("keep me")
    r = cli(short_run, "--format", "trc", "--out", existing)
    assert r.returncode == 2 and "exists" in r.stderr and existing.read_text() == "keep me"
    r = cli(short_run, "--format", "trc", "--out", existing, "--overwrite")
    assert r.returncode == 0 and existing.read_text().startswith("PathFileType")

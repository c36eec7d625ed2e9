"""A several-people run exported: one BVH per person, one TRC / C3D with every person's markers
named per person, one GLB with a skinned body per person; each read back by a reader that does
not share our writing code (the BVH reader of test_exports and bvhio, OpenSim's TRC layout as
text, ezc3d, pygltflib with an independent skinning) and compared with the motion file's values.
Bad input (a person id that would name a file outside the folder, a missing person) is refused
in one line before anything is written."""

import shutil
import subprocess
import sys

import bvhio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocap.export.axes import BVH_FROM_WORLD, GLTF_FROM_WORLD, OPENSIM_FROM_WORLD
from mocap.export.motion import MotionFileError
from mocap.export.people_motion import load_people_motion
from mocap.run_folder.export import export_files, export_run, motion_body
from tests.export.test_exports import glb_accessors, read_bvh_joints


def read_trc_text(path):
    """OpenSim's TRC layout as text: the header, the marker names, the frame rows (blank cells:
    NaN)."""
    lines = path.read_text().split("\n")
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=True))
    names = [n for n in lines[3].split("\t")[2:] if n]
    rows = [r.split("\t") for r in lines[6:] if r]
    cells = np.array([[float(v) if v else np.nan for v in r[2:]] for r in rows])
    return header, names, np.array([[int(r[0]), float(r[1])] for r in rows]), cells


@pytest.fixture(scope="module")
def people(people_run):
    return load_people_motion(people_run)


def live_columns(a):
    return [(int(pid), p) for p, pid in enumerate(a["person_ids"]) if a["live"][:, p].any()]


@pytest.mark.slow
def test_one_bvh_per_person_reproduces_each_persons_joints(people_run, people, tmp_path):
    outs = export_files(people_run, "bvh", tmp_path / "walk.bvh")
    cols = live_columns(people)
    assert len(cols) >= 3 and outs == [tmp_path / f"walk_p{pid}.bvh" for pid, _ in cols]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in outs)   # nothing else left
    for (pid, p), out in zip(cols, outs, strict=True):
        names, pos, dt = read_bvh_joints(out)
        live = people["live"][:, p]
        want = people["joints"][live, p].astype(np.float64) @ BVH_FROM_WORLD.T
        assert names == [str(n) for n in people["joint_names"]]
        assert dt == pytest.approx(1 / float(people["fps"]))
        assert 1e3 * np.abs(pos - want).max() < 1.0, pid
        assert bvhio.readAsBvh(str(out)).FrameCount == int(live.sum())
    # one person alone, as a one-person run; the one-file form refuses a BVH per person
    pid, p = cols[-1]
    one = export_run(people_run, "bvh", tmp_path / "one.bvh", person=pid)
    assert read_bvh_joints(one)[1].shape[0] == int(people["live"][:, p].sum())
    with pytest.raises(ValueError, match="a BVH per person"):
        export_run(people_run, "bvh", tmp_path / "all.bvh")


@pytest.mark.slow
def test_trc_and_c3d_hold_every_person_named_per_person(people_run, people, tmp_path):
    import ezc3d

    F, P, L = people["landmarks"].shape[:3]
    want_names = [f"p{pid}_{n}" for pid in people["person_ids"] for n in people["landmark_names"]]
    live = people["live"]
    world = np.where(live[:, :, None, None], people["landmarks"].astype(np.float64), np.nan)   # (F, P, L, 3)
    # TRC, parsed as text: names, frames, millimetres in OpenSim axes, blank where a person is absent
    (trc,) = export_files(people_run, "trc", tmp_path / "all.trc")
    header, names, frames, cells = read_trc_text(trc)
    assert names == want_names and int(header["NumMarkers"]) == P * L and int(header["NumFrames"]) == F
    np.testing.assert_allclose(frames, np.c_[np.arange(1, F + 1), people["timestamps"]], atol=1e-6)
    got = cells.reshape(F, P, L, 3)
    np.testing.assert_allclose(got, 1e3 * world @ OPENSIM_FROM_WORLD.T, atol=1e-3)
    assert (~live).any() and np.isnan(got[~live]).all()          # the entrant is blank before its birth
    # C3D read back by ezc3d: the same markers, millimetres, Z up
    (c3d,) = export_files(people_run, "c3d", tmp_path / "all.c3d")
    c = ezc3d.c3d(str(c3d))
    assert c["parameters"]["POINT"]["LABELS"]["value"] == want_names
    pts = c["data"]["points"][:3].transpose(2, 1, 0).reshape(F, P, L, 3)
    np.testing.assert_allclose(pts, 1e3 * world, atol=1e-2)
    # the markers a tracker fitted, per person
    (tracker,) = export_files(people_run, "trc", tmp_path / "fitted.trc", markers="tracker")
    assert read_trc_text(tracker)[1][0] == f"p{people['person_ids'][0]}_{people['tracker_landmark_names'][0]}"


def node_world(g, acc, f):
    """World matrix of every node at frame f from the GLB's animation (rotation, translation,
    scale channels), independently of mocap."""
    anim = g.animations[0]
    local = {}
    for i, n in enumerate(g.nodes):
        local[i] = [np.eye(3), np.array(n.translation or [0.0, 0.0, 0.0], float), np.ones(3)]
    for ch in anim.channels:
        val = acc(anim.samplers[ch.sampler].output)[f].astype(np.float64)
        k = {"rotation": 0, "translation": 1, "scale": 2}[ch.target.path]
        local[ch.target.node][k] = Rotation.from_quat(val).as_matrix() if k == 0 else val
    parent = {c: i for i, n in enumerate(g.nodes) for c in (n.children or [])}
    world = {}

    def get(i):
        if i not in world:
            R, t, s = local[i]
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = R * s, t
            world[i] = M if i not in parent else get(parent[i]) @ M
        return world[i]
    return {i: get(i) for i in range(len(g.nodes))}


@pytest.mark.slow
def test_glb_has_a_skinned_body_per_person(people_run, people, tmp_path):
    (out,) = export_files(people_run, "gltf", tmp_path / "all.glb")
    g, acc = glb_accessors(out)
    cols = live_columns(people)
    assert len(g.skins) == len(g.meshes) == len(cols)
    body = motion_body(people_run, want_hash=str(people["model_hash"]))
    F = people["live"].shape[0]
    assert {len(acc(s.input)) for s in g.animations[0].samplers} == {F}
    for k, (pid, p) in enumerate(cols):
        skin = g.skins[k]
        assert g.nodes[skin.joints[0]].name == f"p{pid}_{people['joint_names'][0]}"
        live = people["live"][:, p]
        for f in (int(np.flatnonzero(live)[-1]), int(np.flatnonzero(~live)[0]) if (~live).any() else None):
            if f is None:
                continue
            world = node_world(g, acc, f)
            M = np.stack([world[j] for j in skin.joints])
            if not live[f]:           # not in the scene: its root (and so its body) scaled to nothing
                assert np.abs(M[:, :3, :3]).max() == 0.0
                continue
            joints = M[:, :3, 3]
            want = people["joints"][f, p].astype(np.float64) @ GLTF_FROM_WORLD.T
            assert 1e3 * np.abs(joints - want).max() < 1.0
            prim = g.meshes[k].primitives[0]
            rest = acc(prim.attributes.POSITION).astype(np.float64)
            J = acc(prim.attributes.JOINTS_0).astype(int)
            W = acc(prim.attributes.WEIGHTS_0).astype(np.float64)
            ibm = acc(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
            skinned = np.einsum("vk,vkab,vb->va", W, (M @ ibm)[J], np.c_[rest, np.ones(len(rest))])[:, :3]
            posed = body.shaped(people["alpha"][f, p]).pose(people["chi"][f, p]).vertices[0]
            want = posed.astype(np.float64) @ GLTF_FROM_WORLD.T
            assert 1e3 * np.abs(skinned - want).max() < 10.0      # 4 influences: ~5 mm


def cli(*args):
    return subprocess.run([sys.executable, "-m", "mocap_cli", "export", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def tampered(people_run, tmp_path, **changes):
    """A copy of the run whose motion.npz has ``changes`` (exported with --accept-unverified)."""
    run = tmp_path / "run"
    shutil.copytree(people_run, run)
    with np.load(run / "motion.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update(changes)
    np.savez_compressed(run / "motion.npz", **arrays)
    return run


@pytest.mark.slow
def test_bad_people_files_are_refused_in_one_line(people_run, people, tmp_path):
    P = len(people["person_ids"])
    escaping = tampered(people_run, tmp_path, person_ids=np.array(["../../evil"] * P))
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(MotionFileError, match="field 'person_ids' must be"):
        export_files(escaping, "bvh", out / "m.bvh", require_manifest=False)
    r = cli(escaping, "--format", "bvh", "--out", out / "m.bvh", "--accept-unverified")
    assert r.returncode == 2 and "field 'person_ids' must be" in r.stderr and "Traceback" not in r.stderr
    shutil.rmtree(escaping)
    twice = tampered(people_run, tmp_path, person_ids=np.zeros(P, np.int64))
    with pytest.raises(MotionFileError, match="distinct non-negative"):
        export_files(twice, "trc", out / "m.trc", require_manifest=False)
    shutil.rmtree(twice)
    r = cli(people_run, "--format", "bvh", "--out", out / "m.bvh", "--person", "99")
    assert r.returncode == 2 and "no person 99 (the run's people: " in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    never = tampered(people_run, tmp_path, live=np.zeros_like(people["live"]))
    with pytest.raises(MotionFileError, match="has no frame with an estimate"):
        export_files(never, "bvh", out / "m.bvh", require_manifest=False, person=int(people["person_ids"][0]))
    with pytest.raises(ValueError, match="tracked nobody"):
        export_files(never, "bvh", out / "m.bvh", require_manifest=False)
    assert not list(out.iterdir())              # nothing written, not even a temporary file
    # an existing person file is kept unless --overwrite, before any other is written
    pid = int(people["person_ids"][0])
    (out / f"m_p{pid}.bvh").write_text("keep")
    r = cli(people_run, "--format", "bvh", "--out", out / "m.bvh")
    assert r.returncode == 2 and "exists" in r.stderr
    assert sorted(p.name for p in out.iterdir()) == [f"m_p{pid}.bvh"]
    r = cli(people_run, "--format", "bvh", "--out", out / "m.bvh", "--overwrite")
    assert r.returncode == 0 and r.stdout.startswith("wrote ") and str(out / f"m_p{pid}.bvh") in r.stdout

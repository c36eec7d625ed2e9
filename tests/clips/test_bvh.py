"""The BVH reader against bvhio (float32 inside: agreement to ~1e-6 m), against an independent
double-precision reference (scipy's intrinsic Euler angles, joint by joint: 1e-9 m), against a
hand-computed chain, and its errors on bad input."""

from __future__ import annotations

from pathlib import Path

import bvhio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocap.clips import read_bvh
from mocap.clips.bvh import WORLD_FROM_YUP

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real-motion"
CLIP = REAL / "bandai_namco" / "dataset-1" / "dataset-1_bow_active_001.bvh"

# a skeleton no map recognises: mixed channel counts and orders, position channels on a child,
# a joint without channels, end sites
SMALL = """HIERARCHY
ROOT base
{
  OFFSET 1.0 2.0 3.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT upper
  {
    OFFSET 0.0 10.0 0.5
    CHANNELS 3 Xrotation Yrotation Zrotation
    JOINT lower
    {
      OFFSET 2.0 8.0 -1.0
      CHANNELS 4 Yposition Yrotation Zrotation Xrotation
      End Site
      {
        OFFSET 0.0 5.0 0.0
      }
    }
  }
  JOINT side
  {
    OFFSET -3.0 1.0 0.0
    CHANNELS 0
    JOINT tip
    {
      OFFSET 0.0 0.0 4.0
      CHANNELS 1 Zrotation
      End Site
      {
        OFFSET 1.0 0.0 0.0
      }
    }
  }
}
MOTION
Frames: {frames}
Frame Time: 0.04
"""


def small_bvh(tmp_path: Path, frames: int = 5, seed: int = 0, drop_lines: int = 0, name="small.bvh") -> Path:
    rng = np.random.default_rng(seed)
    vals = np.c_[rng.uniform(-20, 20, (frames, 3)), rng.uniform(-170, 170, (frames, 3)),
                 rng.uniform(-170, 170, (frames, 3)), rng.uniform(5, 12, (frames, 1)),
                 rng.uniform(-170, 170, (frames, 3)), rng.uniform(-90, 90, (frames, 1))]
    lines = [" ".join(f"{v:.6f}" for v in row) for row in vals[:frames - drop_lines]]
    p = tmp_path / name
    p.write_text(SMALL.replace("{frames}", str(frames)) + "\n".join(lines) + "\n")
    return p


def reference_positions(path: Path) -> tuple[list[str], np.ndarray]:
    """Joint world positions (F, J, 3) in file units and axes, joint by joint with scipy."""
    tok = path.read_text().split()
    names, parents, offsets, chans, stack = [], [], [], [], []
    i = 0
    while tok[i] != "MOTION":
        if tok[i] in ("ROOT", "JOINT"):
            names.append(tok[i + 1])
            parents.append(stack[-1] if stack else -1)
            offsets.append([float(t) for t in tok[i + 4:i + 7]])
            n = int(tok[i + 8])
            chans.append(tok[i + 9:i + 9 + n])
            stack.append(len(names) - 1)
            i += 9 + n
        elif tok[i] == "End":
            stack.append(-1)
            i += 7
        elif tok[i] == "}":
            stack.pop()
            i += 1
        else:
            i += 1
    frames = int(tok[i + 2])
    data = np.array(tok[i + 6:], float).reshape(frames, -1)
    out = np.zeros((frames, len(names), 3))
    for f in range(frames):
        col, world = 0, []
        for j, cs in enumerate(chans):
            t = np.array(offsets[j])
            axes, ang = "", []
            for c in cs:
                if c.endswith("position"):
                    t["XYZ".index(c[0])] = data[f, col]
                else:
                    axes += c[0]
                    ang.append(data[f, col])
                col += 1
            R = Rotation.from_euler(axes, ang, degrees=True).as_matrix() if axes else np.eye(3)
            if parents[j] < 0:
                world.append((R, t))
            else:
                Rp, tp = world[parents[j]]
                world.append((Rp @ R, tp + Rp @ t))
            out[f, j] = world[j][1]
    return names, out


def bvhio_positions(path: Path, frames) -> np.ndarray:
    root = bvhio.readAsHierarchy(str(path))
    out = []
    for f in frames:
        root.loadPose(f)
        out.append([list(j.PositionWorld) for j, _, _ in root.layout()])
    return np.array(out, np.float64)


@pytest.mark.skipif(not CLIP.is_file(), reason="../shared/data/real-motion is not here")
def test_real_clip_equals_bvhio_and_reference():
    clip = read_bvh(CLIP)
    assert clip.name_map == "bandai_namco" and clip.fps == 30.0 and clip.scale == 0.01
    assert clip.positions.shape == (128, 22, 3)
    names, ref = reference_positions(CLIP)
    assert clip.names == tuple(names)
    ours_file = (clip.positions @ WORLD_FROM_YUP) / 0.01          # back to file units and axes
    np.testing.assert_allclose(ours_file, ref, atol=1e-9, rtol=0)
    frames = [0, 37, 127]
    theirs = bvhio_positions(CLIP, frames) * 0.01 @ WORLD_FROM_YUP.T
    # bvhio computes in float32 (PyGLM vec3/quat): agreement to float32 rounding
    np.testing.assert_allclose(clip.positions[frames], theirs, atol=5e-6, rtol=0)
    # standing: head ~1.4 m above the floor, z up
    assert 1.3 < clip.joint("Head")[0, 2] < 1.5 and 0.85 < clip.joint("Hips")[0, 2] < 0.97


def test_small_file_equals_bvhio_and_reference(tmp_path):
    p = small_bvh(tmp_path, frames=6)
    clip = read_bvh(p, unit="m", up="z")
    assert clip.names == ("base", "upper", "lower", "side", "tip") and clip.fps == 25.0
    assert list(clip.parents) == [-1, 0, 1, 0, 3]
    _, ref = reference_positions(p)
    np.testing.assert_allclose(clip.positions, ref, atol=1e-9, rtol=0)
    np.testing.assert_allclose(clip.positions, bvhio_positions(p, range(6)), atol=5e-5, rtol=0)
    # end sites ride their joints
    ends = clip.end_sites
    assert ends.shape == (6, 2, 3) and list(clip.end_site_parents) == [2, 4]
    R = clip.world_rotations[:, 4]
    np.testing.assert_allclose(ends[:, 1], clip.positions[:, 4] + R @ [1.0, 0.0, 0.0], atol=1e-12)


def test_two_joint_chain_by_hand(tmp_path):
    """Root at (1, 0, 0) turned 90 deg about Z; child 2 along x turned 90 deg about X; tip 3
    along y. Root turns the child's offset to (0, 2, 0): child at (1, 2, 0). The child's frame
    is Rz(90) Rx(90): its y axis goes to Rz(90) (0, 0, 1) = (0, 0, 1): end site at (1, 2, 3)."""
    p = tmp_path / "chain.bvh"
    p.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition "
                 "Zrotation Xrotation Yrotation\n JOINT b\n {\n  OFFSET 2 0 0\n  CHANNELS 3 Zrotation "
                 "Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 3 0\n  }\n }\n}\nMOTION\nFrames: 2\n"
                 "Frame Time: 0.5\n1 0 0 90 0 0 0 90 0\n0 0 0 0 0 0 0 0 0\n")
    clip = read_bvh(p, unit="m", up="z")
    np.testing.assert_allclose(clip.positions[0], [[1, 0, 0], [1, 2, 0]], atol=1e-12)
    np.testing.assert_allclose(clip.end_sites[0, 0], [1, 2, 3], atol=1e-12)
    np.testing.assert_allclose(clip.positions[1], [[0, 0, 0], [2, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(clip.end_sites[1, 0], [2, 3, 0], atol=1e-12)
    assert clip.fps == 2.0


def test_units_and_up_axis(tmp_path):
    p = small_bvh(tmp_path)
    metres = read_bvh(p, unit="m", up="z").positions
    for unit, k in (("cm", 0.01), ("mm", 0.001), ("inch", 0.0254)):
        np.testing.assert_allclose(read_bvh(p, unit=unit, up="z").positions, k * metres, atol=1e-12)
    yup = read_bvh(p, unit="m", up="y")
    # Y up -> Z up: (x, y, z) -> (x, -z, y), a proper rotation
    np.testing.assert_allclose(yup.positions[..., 0], metres[..., 0], atol=1e-12)
    np.testing.assert_allclose(yup.positions[..., 1], -metres[..., 2], atol=1e-12)
    np.testing.assert_allclose(yup.positions[..., 2], metres[..., 1], atol=1e-12)
    assert np.isclose(np.linalg.det(WORLD_FROM_YUP), 1.0)
    # local rotations and offsets are expressed in the new axes: FK on them gives the positions
    from mocap.clips.bvh import forward_kinematics
    P, _ = forward_kinematics(yup.parents, yup.translations, yup.rotations)
    np.testing.assert_allclose(P, yup.positions, atol=1e-12)


def test_frames_slice(tmp_path):
    p = small_bvh(tmp_path, frames=10)
    full = read_bvh(p, unit="m", up="z")
    part = read_bvh(p, unit="m", up="z", frames=slice(2, 9, 3))
    assert list(part.frame_index) == [2, 5, 8]
    np.testing.assert_allclose(part.positions, full.positions[[2, 5, 8]], atol=0)
    with pytest.raises(ValueError, match=r"small.bvh: has 10 frames.*slice\(0, 10\)"):
        read_bvh(p, unit="m", up="z", frames=slice(0, 20))


def test_cmu_names_are_recognised(tmp_path):
    """A synthetic BVH with the CMU (cgspeed) names: the cmu map gives unit and up."""
    names = ["Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "RHipJoint", "RightUpLeg",
             "RightLeg", "RightFoot", "LowerBack", "Spine", "Spine1", "Neck", "Head", "LeftShoulder",
             "LeftArm", "LeftForeArm", "LeftHand", "RightShoulder", "RightArm", "RightForeArm", "RightHand"]
    body = "".join(f"JOINT {n}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n}}\n"
                   for n in names[1:])
    p = tmp_path / "cmu.bvh"
    p.write_text("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition "
                 f"Zrotation Xrotation Yrotation\n{body}}}\nMOTION\nFrames: 1\nFrame Time: 0.008333\n"
                 + " ".join(["0", "17.0", "0"] + ["0"] * (3 + 3 * (len(names) - 1))) + "\n")
    clip = read_bvh(p)
    assert clip.name_map == "cmu" and np.isclose(clip.scale, 0.0254 / 0.45)
    np.testing.assert_allclose(clip.joint("Hips")[0], [0, 0, 17.0 * 0.0254 / 0.45], atol=1e-12)
    np.testing.assert_allclose(clip.joint("LeftUpLeg")[0], [0, 0, 18.0 * 0.0254 / 0.45], atol=1e-12)
    assert abs(clip.fps - 120.0) < 0.01


# -- bad input ---------------------------------------------------------------------------------

def test_unknown_skeleton_needs_unit_and_up(tmp_path):
    p = small_bvh(tmp_path)
    with pytest.raises(ValueError, match=r"small.bvh: skeleton not recognised.*pass unit= and up=.*clips.md"):
        read_bvh(p)
    with pytest.raises(ValueError, match=r"small.bvh: .*pass up="):
        read_bvh(p, unit="cm")
    with pytest.raises(ValueError, match=r"unit='feet' for .*small.bvh: allowed m, cm, mm, inch"):
        read_bvh(p, unit="feet", up="y")


def test_truncated_files(tmp_path):
    p = small_bvh(tmp_path, frames=5, drop_lines=2)
    with pytest.raises(ValueError, match=r"small.bvh: 'Frames: 5' but only 3 frame lines: the file is trunc"):
        read_bvh(p, unit="m", up="z")
    # a short last line (the file cut mid-line)
    q = small_bvh(tmp_path, frames=5, name="cut.bvh")
    q.write_text(q.read_text().rstrip().rsplit(" ", 4)[0] + "\n")
    with pytest.raises(ValueError, match=r"cut.bvh: frame 4 has 10 values, the hierarchy declares 14"):
        read_bvh(q, unit="m", up="z")
    # cut inside the hierarchy
    r = tmp_path / "head.bvh"
    r.write_text(SMALL[:200])
    with pytest.raises(ValueError, match=r"head.bvh: .*truncated"):
        read_bvh(r, unit="m", up="z")


def test_empty_file_unknown_channel_missing_file(tmp_path):
    e = tmp_path / "empty.bvh"
    e.write_text("")
    with pytest.raises(ValueError, match=r"empty.bvh: is empty"):
        read_bvh(e, unit="m", up="z")
    u = tmp_path / "chan.bvh"
    u.write_text(small_bvh(tmp_path).read_text().replace("CHANNELS 1 Zrotation", "CHANNELS 1 Wrotation"))
    with pytest.raises(ValueError, match=r"chan.bvh: joint 'tip': unknown channel\(s\) Wrotation"):
        read_bvh(u, unit="m", up="z")
    with pytest.raises(ValueError, match=r"nothere.bvh does not exist"):
        read_bvh(tmp_path / "nothere.bvh", unit="m", up="z")

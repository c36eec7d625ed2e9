"""A BVH reader: world joint positions per frame by forward kinematics, vectorised over frames.

Format (Biovision hierarchy): ``HIERARCHY`` then ``ROOT``/``JOINT`` blocks, each with an
``OFFSET`` (the joint's position in its parent's frame at rest) and ``CHANNELS n ...`` (any
count and order of ``Xposition Yposition Zposition Xrotation Yrotation Zrotation``), ``End
Site`` blocks (an offset only), then ``MOTION``, ``Frames: F``, ``Frame Time: dt`` and F lines
of channel values in the order the channels are declared, depth first.

Conventions (those of the format's common readers, ``bvhio`` among them):
- A joint's translation in its parent's frame is its OFFSET, where a position channel, if
  present, REPLACES the offset's component (Bandai Namco's files give every joint position
  channels equal to its offset).
- Rotation channels are intrinsic Euler angles in degrees, applied in the declared order:
  channels ``Zrotation Xrotation Yrotation`` give ``R = Rz(z) @ Rx(x) @ Ry(y)``.
- ``world_R[j] = world_R[parent] @ R[j]``, ``world_p[j] = world_p[parent] + world_R[parent] @ t[j]``.

Units and axes: positions come out in METRES in mocap's world frame (Z up, right-handed).
``unit`` scales the file's numbers (``cm``, ``m``, ``mm``, ``inch``); a name map (see
:mod:`mocap.clips.names`) may give a skeleton's scale as metres per file unit instead (CMU).
``up="y"``: a Y-up file is turned into Z-up by the proper rotation
``(x, y, z) -> (x, -z, y)`` (``WORLD_FROM_YUP``, the inverse of the exporter's
:data:`mocap.export.axes.BVH_FROM_WORLD`, so a BVH written by ``mocap export`` reads back in
place); ``up="z"`` keeps the axes. When ``unit``/``up`` are not given they come from the name
map that recognises the skeleton; a skeleton no map recognises needs both options.

Offsets and local rotations of the returned :class:`Clip` are expressed in the mocap frame
too (``C @ offset``, ``C @ R @ C.T``), so forward kinematics on them reproduces ``positions``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocap.export.axes import BVH_FROM_WORLD

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254}
UPS = ("y", "z")
WORLD_FROM_YUP = BVH_FROM_WORLD.T.copy()      # (x, y, z) -> (x, -z, y), det +1
_CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")


@dataclass(frozen=True)
class Clip:
    """A motion-capture clip (F frames, J joints, E end sites; metres, mocap's frame, Z up).

    ``rotations`` (F, J, 3, 3) are the joints' local rotations (relative to the parent's frame),
    ``world_rotations`` (F, J, 3, 3) their products along the chain; ``offsets`` (J, 3) the rest
    offsets of the hierarchy and ``translations`` (F, J, 3) the per-frame translations (the
    offsets with position channels applied). ``end_sites`` (F, E, 3) world points of the end
    sites, ``end_site_parents`` (E,) their joints. ``frame_index`` (F,) the file's frame numbers
    kept (after ``frames=``), ``times`` (F,) their times in seconds. ``scale``: metres per file
    unit; ``up``: the file's up axis. ``name_map``: the name of the map that recognised the
    skeleton ("" if none)."""

    path: Path
    names: tuple[str, ...]
    parents: np.ndarray
    fps: float
    positions: np.ndarray
    offsets: np.ndarray
    translations: np.ndarray
    rotations: np.ndarray
    world_rotations: np.ndarray
    end_sites: np.ndarray
    end_site_parents: np.ndarray
    frame_index: np.ndarray
    scale: float
    up: str
    name_map: str = ""
    channels: tuple[tuple[str, ...], ...] = field(default=())
    times: np.ndarray | None = None          # (F,) seconds from the file's first frame

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])

    def joint(self, name: str) -> np.ndarray:
        """(F, 3) world positions of the joint called ``name``."""
        if name not in self.names:
            raise KeyError(f"{self.path.name}: no joint {name!r} (joints: {', '.join(self.names)})")
        return self.positions[:, self.names.index(name)]


@dataclass(frozen=True)
class _Hierarchy:
    names: list[str]
    parents: list[int]
    offsets: np.ndarray          # (J, 3) file units, file axes
    channels: list[tuple[str, ...]]
    end_parents: list[int]
    end_offsets: np.ndarray      # (E, 3)
    frames: int
    frame_time: float
    motion: list[str]            # the frame lines (stripped, non-empty)


def _fail(path: Path, what: str) -> ValueError:
    return ValueError(f"BVH file {path}: {what}")


def _parse(path: Path) -> _Hierarchy:
    try:
        text = path.read_text(errors="replace")
    except OSError as e:
        raise _fail(path, f"cannot be read ({e.strerror})") from None
    head, sep, motion = text.partition("MOTION")
    tok = head.split()
    if not tok:
        raise _fail(path, "is empty; expected a BVH file starting with HIERARCHY")
    if tok[0] != "HIERARCHY":
        raise _fail(path, f"starts with {tok[0][:30]!r}, not HIERARCHY: not a BVH file")
    if not sep:
        raise _fail(path, "has no MOTION section: the file is truncated (or not a BVH file)")
    names, parents, offsets, channels = [], [], [], []
    end_parents, end_offsets = [], []
    stack: list[int] = []          # joint indices of the open blocks (-2: an end site)
    i, n = 1, len(tok)

    def floats(k: int, what: str) -> list[float]:
        try:
            return [float(t) for t in tok[k:k + 3]] if k + 3 <= n else _bad(what)
        except ValueError:
            return _bad(what)

    def _bad(what: str):
        raise _fail(path, f"malformed {what}")

    while i < n:
        t = tok[i]
        if t in ("ROOT", "JOINT"):
            if i + 1 >= n:
                raise _fail(path, f"{t} without a name")
            if t == "ROOT" and stack:
                raise _fail(path, "ROOT inside another joint")
            if t == "JOINT" and not stack:
                raise _fail(path, f"JOINT {tok[i + 1]} outside the ROOT")
            name = tok[i + 1]
            if name in names:
                raise _fail(path, f"joint {name!r} declared twice")
            if i + 2 >= n or tok[i + 2] != "{" or i + 3 >= n or tok[i + 3] != "OFFSET":
                raise _fail(path, f"joint {name!r}: expected '{{ OFFSET x y z'")
            off = floats(i + 4, f"OFFSET of joint {name!r}")
            i += 7
            chans: tuple[str, ...] = ()
            if i < n and tok[i] == "CHANNELS":
                try:
                    c = int(tok[i + 1])
                except (ValueError, IndexError):
                    raise _fail(path, f"joint {name!r}: CHANNELS needs a count") from None
                chans = tuple(tok[i + 2:i + 2 + c])
                bad = [ch for ch in chans if ch not in _CHANNELS]
                if len(chans) != c or bad:
                    raise _fail(path, f"joint {name!r}: unknown channel(s) {', '.join(bad) or '(missing)'}; "
                                      f"allowed: {', '.join(_CHANNELS)}")
                if len(set(chans)) != len(chans):
                    raise _fail(path, f"joint {name!r}: a channel is repeated ({' '.join(chans)})")
                i += 2 + c
            parents.append(stack[-1] if stack else -1)
            names.append(name)
            offsets.append(off)
            channels.append(chans)
            stack.append(len(names) - 1)
        elif t == "End":
            if not stack or stack[-1] < 0:
                raise _fail(path, "End Site outside a joint")
            if tok[i + 1:i + 4] != ["Site", "{", "OFFSET"]:
                raise _fail(path, "End Site: expected 'End Site { OFFSET x y z }'")
            end_offsets.append(floats(i + 4, "End Site OFFSET"))
            end_parents.append(stack[-1])
            stack.append(-2)
            i += 7
        elif t == "}":
            if not stack:
                raise _fail(path, "unbalanced '}' in the hierarchy")
            stack.pop()
            i += 1
        else:
            raise _fail(path, f"unexpected {t[:30]!r} in the hierarchy")
    if stack:
        raise _fail(path, "the hierarchy ends inside a joint (missing '}'): the file is truncated")
    if not names:
        raise _fail(path, "declares no joints")
    lines = [ln.strip() for ln in motion.splitlines()]
    lines = [ln for ln in lines if ln]
    if len(lines) < 2 or not lines[0].startswith("Frames:") or not lines[1].startswith("Frame Time:"):
        raise _fail(path, "MOTION must be followed by 'Frames: F' and 'Frame Time: dt' lines")
    try:
        frames = int(lines[0].split()[1])
        frame_time = float(lines[1].split()[2])
    except (ValueError, IndexError):
        raise _fail(path, "malformed 'Frames:' or 'Frame Time:' line") from None
    if frames < 0 or not 0 < frame_time < float("inf"):
        raise _fail(path, f"Frames: {frames}, Frame Time: {frame_time}: need Frames >= 0 and Frame Time > 0")
    return _Hierarchy(names, parents, np.asarray(offsets, np.float64).reshape(-1, 3), channels,
                      end_parents, np.asarray(end_offsets, np.float64).reshape(-1, 3), frames,
                      frame_time, lines[2:])


def euler_matrices(angles_deg: np.ndarray, axes: str) -> np.ndarray:
    """Intrinsic Euler angles (..., n) in degrees about ``axes`` (e.g. "ZXY", applied in that
    order: ``R = R_Z @ R_X @ R_Y``) -> rotation matrices (..., 3, 3)."""
    a = np.deg2rad(np.asarray(angles_deg, np.float64))
    R = np.broadcast_to(np.eye(3), a.shape[:-1] + (3, 3)).copy()
    for k, ax in enumerate(axes):
        c, s = np.cos(a[..., k]), np.sin(a[..., k])
        M = np.zeros(a.shape[:-1] + (3, 3))
        i = "XYZ".index(ax)
        j, k2 = (i + 1) % 3, (i + 2) % 3
        M[..., i, i] = 1.0
        M[..., j, j], M[..., j, k2], M[..., k2, j], M[..., k2, k2] = c, -s, s, c
        R = R @ M
    return R


def forward_kinematics(parents: np.ndarray, translations: np.ndarray,
                       rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """parents (J,) (each after its parent), translations (F, J, 3), local rotations
    (F, J, 3, 3) -> world positions (F, J, 3) and world rotations (F, J, 3, 3)."""
    F, J = translations.shape[:2]
    P = np.empty((F, J, 3))
    W = np.empty((F, J, 3, 3))
    for j in range(J):
        p = parents[j]
        if p < 0:
            W[:, j] = rotations[:, j]
            P[:, j] = translations[:, j]
        else:
            W[:, j] = W[:, p] @ rotations[:, j]
            P[:, j] = P[:, p] + (W[:, p] @ translations[:, j, :, None])[..., 0]
    return P, W


def _frame_values(path: Path, h: _Hierarchy, width: int, sel: np.ndarray) -> np.ndarray:
    if len(h.motion) < h.frames:
        raise _fail(path, f"'Frames: {h.frames}' but only {len(h.motion)} frame lines: the file is "
                          f"truncated (re-export it, or read the first frames with frames=slice(0, "
                          f"{len(h.motion)}))")
    if len(h.motion) > h.frames:
        raise _fail(path, f"'Frames: {h.frames}' but {len(h.motion)} frame lines: fix the Frames: line")
    rows = [h.motion[f].split() for f in sel]
    short = [int(f) for f, r in zip(sel, rows, strict=True) if len(r) != width]
    if short:
        f = short[0]
        got = len(rows[list(sel).index(f)])
        raise _fail(path, f"frame {f} has {got} values, the hierarchy declares {width} channels "
                          f"({len(short)} such frame line(s)): the file is truncated or corrupt")
    try:
        return np.asarray(rows, np.float64).reshape(len(sel), width)
    except ValueError:
        raise _fail(path, "a frame line holds a value that is not a number") from None


def _refuse_nonfinite(path: Path, h: _Hierarchy, values: np.ndarray, sel: np.ndarray) -> None:
    """NaN / Inf in an OFFSET or a frame's channel value: refused, naming the joint (and frame)."""
    for offsets, names in ((h.offsets, h.names), (h.end_offsets, [f"End Site of {h.names[p]}"
                                                                   for p in h.end_parents])):
        bad = ~np.isfinite(offsets).all(axis=1)
        if bad.any():
            raise _fail(path, f"{names[int(np.flatnonzero(bad)[0])]!r}: OFFSET is not finite")
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        columns = [(name, ch) for name, chans in zip(h.names, h.channels, strict=True) for ch in chans]
        joint, channel = columns[c]
        raise _fail(path, f"frame {int(sel[r])}: joint {joint!r} channel {channel} is {values[r, c]} "
                          f"({int(bad.any(axis=1).sum())} frame(s) hold NaN/Inf): refused")


def _frame_selection(path: Path, total: int, frames: slice | None) -> np.ndarray:
    if frames is None:
        return np.arange(total)
    if not isinstance(frames, slice):
        raise ValueError(f"frames={frames!r}: pass a slice, e.g. slice(0, 100)")
    start, stop, step = frames.start or 0, frames.stop, frames.step or 1
    if step <= 0 or start < 0 or (stop is not None and stop < 0):
        raise ValueError(f"frames={frames!r}: use non-negative start/stop and a positive step")
    if start >= total or (stop is not None and stop > total):
        last = (stop if stop is not None else start + 1) - 1
        raise _fail(path, f"has {total} frames, but frames={frames!r} asks for frames up to {last}: "
                          f"ask for at most slice(0, {total})")
    return np.arange(total)[frames]


def read_bvh(path: str | Path, *, unit: str | None = None, up: str | None = None,
             frames: slice | None = None) -> Clip:
    """Read a BVH file into a :class:`Clip` (world joint positions in metres, Z up).

    ``unit``: one of :data:`UNITS` (the file's length unit); ``up``: "y" or "z" (the file's up
    axis). None: taken from the name map that recognises the skeleton (:mod:`mocap.clips.names`);
    a skeleton no map recognises must be given both. ``frames``: a slice of the file's frames
    (e.g. ``slice(0, 300, 2)``); asking for frames beyond the clip's end is an error."""
    from mocap.clips.names import detect_map

    path = Path(path)
    if unit is not None and unit not in UNITS:
        raise ValueError(f"unit={unit!r} for {path}: allowed {', '.join(UNITS)}")
    if up is not None and up not in UPS:
        raise ValueError(f"up={up!r} for {path}: allowed {', '.join(UPS)}")
    if not path.is_file():
        raise ValueError(f"BVH file {path} does not exist")
    h = _parse(path)
    name_map = detect_map(h.names)
    if unit is None or up is None:
        if name_map is None:
            missing = " and ".join(f"{k}=" for k, v in (("unit", unit), ("up", up)) if v is None)
            raise _fail(path, "skeleton not recognised by any name map "
                              f"(joints {', '.join(h.names[:6])}, ...): "
                              f"pass {missing} (unit one of {', '.join(UNITS)}; up 'y' or 'z'), or add a "
                              "name map to mocap/clips/maps/ (see docs/clips.md)")
    scale = UNITS[unit] if unit is not None else name_map.metres_per_unit
    up = up if up is not None else name_map.up
    if len(h.motion) != h.frames:           # before anything is sized by the Frames: line
        _frame_values(path, h, 0, np.arange(0))
    sel = _frame_selection(path, h.frames, frames)
    width = sum(len(c) for c in h.channels)
    values = _frame_values(path, h, width, sel)
    _refuse_nonfinite(path, h, values, sel)

    F, J = len(sel), len(h.names)
    trans = np.broadcast_to(h.offsets, (F, J, 3)).copy()
    rots = np.broadcast_to(np.eye(3), (F, J, 3, 3)).copy()
    col = 0
    for j, chans in enumerate(h.channels):
        rot_axes, rot_cols = "", []
        for c in chans:
            if c.endswith("position"):
                trans[:, j, "XYZ".index(c[0])] = values[:, col]
            else:
                rot_axes += c[0]
                rot_cols.append(col)
            col += 1
        if rot_axes:
            rots[:, j] = euler_matrices(values[:, rot_cols], rot_axes)
    C = WORLD_FROM_YUP if up == "y" else np.eye(3)
    trans = scale * trans @ C.T
    rots = C @ rots @ C.T
    parents = np.asarray(h.parents, int)
    P, W = forward_kinematics(parents, trans, rots)
    ep = np.asarray(h.end_parents, int)
    ends = P[:, ep] + (W[:, ep] @ (scale * h.end_offsets @ C.T)[None, :, :, None])[..., 0]
    fps = 1.0 / h.frame_time
    fps = float(round(fps)) if abs(fps - round(fps)) < 1e-3 else fps     # 0.0333333 s -> 30 fps
    return Clip(path=path, names=tuple(h.names), parents=parents, fps=fps,
                positions=P, offsets=scale * h.offsets @ C.T, translations=trans, rotations=rots,
                world_rotations=W, end_sites=ends, end_site_parents=ep, frame_index=sel,
                scale=float(scale), up=up, name_map=name_map.name if name_map else "",
                channels=tuple(h.channels), times=sel * h.frame_time)


def resample(clip: Clip, fps: float) -> Clip:
    """The clip at another frame rate: local rotations interpolated by slerp, translations
    linearly, then forward kinematics (bones keep their lengths). Frames at times 0, 1/fps, ...
    up to the clip's last frame; ``frame_index`` then holds the nearest source frame.
    Each joint's local rotation is interpolated on its own (the clip's frames should be close
    enough in time that a joint turns < 180 degrees between them)."""
    from scipy.spatial.transform import Rotation, Slerp

    if not fps > 0:
        raise ValueError(f"fps={fps!r} for {clip.path}: must be positive")
    t_all = clip.times if clip.times is not None else clip.frame_index / clip.fps
    if len(t_all) < 2:
        raise ValueError(f"{clip.path}: {len(t_all)} frame(s), cannot resample")
    t_src = t_all - t_all[0]
    t = np.arange(0.0, t_src[-1] + 1e-9, 1.0 / fps)
    F, J = len(t), len(clip.names)
    rots = np.empty((F, J, 3, 3))
    for j in range(J):
        rots[:, j] = Slerp(t_src, Rotation.from_matrix(clip.rotations[:, j]))(t).as_matrix()
    trans = np.stack([np.stack([np.interp(t, t_src, clip.translations[:, j, c]) for c in range(3)], -1)
                      for j in range(J)], axis=1)
    P, W = forward_kinematics(clip.parents, trans, rots)
    ep = clip.end_site_parents
    local_ends = np.einsum("eji,ej->ei", clip.world_rotations[0, ep],
                           clip.end_sites[0] - clip.positions[0, ep]) if len(ep) else np.zeros((0, 3))
    ends = P[:, ep] + (W[:, ep] @ local_ends[None, :, :, None])[..., 0]
    index = clip.frame_index[np.abs(t_src[None, :] - t[:, None]).argmin(axis=1)]
    return Clip(path=clip.path, names=clip.names, parents=clip.parents, fps=float(fps), positions=P,
                offsets=clip.offsets, translations=trans, rotations=rots, world_rotations=W, end_sites=ends,
                end_site_parents=ep, frame_index=index, scale=clip.scale, up=clip.up,
                name_map=clip.name_map, channels=clip.channels, times=t + t_all[0])

"""Motion-capture clips in: a BVH reader (:mod:`mocap.clips.bvh`), name maps from a clip's
skeleton to our body's points kept as data (:mod:`mocap.clips.names`, ``maps/*.yaml``), and
retargeting onto our body (:mod:`mocap.clips.retarget`). See docs/clips.md."""

from mocap.clips.bvh import Clip, read_bvh
from mocap.clips.names import NameMap, detect_map, load_map

__all__ = ["Clip", "read_bvh", "NameMap", "detect_map", "load_map"]

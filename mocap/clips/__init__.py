"""Motion-capture clips in: a BVH reader (:mod:`mocap.clips.bvh`), name maps from a clip's
skeleton to our body's points kept as data (:mod:`mocap.clips.names`, ``maps/*.yaml``),
retargeting onto our body (:mod:`mocap.clips.retarget`) and a clip written as a run's
``motion.npz`` (:mod:`mocap.clips.motion_in`). See docs/clips.md."""

from mocap.clips.bvh import Clip, read_bvh, resample
from mocap.clips.motion_in import import_motion
from mocap.clips.names import NameMap, detect_map, load_map
from mocap.clips.retarget import Retargeted, retarget, retarget_points

__all__ = ["Clip", "read_bvh", "resample", "NameMap", "detect_map", "load_map", "Retargeted", "retarget",
           "retarget_points", "import_motion"]

"""The motion out: ``motion.npz`` of every run (:mod:`mocap.export.motion`) and its writers to
BVH, TRC, glTF/GLB and C3D (:mod:`mocap.export.bvh`, ...); a run folder is exported by
:func:`mocap.run_folder.export.export_run`."""

#: the export formats and their file suffixes
FORMATS = {"bvh": ".bvh", "trc": ".trc", "gltf": ".glb", "c3d": ".c3d"}

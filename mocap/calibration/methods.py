"""The ways ``mocap calibrate`` places the cameras (``--extrinsics``), apart from the pipeline
(:mod:`mocap.calibration.pipeline`) so that the command's --help and argument errors import none
of the numeric stack."""

#: none: intrinsics only; board: a board seen by several cameras; points: points of known
#: coordinates; people: the people in the scene
EXTRINSICS = ("none", "board", "points", "people")

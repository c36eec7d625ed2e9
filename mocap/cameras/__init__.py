"""Pinhole cameras with OpenCV distortion: projection, rays, Plücker lines, epipolar
geometry, triangulation, synthetic rigs and calibration files.

Conventions: OpenCV camera frame (x right, y down, z forward), world-to-camera
``x_cam = R @ x_world + t``, world z up in metres, pixel centres at integer coordinates.
Everything is batch-first numpy: ``project(rig, points (P, N, 3)) -> (P, C, N, 2)``.
"""

from mocap.cameras.calibration_io import (
    CalibrationError,
    load_calibration,
    read_mocap_calibration,
    read_opencv_calibration,
    read_pose2sim_calibration,
    rig_from_dict,
    rig_to_dict,
    save_calibration,
    write_mocap_calibration,
    write_opencv_calibration,
    write_pose2sim_calibration,
)
from mocap.cameras.camera import (
    Camera,
    InvalidCameraError,
    Rig,
    as_rig,
    rodrigues_from_rotation,
    rotation_from_rodrigues,
    view_rigs,
)
from mocap.cameras.projection import (
    camera_coordinates,
    distort_normalized,
    epipolar_distance,
    fundamental_matrices,
    fundamental_matrix,
    pixel_rays,
    pixels_from_camera,
    plucker_from_rays,
    point_line_distance,
    project,
    triangulate,
    undistort_normalized,
    undistort_points,
)
from mocap.cameras.rigs import (
    intrinsics,
    look_at_camera,
    look_at_rotation,
    rig_from_config,
    ring_rig,
)

__all__ = [
    "CalibrationError",
    "Camera",
    "InvalidCameraError",
    "Rig",
    "as_rig",
    "camera_coordinates",
    "view_rigs",
    "distort_normalized",
    "epipolar_distance",
    "fundamental_matrices",
    "fundamental_matrix",
    "intrinsics",
    "load_calibration",
    "look_at_camera",
    "look_at_rotation",
    "pixel_rays",
    "pixels_from_camera",
    "plucker_from_rays",
    "point_line_distance",
    "project",
    "read_mocap_calibration",
    "read_opencv_calibration",
    "read_pose2sim_calibration",
    "rig_from_config",
    "rig_from_dict",
    "rig_to_dict",
    "ring_rig",
    "rodrigues_from_rotation",
    "rotation_from_rodrigues",
    "save_calibration",
    "triangulate",
    "undistort_normalized",
    "undistort_points",
    "write_mocap_calibration",
    "write_opencv_calibration",
    "write_pose2sim_calibration",
]

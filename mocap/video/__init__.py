"""Video in: lazy decoding of calibrated videos, the built-in 2D detector (keypoints and person
masks), and segmentation into silhouettes.

- :mod:`mocap.video.detector` - MediaPipe BlazePose (optional dependency: requirements-detect.txt)
- :mod:`mocap.video.detect` - ``mocap detect``: videos -> a Pose2Sim-style folder of keypoints + masks
- :mod:`mocap.video.person_masks` - person masks from the detector combined with GrabCut,
  a background model and multi-view carving
- decoding (:class:`VideoFrames`) and the background / GrabCut segmentation
  (:func:`segment_sequence`) are :mod:`mocap.data.video` and :mod:`mocap.data.segmentation`,
  re-exported here (kept in place so that existing imports keep working).
"""

from mocap.data.segmentation import SegmentationResult, iou, segment_sequence
from mocap.data.video import VideoError, VideoFrames, VideoInfo, video_info

__all__ = ["SegmentationResult", "VideoError", "VideoFrames", "VideoInfo", "iou", "segment_sequence",
           "video_info"]

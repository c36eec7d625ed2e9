"""Video in: lazy decoding of calibrated videos, the built-in 2D detector (keypoints and person
masks), and segmentation into silhouettes.

- :mod:`mocap.video.detector` - MediaPipe BlazePose (optional dependency: requirements-detect.txt)
- :mod:`mocap.video.detect` - ``mocap detect``: videos -> a Pose2Sim-style folder of keypoints + masks
- :mod:`mocap.video.people` - several people per view with the one-person detector (``--people``);
  :mod:`mocap.video.people_views` groups them across views for the per-person left/right check
- :mod:`mocap.video.person_masks` - person masks from the detector combined with GrabCut,
  a background model and multi-view carving
- :mod:`mocap.video.frames` - lazy decoding (:class:`VideoFrames`), videos matched to cameras
- :mod:`mocap.video.segmentation` - background / GrabCut segmentation (:func:`segment_sequence`)
- :mod:`mocap.video.sequence` - a recording given as videos + calibration as a ``Sequence``
"""

from mocap.video.frames import VideoError, VideoFrames, VideoInfo, video_info
from mocap.video.segmentation import SegmentationResult, iou, segment_sequence

__all__ = ["SegmentationResult", "VideoError", "VideoFrames", "VideoInfo", "iou", "segment_sequence",
           "video_info"]

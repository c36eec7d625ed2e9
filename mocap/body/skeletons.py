"""Skeleton and keypoint vocabularies: the names each layout gives its points and the point of
the body each one stands for (a joint of the body model, or a landmark of the catalogue,
:mod:`mocap.body.catalogue`).

- :data:`LAYOUTS`: 2D keypoint layouts of detectors (OpenPose BODY_25 / BODY_25B / COCO,
  MS-COCO, Halpe-26, MediaPipe BlazePose), keypoint index -> body point; :data:`LAYOUT_BONES`
  the short bones that tell a layout read with the wrong labels.
- :data:`SKELETONS`: ground-truth skeletons (HumanEva-15, Shelf/Campus-14, MS-COCO-17, OpenPose
  BODY_25), their joint names -> body point; :func:`resolve_mapping` checks a ground truth's
  names against one of them or against the body's own names.
- the body's own names: its joints (:attr:`mocap.body.model.BodyModel.joint_names`) and
  landmarks (:data:`mocap.body.catalogue.CATALOGUE`); motion-capture clip skeletons are
  mapped onto them by the YAML name maps of ``mocap/clips/maps`` (:mod:`mocap.clips.names`).

BODY_25's ``Neck`` (index 1) is ``neck_base``, the base of the neck between the clavicles,
in both tables; ``neck`` is our neck joint (BODY_25B's upper neck).
"""

from __future__ import annotations

from collections.abc import Sequence

#: Keypoint layouts: keypoint index -> landmark name of the catalogue
#: (mocap/body/catalogue.py); None: a keypoint the tracker does not use.
#:
#: ============  ====  ========================================================================
#: layout        K     detector / notes
#: ============  ====  ========================================================================
#: BODY_25B      25    OpenPose BODY_25B (Pose2Sim default): COCO order, then upper neck,
#:                     head top, big toe, small toe, heel (left then right)
#: BODY_25       25    OpenPose BODY_25: nose, neck (base), right arm, left arm, mid-hip, right
#:                     leg, left leg, eyes, ears, feet. Same K as BODY_25B: told apart by
#:                     :func:`mocap.data.openpose.layout_scores`
#: COCO          18    OpenPose COCO-18 (BODY_25 without mid-hip and feet)
#: COCO_17       17    MS-COCO keypoints (MMPose, RTMPose, YOLO-pose, Detectron2)
#: HALPE_26      26    Halpe-26 (AlphaPose, RTMPose body7/halpe): COCO_17 + head top, neck
#:                     (base), mid-hip, big toes, small toes, heels
#: MEDIAPIPE_33  33    MediaPipe / BlazePose: face (eye corners, mouth: unused), arms, hands
#:                     (pinky/index/thumb: unused), legs, heels, foot index (toe)
#: ============  ====  ========================================================================
COCO_17 = ("nose", "l_eye", "r_eye", "l_ear", "r_ear", "l_shoulder", "r_shoulder", "l_elbow",
           "r_elbow", "l_wrist", "r_wrist", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle")
LAYOUTS: dict[str, tuple[str | None, ...]] = {
    "BODY_25B": (*COCO_17, "neck", "head_top", "l_toe", "l_small_toe", "l_heel", "r_toe",
                 "r_small_toe", "r_heel"),
    "BODY_25": ("nose", "neck_base", "r_shoulder", "r_elbow", "r_wrist", "l_shoulder", "l_elbow",
                "l_wrist", "pelvis", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle",
                "r_eye", "l_eye", "r_ear", "l_ear", "l_toe", "l_small_toe", "l_heel", "r_toe",
                "r_small_toe", "r_heel"),
    "COCO": ("nose", "neck_base", "r_shoulder", "r_elbow", "r_wrist", "l_shoulder", "l_elbow",
             "l_wrist", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle", "r_eye",
             "l_eye", "r_ear", "l_ear"),
    "COCO_17": COCO_17,
    "HALPE_26": (*COCO_17, "head_top", "neck_base", "pelvis", "l_toe", "r_toe", "l_small_toe",
                 "r_small_toe", "l_heel", "r_heel"),
    "MEDIAPIPE_33": ("nose", None, "l_eye", None, None, "r_eye", None, "l_ear", "r_ear", None, None,
                     "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
                     None, None, None, None, None, None, "l_hip", "r_hip", "l_knee", "r_knee",
                     "l_ankle", "r_ankle", "l_heel", "r_heel", "l_toe", "r_toe"),
}

#: Pairs of landmarks joined by a short bone; a layout read with the wrong labels joins
#: keypoints across the body (:func:`mocap.data.openpose.layout_scores`).
LAYOUT_BONES: tuple[tuple[str, str], ...] = (
    ("l_shoulder", "l_elbow"), ("l_elbow", "l_wrist"), ("r_shoulder", "r_elbow"), ("r_elbow", "r_wrist"),
    ("l_hip", "l_knee"), ("l_knee", "l_ankle"), ("r_hip", "r_knee"), ("r_knee", "r_ankle"),
    ("l_ankle", "l_heel"), ("r_ankle", "r_heel"), ("l_heel", "l_toe"), ("r_heel", "r_toe"),
    ("nose", "l_eye"), ("nose", "r_eye"), ("l_eye", "l_ear"), ("r_eye", "r_ear"),
    ("l_shoulder", "r_shoulder"), ("l_hip", "r_hip"), ("l_shoulder", "l_hip"), ("r_shoulder", "r_hip"),
)


#: ground-truth skeletons: a skeleton's joint name -> the body's joint or landmark (None: a point
#: the body does not model, left out of the scores)
SKELETONS: dict[str, dict[str, str | None]] = {
    # HumanEva-I/II, the 15 joints of the common evaluation protocol. Its pelvis is the
    # midpoint of the hip joints (ours sits above it), its thorax the base of the neck between
    # the clavicles (our ``thorax`` joint is mid-spine, 0.1-0.15 m lower), its head a point
    # inside the head (ours is the skull base): the centroid of our head part.
    "humaneva15": {"pelvis": "mid_hip", "thorax": "neck_base", "head": "head_centre",
                   "lsho": "l_shoulder", "lelb": "l_elbow", "lwri": "l_wrist",
                   "rsho": "r_shoulder", "relb": "r_elbow", "rwri": "r_wrist",
                   "lhip": "l_hip", "lkne": "l_knee", "lank": "l_ankle",
                   "rhip": "r_hip", "rkne": "r_knee", "rank": "r_ankle"},
    # Shelf / Campus (Belagiannis et al. 2014), 14 joints
    "shelf14": {"Right-Ankle": "r_ankle", "Right-Knee": "r_knee", "Right-Hip": "r_hip",
                "Left-Hip": "l_hip", "Left-Knee": "l_knee", "Left-Ankle": "l_ankle",
                "Right-Wrist": "r_wrist", "Right-Elbow": "r_elbow", "Right-Shoulder": "r_shoulder",
                "Left-Shoulder": "l_shoulder", "Left-Elbow": "l_elbow", "Left-Wrist": "l_wrist",
                "Bottom-Head": "neck", "Top-Head": "head_top"},
    # MS-COCO keypoints, 17
    "coco17": {"nose": None, "left_eye": None, "right_eye": None, "left_ear": None, "right_ear": None,
               "left_shoulder": "l_shoulder", "right_shoulder": "r_shoulder",
               "left_elbow": "l_elbow", "right_elbow": "r_elbow", "left_wrist": "l_wrist",
               "right_wrist": "r_wrist", "left_hip": "l_hip", "right_hip": "r_hip",
               "left_knee": "l_knee", "right_knee": "r_knee", "left_ankle": "l_ankle",
               "right_ankle": "r_ankle"},
    # OpenPose BODY_25; its Neck is the base of the neck between the shoulders, as in LAYOUTS
    "body25": {"Nose": None, "Neck": "neck_base", "RShoulder": "r_shoulder", "RElbow": "r_elbow",
               "RWrist": "r_wrist", "LShoulder": "l_shoulder", "LElbow": "l_elbow",
               "LWrist": "l_wrist", "MidHip": "mid_hip", "RHip": "r_hip", "RKnee": "r_knee",
               "RAnkle": "r_ankle", "LHip": "l_hip", "LKnee": "l_knee", "LAnkle": "l_ankle",
               "REye": None, "LEye": None, "REar": None, "LEar": None, "LBigToe": "l_toe",
               "LSmallToe": None, "LHeel": None, "RBigToe": "r_toe", "RSmallToe": None,
               "RHeel": None},
}


class JointNameError(ValueError):
    """Ground-truth joint names do not match the skeleton they claim to be."""


def resolve_mapping(gt_names: Sequence[str], known: Sequence[str], skeleton: str | None = None,
                    required: Sequence[str] = ()) -> dict[str, str | None]:
    """Ground-truth name -> estimate name. ``skeleton``: a key of :data:`SKELETONS` (the names
    must be exactly that skeleton's, in any order) or None/"" (mocap's own names: every name
    must be one of ``known``, and ``required`` must all be there). Errors name the extra,
    missing or unknown joints."""
    gt_names = list(gt_names)
    dup = sorted({n for n in gt_names if gt_names.count(n) > 1})
    if dup:
        raise JointNameError(f"ground truth names joints more than once: {', '.join(dup)}")
    if skeleton:
        if skeleton not in SKELETONS:
            raise JointNameError(f"unknown skeleton {skeleton!r} (known: {', '.join(SKELETONS)})")
        table = SKELETONS[skeleton]
        extra = [n for n in gt_names if n not in table]
        missing = [n for n in table if n not in gt_names]
        if extra or missing:
            raise JointNameError(
                f"ground truth is not the {skeleton} skeleton: "
                + "; ".join(p for p in (f"unknown joints {', '.join(extra)}" if extra else "",
                                        f"missing joints {', '.join(missing)}" if missing else "") if p))
        mapping = {n: table[n] for n in gt_names}
    else:
        extra = [n for n in gt_names if n not in known]
        missing = [n for n in required if n not in gt_names]
        if extra or missing:
            raise JointNameError(
                "ground-truth joint names do not match the body's: "
                + "; ".join(p for p in (f"unknown joints {', '.join(extra)} (known: {', '.join(known)}; "
                                        f"or name a skeleton: {', '.join(SKELETONS)})" if extra else "",
                                        f"missing joints {', '.join(missing)}" if missing else "") if p))
        mapping = {n: n for n in gt_names}
    absent = [v for v in mapping.values() if v is not None and v not in known]
    if absent:
        raise JointNameError(f"the estimate has no point named {', '.join(absent)}")
    return mapping

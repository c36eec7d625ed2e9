"""Fixtures shared by the marker-likelihood tests."""

import pytest


@pytest.fixture(scope="module")
def false_positive_scene(body64):
    """A synthetic walk on the HumanEva-like rig (4 views) with missed detections and false
    positives (several candidates per landmark and view): (sequence, landmark set, frame 1's
    arranged observation, rig)."""
    from mocap.body.catalogue import make_landmark_set
    from mocap.cameras import rig_from_config
    from mocap.data.generate import make_synthetic
    from mocap.energy.markers import arrange_detections

    rig = rig_from_config("humaneva")
    det = {"enabled": True, "detection_rate": 0.8, "false_positive_rate": 0.5, "noise_px": 2.0,
           "occlusion": False}
    seq = make_synthetic(body64, rig, motion="walk", frames=2, fps=25, seed=1, masks=False, detections=det)
    lms = make_landmark_set(body64, "auto", seq.detections.labels)
    obs = arrange_detections(seq.detections.select(1), lms.names, rig)
    assert obs.num_candidates >= 2                                   # false positives: several candidates
    return seq, lms, obs, rig

"""Landmark kinds: a centroid of a part's vertices, and the catalogue's evaluation points."""

import numpy as np
import pytest

from mocap.body.catalogue import landmarks_with, rest_point_basis
from mocap.body.landmarks import LandmarkSet


def test_centroid_landmark_is_the_mean_of_its_parts_vertices_and_rides_the_joint(body):
    rng = np.random.default_rng(0)
    marks = LandmarkSet(body, [{"name": "head_centre", "joint": "head", "centroid": True}])
    head = body.joint_index("head")
    alpha = rng.normal(size=body.num_shape)
    shaped = body.shaped(alpha)
    expect = shaped.rest_vertices[body.part_labels == head].mean(axis=0)
    np.testing.assert_allclose(marks.rest_points(shaped)[0], expect, atol=1e-6)
    # linear in the shape: the basis reproduces it at another shape
    R0, B = rest_point_basis(body, marks)
    np.testing.assert_allclose(R0[0] + np.einsum("k,kc->c", alpha, B[:, 0]), expect, atol=1e-5)
    # posed: the head joint's rigid transform applied to the rest centroid
    chi = 0.3 * rng.normal(size=(2, body.num_dofs))
    out = shaped.pose(chi)
    G = out.transforms[:, head].astype(np.float64)
    np.testing.assert_allclose(marks.positions(shaped, chi)[:, 0],
                               (G[:, :3, :3] @ expect + G[:, :3, 3]), atol=1e-5)
    with pytest.raises(ValueError, match="needs"):
        LandmarkSet(body, [{"name": "x", "joint": "head"}])


def test_evaluation_points_join_the_default_set_only_when_named(body):
    default = LandmarkSet(body).names
    assert landmarks_with(body, ["l_knee", "unknown", None]).names == default
    marks = landmarks_with(body, ["neck_base", "head_centre", "head_top", "l_knee"])
    assert marks.names == (*default, "neck_base", "head_centre")
    shaped = body.shaped(np.zeros(body.num_shape))
    chi = np.zeros((1, body.num_dofs))
    p = dict(zip(marks.names, marks.positions(shaped, chi)[0], strict=True))
    J = shaped.joints(chi)[0]
    # the base of the neck is between the clavicles, above our mid-spine thorax joint
    np.testing.assert_allclose(p["neck_base"], J[[body.joint_index("l_clavicle"),
                                                  body.joint_index("r_clavicle")]].mean(axis=0), atol=1e-6)
    assert p["neck_base"][2] > J[body.joint_index("thorax"), 2] + 0.05
    # the centre of the head is above the skull base and below the top of the head
    assert J[body.joint_index("head"), 2] < p["head_centre"][2] < p["head_top"][2]

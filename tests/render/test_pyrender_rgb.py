"""RGB rendering with pyrender (EGL): skipped cleanly where no EGL/OpenGL is available."""

import numpy as np
import pytest

from mocap.cameras import project, ring_rig
from mocap.render import rasterize_silhouettes


@pytest.fixture(scope="module")
def renderer():
    try:
        from mocap.render.pyrender_rgb import RGBRenderer

        r = RGBRenderer(500, 500)
    except Exception as exc:  # no EGL, no pyrender: nothing to test here
        pytest.skip(f"pyrender/EGL unavailable: {exc}")
    yield r
    r.close()


def test_rasterizer_matches_pyrender_depth_mask(renderer, body):
    from mocap.render.pyrender_rgb import RenderMesh, body_texture

    rig = ring_rig(4, 3.5, 1.5, 500, 500, fov_deg=45, look_at=(0, 0, 0.9))
    chi = body.zero_pose()
    chi[body.dof_index("l_shoulder_flex")] = 0.8
    chi[body.dof_index("r_knee_flex")] = 0.9
    verts = body.shaped().pose(chi).vertices[0]
    colors = body_texture(body.part_labels, body.joint_names)
    px, depth = project(rig, verts, return_depth=True)
    ours = rasterize_silhouettes(px, body.faces, 500, 500, depth)
    for c, cam in enumerate(rig):
        _, gl_depth = renderer.render(cam, [RenderMesh(verts, body.faces, colors)])
        gl = gl_depth > 0
        iou = (gl & ours[c]).sum() / (gl | ours[c]).sum()
        print(f"{cam.name}: IoU {iou:.4f}")
        assert iou >= 0.97, f"{cam.name}: IoU {iou:.4f}"


def test_rendered_body_is_textured_and_placed_where_projected(renderer, body):
    from mocap.render.pyrender_rgb import RenderMesh, body_texture

    cam = ring_rig(1, 3.5, 1.5, 500, 500, fov_deg=45, look_at=(0, 0, 0.9))[0]
    verts = body.shaped().pose(body.zero_pose()).vertices[0]
    img, depth = renderer.render(cam, [RenderMesh(verts, body.faces,
                                                  body_texture(body.part_labels, body.joint_names))])
    assert img.shape == (500, 500, 3) and img.dtype == np.uint8
    fg = depth > 0
    # texture: plenty of local contrast on the body (SIFT needs it)
    assert img[fg].std(axis=0).mean() > 20
    # the rendered depth agrees with the camera-frame depth of the nearest vertices
    px, z = project(cam, verts, return_depth=True)
    u, v = np.round(px).astype(int).T
    assert abs(np.median(depth[fg]) - np.median(z)) < 0.15
    assert fg[v.clip(0, 499), u.clip(0, 499)].mean() > 0.9


def test_distorted_camera_renders_where_the_distorted_projection_lands(renderer, body):
    from mocap.render.pyrender_rgb import RenderMesh, body_texture

    cam = ring_rig(1, 3.0, 1.5, 500, 500, fov_deg=50, look_at=(0, 0, 0.9),
                   dist=(-0.25, 0.08, 0.0, 0.0, 0.0))[0]
    verts = body.shaped().pose(body.zero_pose()).vertices[0]
    _, depth = renderer.render(cam, [RenderMesh(verts, body.faces,
                                                body_texture(body.part_labels, body.joint_names))])
    px, d = project(cam, verts, return_depth=True)
    ours = rasterize_silhouettes(px[None], body.faces, 500, 500, d[None])[0]
    gl = depth > 0
    assert (gl & ours).sum() / (gl | ours).sum() >= 0.95

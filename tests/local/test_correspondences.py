import numpy as np
import pytest
from scipy.spatial import cKDTree

from mocap.cameras import project, ring_rig
from mocap.data.generate import make_synthetic
from mocap.local.contour import ContourMatcher, observed_contours
from mocap.local.misalignment import MisalignmentDetector
from mocap.trackers.local_tracker import LocalTracker
from mocap.trackers.run import frame_of


@pytest.fixture(scope="module")
def walk(body):
    rig = ring_rig(6, 3.5, 1.5, 400, 400, fov_deg=45, look_at=(0, 0, 0.9))
    return rig, make_synthetic(body, rig, motion="walk", frames=3, fps=25, seed=2)


def test_contour_correspondences_lie_on_the_silhouette_contour(body, walk):
    rig, seq = walk
    sb = body.shaped(seq.gt.alpha)
    verts = sb.pose(seq.gt.chi[1]).vertices[0].astype(np.float64)
    obs = observed_contours(seq.masks[1])
    corr, info = ContourMatcher(body, rig)(verts, obs)
    assert min(info["contour_per_view"]) > 100 and len(corr) == sum(info["contour_per_view"])
    start = 0
    for c, cam in enumerate(rig):
        n = info["contour_per_view"][c]
        d, m, X = corr.d[start:start + n], corr.m[start:start + n], corr.points[start:start + n]
        start += n
        # the rays pass through observed contour pixels ...
        on_ray = np.cross(d, m) + 3.0 * d            # the foot of each ray from the origin, moved along it
        ray_px = project(cam, on_ray)
        dist_ray, _ = cKDTree(obs.points[c]).query(ray_px)
        assert np.max(dist_ray) < 1e-6
        # ... and at the true pose the model points project onto the observed outline
        dist_model, _ = cKDTree(obs.points[c]).query(project(cam, X))
        assert np.median(dist_model) < 1.0 and np.percentile(dist_model, 75) < 2.0


def test_misalignment_flags_a_rotated_limb_and_its_children_only(body, walk):
    rig, seq = walk
    sb = body.shaped(seq.gt.alpha)
    det = MisalignmentDetector(body, rig)
    aligned = det(sb.pose(seq.gt.chi[1]).vertices[0], seq.masks[1])
    assert aligned.names == [], aligned.errors
    wrong = seq.gt.chi[1].copy()
    wrong[body.dof_index("l_shoulder_abd")] += np.deg2rad(60)
    check = det(sb.pose(wrong).vertices[0], seq.masks[1])
    assert set(check.names) == {"l_shoulder", "l_elbow", "l_wrist"}
    free = det.free_dofs(check)
    names = {body.dof_names[d] for d in np.flatnonzero(free)}
    assert {"l_shoulder_flex", "l_shoulder_abd", "l_shoulder_rot", "l_elbow_flex"} <= names
    assert not free[:6].any() and "r_knee_flex" not in names


def test_local_tracker_corrects_a_perturbed_start(body, walk):
    rig, seq = walk
    sb = body.shaped(seq.gt.alpha)
    tr = LocalTracker(body, rig, sift={"enabled": False})
    tr.initialize(seq.gt.chi[0], seq.gt.alpha)
    start = seq.gt.chi[1].astype(np.float64).copy()
    start[body.dof_index("r_knee_flex")] += np.deg2rad(15)
    start[body.dof_index("l_shoulder_flex")] -= np.deg2rad(15)
    start[0] += 0.03
    chi, diag = tr.local_step(frame_of(seq, 1), start)
    err = lambda c: np.linalg.norm(sb.joints(c)[0] - seq.gt.joints[1], axis=1).mean()  # noqa: E731
    assert err(chi) < err(start) / 2        # closest-point matching converges gradually
    assert diag.iterations >= 1 and not diag.skipped


def test_view_without_contour_is_reported_and_tracking_goes_on(body, walk):
    rig, seq = walk
    tr = LocalTracker(body, rig, sift={"enabled": False})
    tr.initialize(seq.gt.chi[0], seq.gt.alpha)
    masks = seq.masks[1].copy()
    masks[2] = False
    est = tr.step(type(frame_of(seq, 1))(index=1, masks=masks))
    assert est.diagnostics["views_without_contour"] == [rig.names[2]]
    assert np.all(np.isfinite(est.chi))


def test_no_previous_sift_keypoints_is_reported(body, walk):
    rig, seq = walk
    tr = LocalTracker(body, rig)
    tr.initialize(seq.gt.chi[0], seq.gt.alpha)
    images = np.full(seq.masks[1].shape + (3,), 90, np.uint8)         # textureless
    frame = type(frame_of(seq, 1))(index=1, masks=seq.masks[1], images=images)
    est = tr.step(frame)
    assert "no keypoints from a previous frame" in est.diagnostics["sift"]["note"]
    est2 = tr.step(type(frame)(index=2, masks=seq.masks[2], images=images))
    assert np.all(np.isfinite(est2.chi))
    assert sum(est2.diagnostics["sift"].get("sift_matches_per_view", [0])) == 0


@pytest.fixture(scope="module")
def textured(body):
    rig = ring_rig(4, 3.0, 1.5, 500, 500, fov_deg=45, look_at=(0, 0, 0.9))
    try:
        seq = make_synthetic(body, rig, motion="gestures", frames=2, fps=25, seed=0, images=True)
    except Exception as exc:  # no EGL / pyrender here
        pytest.skip(f"textured rendering unavailable: {exc}")
    return rig, seq


def test_sift_correspondences_map_to_model_points_near_the_true_ones(body, textured):
    from mocap.local.sift import SiftTracker

    rig, seq = textured
    sb = body.shaped(seq.gt.alpha)
    v0 = sb.pose(seq.gt.chi[0]).vertices[0].astype(np.float64)
    v1 = sb.pose(seq.gt.chi[1]).vertices[0].astype(np.float64)
    sift = SiftTracker(body, rig)
    sift.remember(seq.images[0], v0)
    pairs, info = sift.match(seq.images[1], v0)
    assert pairs is not None and sum(info["sift_matches_per_view"]) > 40
    # the model points, posed at the true frame-1 pose, lie close to their matched rays
    X = pairs.correspondences(v1).points
    dist = np.linalg.norm(np.cross(X, pairs.d) - pairs.m, axis=1)
    assert np.median(dist) < 0.01                               # 1 cm


def test_shape_initialisation_is_closer_to_the_truth_than_the_mean_shape(body):
    from mocap.trackers.initialization import initialize_from_silhouettes
    from mocap.trackers.tracker_settings import InitSettings

    rig = ring_rig(8, 3.5, 1.5, 320, 320, fov_deg=45, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="gestures", frames=1, fps=25, seed=5, shape_scale=2.0)
    chi, alpha, diag = initialize_from_silhouettes(
        body, rig, seq.masks[0], np.random.default_rng(0),
        InitSettings(rounds=1, pose_particles=30, pose_layers=6, shape_particles=30, shape_layers=6,
                     hypotheses=0, keep=1))     # one heading (the others: test_initialization_hypotheses)
    true_v, true_j = body.rest(seq.gt.alpha)
    est_v, est_j = body.rest(alpha)
    mean_v, mean_j = body.rest(np.zeros(body.num_shape))
    err = lambda a, b: np.linalg.norm(a - b, axis=1).mean()  # noqa: E731
    assert err(est_v, true_v) < err(mean_v, true_v)
    assert err(est_j, true_j) < err(mean_j, true_j)
    assert np.all(np.isfinite(chi)) and len(diag["heading_energy"]) == 12


@pytest.mark.parametrize("dtype", ["body", "body64"])
def test_compiled_contour_generator_equals_the_numpy_one(dtype, request, monkeypatch):
    """The compiled contour generator (the views' facing signs as bits of a word per face, one
    pass over the edges) gives the numpy path's vertex sets, view for view, on random poses
    and shapes, for a rig's 6 views and for 70 centres (two passes of at most 64)."""
    from mocap.local import contour

    pytest.importorskip("numba")
    b = request.getfixturevalue(dtype)
    rig = ring_rig(6, 3.5, 1.5, 200, 200, fov_deg=50, look_at=(0, 0, 0.9))
    matcher = ContourMatcher(b, rig)
    rng = np.random.default_rng(3)
    for _ in range(6):
        chi = b.zero_pose()
        chi[6:] = rng.normal(0, 0.4, b.num_dofs - 6)
        chi[:3] = rng.normal(0, 0.2, 3)
        chi = np.clip(chi, b.limits[:, 0], b.limits[:, 1]).astype(b.dtype)
        verts = b.shaped(rng.normal(size=b.num_shape)).pose(chi).vertices[0]
        # the rig's centres, and 70 around the body (more than the kernel's 64 views a pass)
        around = rng.normal(0, 1, (70, 3))
        around = 3.5 * around / np.linalg.norm(around, axis=1, keepdims=True) + [0, 0, 0.9]
        for centers in (rig.centers, around):
            compiled = matcher.contour_vertices(verts, centers)
            monkeypatch.setattr(contour, "HAVE_NUMBA", False)
            reference = matcher.contour_vertices(verts, centers)
            monkeypatch.undo()
            assert all(len(a) > 50 for a in compiled)
            for a, r in zip(compiled, reference, strict=True):
                np.testing.assert_array_equal(a, r)


def test_outline_band_on_the_masks_box_is_the_whole_image_computation():
    """The visibility band (outline of the model mask, dilated by the tolerance) taken on the
    mask's grown bounding box = erode / subtract / dilate on the whole image: blobs inside,
    touching each border, with holes, a single pixel, the full image, an empty mask."""
    import cv2

    from mocap.local.contour import outline_band

    k3 = np.ones((3, 3), np.uint8)
    rng = np.random.default_rng(4)
    h, w = 90, 120
    yy, xx = np.ogrid[:h, :w]
    masks = [np.zeros((h, w), bool), np.ones((h, w), bool)]
    one = np.zeros((h, w), bool)
    one[40, 60] = True
    masks.append(one)
    for _ in range(12):
        cy, cx = rng.integers(-10, h + 10), rng.integers(-10, w + 10)
        m = ((yy - cy) / rng.integers(3, 40)) ** 2 + ((xx - cx) / rng.integers(3, 50)) ** 2 < 1
        m &= rng.random((h, w)) > 0.05                                     # holes
        masks.append(m)
    for r in (1, 2, 3):
        kt = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        for m in masks:
            u8 = m.astype(np.uint8)
            want = cv2.dilate(u8 - cv2.erode(u8, k3), kt)
            np.testing.assert_array_equal(outline_band(m, k3, kt), want)
            # a larger box than the mask's (the matcher's, from the projected vertices)
            x, y, bw, bh = cv2.boundingRect(u8)
            box = (max(x - 3, 0), max(y - 5, 0), bw + 9, bh + 7) if bw else (10, 10, 20, 20)
            out = np.zeros((h, w), np.uint8)
            assert outline_band(m, k3, kt, box, out) is out
            np.testing.assert_array_equal(out, want)


def test_compiled_matcher_equals_the_numpy_path(body, walk, monkeypatch):
    """The compiled matcher (visibility and pairing in one pass over the views, observed grids
    and rays once per frame) gives the numpy path's correspondences, bit for bit: at the true
    pose, at poses off by a few degrees (long matches, rejected ones), with one view's
    silhouette empty (no contour) and with a stride on both sides."""
    from mocap.local import contour

    pytest.importorskip("numba")
    rig, seq = walk
    sb = body.shaped(seq.gt.alpha)
    rng = np.random.default_rng(7)
    masks = seq.masks[1].copy()
    masks[2] = False
    for stride, observed_stride, m in ((1, 4, seq.masks[1]), (2, 3, masks)):
        matcher = ContourMatcher(body, rig, stride=stride, observed_stride=observed_stride)
        for k in range(3):
            chi = seq.gt.chi[1].astype(np.float64).copy()
            chi[6:] += rng.normal(0, 0.08 * k, body.num_dofs - 6)
            verts = sb.pose(chi).vertices[0].astype(np.float64)
            got, info = matcher(verts, observed_contours(m))
            monkeypatch.setattr(contour, "HAVE_NUMBA", False)
            want, want_info = matcher(verts, observed_contours(m))
            monkeypatch.undo()
            assert info == want_info and len(got) > 500
            for f in ("points", "limbs", "d", "m", "weights"):
                np.testing.assert_array_equal(getattr(got, f), getattr(want, f))
    assert want_info["views_without_contour"] == [rig.names[2]]


def test_observed_lines_are_the_rays_of_the_contour_pixels(body, walk):
    """The Plücker lines back-projected once per frame for all views are each view's
    pixel_rays + plucker_from_rays of its contour pixels (views one after the other)."""
    from mocap.cameras import pixel_rays, plucker_from_rays

    rig, seq = walk
    obs = observed_contours(seq.masks[1])
    matcher = ContourMatcher(body, rig)
    d, m = matcher.observed_lines(obs)
    first = 0
    for c, cam in enumerate(rig):
        n = len(obs.points[c])
        wd, wm = plucker_from_rays(*pixel_rays(cam, obs.points[c]))
        np.testing.assert_allclose(d[first:first + n], wd, rtol=0, atol=1e-12)
        np.testing.assert_allclose(m[first:first + n], wm, rtol=0, atol=1e-12)
        first += n
    assert first == len(d) and matcher.observed_lines(obs)[0] is d       # once per frame


@pytest.mark.parametrize("distorted", [False, True])
def test_pixels_in_both_rigs_equal_pixels_from_camera(body, walk, distorted):
    """The matcher's one-pass projection into the visibility rig and the rig gives
    pixels_from_camera's floats (with lens distortion and skew too) and its depth."""
    from mocap.cameras import Rig, camera_coordinates, pixels_from_camera

    pytest.importorskip("numba")
    rig, seq = walk
    if distorted:
        rng = np.random.default_rng(2)
        skew = np.array([[0, 0.7, 0], [0, 0, 0], [0, 0, 0]])
        rig = Rig(tuple(cam.replace(dist=rng.normal(0, 0.05, 5), K=cam.K + skew) for cam in rig))
    matcher = ContourMatcher(body, rig)
    verts = body.shaped(seq.gt.alpha).pose(seq.gt.chi[1]).vertices[0].astype(np.float64)
    xyz = camera_coordinates(rig, verts)
    small, full, depth = matcher.pixels(xyz)
    want_small, want_depth = pixels_from_camera(matcher.small, xyz)
    np.testing.assert_array_equal(small, want_small)
    np.testing.assert_array_equal(full, pixels_from_camera(rig, xyz)[0])
    np.testing.assert_array_equal(depth, want_depth)


def _blob_masks(h, w, rng, count=12):
    """Masks for the outline tests: empty, full, a single pixel, a one-pixel row and column on
    the border, and random elliptic blobs (some over the border) with holes."""
    yy, xx = np.ogrid[:h, :w]
    masks = [np.zeros((h, w), bool), np.ones((h, w), bool)]
    for sl in ((40, 60), (0, slice(None)), (slice(None), w - 1), (h - 1, 0)):
        m = np.zeros((h, w), bool)
        m[sl] = True
        masks.append(m)
    for _ in range(count):
        cy, cx = rng.integers(-10, h + 10), rng.integers(-10, w + 10)
        m = ((yy - cy) / rng.integers(3, 40)) ** 2 + ((xx - cx) / rng.integers(3, 50)) ** 2 < 1
        m &= rng.random((h, w)) > 0.05                                     # holes
        masks.append(m)
    return masks


def test_visibility_without_the_band_image_equals_the_band_lookup():
    """The compiled visibility (an outline pixel searched within the tolerance's element
    around each vertex, the outline eroded on the mask's box) keeps exactly the vertices whose
    rounded pixel lies on the numpy path's band (:func:`outline_band`): points all over the
    image, on half-pixels and outside it, with a stride, for tolerances 1 to 3 px, on masks
    touching every border, with holes, a single pixel, the full image and an empty one."""
    import cv2

    from mocap.local import contour

    pytest.importorskip("numba")
    k3 = np.ones((3, 3), np.uint8)
    rng = np.random.default_rng(11)
    h, w = 90, 120
    masks = _blob_masks(h, w, rng)
    V = 3000
    px = np.stack([rng.uniform(-3, w + 2, V), rng.uniform(-3, h + 2, V)], -1)
    px[:400] = np.round(px[:400] * 2) / 2                                   # half-pixels: ties
    mark = rng.random((len(masks), V)) < 0.6
    pxs = np.ascontiguousarray(np.broadcast_to(px, (len(masks), V, 2)))
    for tol in (1.0, 1.5, 3.0):
        r = int(np.ceil(tol))
        kt = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        off = np.argwhere(kt > 0) - np.array(kt.shape) // 2
        offsets = np.ascontiguousarray(off[np.argsort((off**2).sum(1), kind="stable")], np.int64)
        for stride in (1, 3):
            stack = np.ascontiguousarray(masks)
            boxes = np.zeros((len(masks), 4), np.int64)
            for c, m in enumerate(masks):                 # the mask's box (the kept masks' case)
                x, y, bw, bh = cv2.boundingRect(m.astype(np.uint8))
                boxes[c] = y, y + bh, x, x + bw
            ids = np.zeros(mark.shape, np.int64)
            marked = mark.sum(axis=1)
            for c in range(len(masks)):
                ids[c, :marked[c]] = np.flatnonzero(mark[c])
            out = np.empty(mark.shape, np.int64)
            count = np.zeros(len(masks), np.int64)
            contour._visible_on_masks(ids, marked, pxs, stack, boxes, offsets, stride, out, count)
            whole = np.zeros_like(boxes)
            whole[:, 1], whole[:, 3] = h, w
            out2, count2 = np.empty(mark.shape, np.int64), np.zeros(len(masks), np.int64)
            contour._visible_on_masks(ids, marked, pxs, stack, whole, offsets, stride, out2, count2)
            for c, m in enumerate(masks):
                band = contour.outline_band(m, k3, kt)
                vid = np.flatnonzero(mark[c])[::stride]
                p = px[vid]
                inside = (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)
                vid, p = vid[inside], p[inside]
                ui, vi = np.round(p).astype(int).T
                want = vid[band[vi, ui] > 0]
                np.testing.assert_array_equal(out[c, :count[c]], want)
                np.testing.assert_array_equal(out2[c, :count2[c]], want)
                assert 0 < len(want) < len(vid) or c < 2 or m.sum() < 2


def test_masks_kept_between_calls_equal_fresh_rasterizer_masks(body, walk):
    """The local step's model silhouettes drawn into masks kept between calls (only the last
    call's boxes cleared and scanned) are the rasterizer's masks at every call: a walk's poses
    one after the other, the body moved off the side of some views and back, vertices behind
    the near plane (their faces culled) in some views; the accumulation image is all 0 after
    each call."""
    from mocap.cameras import project
    from mocap.render import get_rasterizer
    from mocap.render._compiled import KeptMasks

    pytest.importorskip("numba")
    rig, seq = walk
    small = rig.scaled(0.5)
    w, h = (int(v) for v in small.sizes[0])
    raster = get_rasterizer(body.faces, body.num_vertices)
    faces, edges = raster.kernel_arrays
    kept = KeptMasks(len(rig), h, w)
    sb = body.shaped(seq.gt.alpha)
    rng = np.random.default_rng(2)
    poses = [seq.gt.chi[f].astype(np.float64) for f in range(3)]
    far = poses[0].copy()
    far[:3] += [1.6, 0.4, 0.0]
    touching = 0
    for k, chi in enumerate([*poses, far, far, poses[1], poses[2], poses[2]]):
        verts = sb.pose(chi).vertices[0].astype(np.float64)
        px, depth = project(small, verts, return_depth=True)
        if k >= 4:                                   # some vertices behind the near plane
            depth = depth.copy()
            depth[rng.random(depth.shape) < 0.02] = 0.01
        want = raster(px, h, w, depth, near=0.05)
        got = kept.draw(np.ascontiguousarray(px[..., 0]), np.ascontiguousarray(px[..., 1]),
                        np.ascontiguousarray(depth > 0.05), faces, edges)
        np.testing.assert_array_equal(got, want)
        assert not kept.acc.any()
        touching += int(want[:, :, [0, -1]].any() or want[:, [0, -1], :].any())
        assert want.any()
    assert touching >= 2                             # the moved body crosses an image border


def test_one_matcher_called_from_two_threads_keeps_each_threads_masks(body, walk):
    """The model masks a matcher keeps between calls are per thread: a thread's masks are not
    overwritten by another thread's call in between (ordered by events, not by timing); each
    equals the rasterizer's masks of its own pose."""
    import threading

    pytest.importorskip("numba")
    rig, seq = walk
    matcher = ContourMatcher(body, rig)
    h, w = matcher.small_size
    sb = body.shaped(seq.gt.alpha)
    far = seq.gt.chi[0].astype(np.float64).copy()
    far[:3] += [0.8, 0.3, 0.0]
    pixels = [project(matcher.small, sb.pose(chi).vertices[0].astype(np.float64), return_depth=True)
              for chi in (seq.gt.chi[1].astype(np.float64), far)]
    want = [matcher.raster(px, h, w, depth, near=0.05) for px, depth in pixels]
    assert not np.array_equal(want[0], want[1])
    drawn, other_done, got = threading.Event(), threading.Event(), {}

    def first():
        masks = matcher.model_masks(*pixels[0])
        drawn.set()
        other_done.wait(60)
        got[0] = masks.copy()               # read after the other thread's call

    def second():
        drawn.wait(60)
        got[1] = matcher.model_masks(*pixels[1]).copy()
        other_done.set()

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


def test_two_local_trackers_in_two_threads_give_what_each_gives_alone(body, walk):
    """Two local trackers stepped at once in two threads, the second even sharing the first's
    contour matcher, track as each does alone, bit for bit (the threads switched every 10 us:
    with one set of kept masks per matcher, this failed 3 runs of 3)."""
    import sys
    from concurrent.futures import ThreadPoolExecutor

    rig, seq = walk
    starts = [seq.gt.chi[0].astype(np.float64).copy() for _ in range(2)]
    starts[1][body.dof_index("r_knee_flex")] += np.deg2rad(12)
    starts[1][0] += 0.03

    def make(k, matcher=None):
        tr = LocalTracker(body, rig, sift={"enabled": False}, iterations=3)
        tr.initialize(starts[k], seq.gt.alpha)
        if matcher is not None:
            tr.matcher = matcher
        return tr

    def run(tr):
        return [tr.step(frame_of(seq, f)).chi for f in (1, 2)]

    alone = [run(make(0)), run(make(1))]
    first = make(0)
    pair = [first, make(1, matcher=first.matcher)]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)             # the threads take turns often
    try:
        with ThreadPoolExecutor(2) as pool:
            together = list(pool.map(run, pair))
    finally:
        sys.setswitchinterval(interval)
    assert not np.array_equal(alone[0][-1], alone[1][-1])
    for a, b in zip(alone, together, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


def test_observed_contours_on_the_masks_box_are_the_whole_image_ones():
    """The observed outline traced on each mask's box grown by a pixel is cv2.findContours on
    the whole image, point for point and in the same order: blobs inside and over every
    border, with holes, a single pixel, a border row and column, the full image, an empty one."""
    import cv2

    rng = np.random.default_rng(12)
    masks = np.stack(_blob_masks(90, 120, rng, count=20))
    got = observed_contours(masks)
    for m, p in zip(masks, got.points, strict=True):
        contours, _ = cv2.findContours(m.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
        want = (np.concatenate([c[:, 0, :] for c in contours]).astype(np.float64) if contours
                else np.zeros((0, 2)))
        np.testing.assert_array_equal(p, want)
    assert sum(len(p) == 0 for p in got.points) == 1 and got.trees[0] is None

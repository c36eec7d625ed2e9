"""Synthetic scenes with several people, as a keypoint detector sees them: per frame and view,
one skeleton of labelled keypoints per visible person, grouped by ``Detections.person`` (the
detector's per-view index, shuffled so that it says nothing about identity across views or
frames). For tests and figures of the multi-person start-up and tracking.

    det, points = crowd_detections(body, rig, chis, alphas, labels, noise_px=1.0, seed=0)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mocap.body.catalogue import make_landmark_set
from mocap.body.model import BodyModel
from mocap.cameras import Rig, project
from mocap.data.sequence import Detections
from mocap.data.sequence import Sequence as Sequence_


def crowd_detections(body: BodyModel, rig: Rig, chis: np.ndarray, alphas: np.ndarray,
                     labels: Sequence[str], noise_px: float = 1.0, seed: int = 0,
                     confidence: float = 0.8,
                     present: np.ndarray | None = None) -> tuple[Detections, np.ndarray]:
    """chis: (N, F, D) poses of N people over F frames; alphas: (N, K) their shapes; labels:
    keypoint names of the landmark catalogue; present: (N, F) bool, the frames each person is
    in the scene (None: all). Returns the detections (every keypoint of a present person in
    front of a camera and inside its image; pixel noise ``noise_px``) and the true
    keypoints (N, F, L, 3) world metres (NaN where absent)."""
    rng = np.random.default_rng(seed)
    lms = make_landmark_set(body, list(labels))
    chis = np.asarray(chis, np.float64)
    N, F, _ = chis.shape
    pts = np.stack([lms.positions(body.shaped(alphas[n]), chis[n]).astype(np.float64) for n in range(N)])
    if present is not None:
        pts[~np.asarray(present, bool)] = np.nan
    rows = []
    sizes = np.asarray(rig.sizes, np.float64)                          # (C, 2) width, height
    for f in range(F):
        for c in range(len(rig)):
            order = rng.permutation(N)                                 # the detector's own order
            for slot, n in enumerate(o for o in order if np.isfinite(pts[o, f, 0, 0])):
                px, depth = project(rig[c], pts[n, f], return_depth=True)
                px = px + rng.normal(0.0, noise_px, px.shape)
                ok = (depth > 0.1) & np.all((px >= 0) & (px < sizes[c]), axis=1)
                for k in np.flatnonzero(ok):
                    rows.append((f, c, k, px[k, 0], px[k, 1], confidence, slot))
    a = np.array(rows, np.float64).reshape(-1, 7)
    det = Detections(tuple(lms.names), a[:, 0].astype(np.int64), a[:, 1].astype(np.int64),
                     a[:, 2].astype(np.int64), a[:, 3:5], a[:, 5], a[:, 6].astype(np.int64))
    return det, pts


def straight_walk(body: BodyModel, frames: int, start: Sequence[float], end: Sequence[float],
                  yaw: float, seed: int = 0, action: str = "walk") -> np.ndarray:
    """(frames, D) poses: the joint angles of ``action`` (:func:`mocap.data.motion.generate_motion`)
    with the root moved in a straight line from ``start`` to ``end`` (x, y world metres, the
    generated root height kept) and turned by ``yaw`` radians about the vertical."""
    from mocap.body.twists import se3_exp, se3_log
    from mocap.data.motion import generate_motion

    chi = generate_motion(body, action, frames, fps=25, seed=seed)
    T = se3_exp(chi[:, :6].astype(np.float64))                      # (F, 4, 4) root motion
    s = np.linspace(0.0, 1.0, frames)[:, None]
    xy = (1 - s) * np.asarray(start, np.float64) + s * np.asarray(end, np.float64)
    c, si = np.cos(yaw), np.sin(yaw)
    Rz = np.array([[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]])
    # keep the generated root orientation relative to its own heading at frame 0; place it
    out = np.array(T)
    root_rest = body.shaped(np.zeros(body.num_shape)).rest_joints[0].astype(np.float64)
    for f in range(frames):
        R = Rz @ T[f, :3, :3]
        pos = np.array([xy[f, 0], xy[f, 1], (T[f, :3, :3] @ root_rest + T[f, :3, 3])[2]])
        out[f, :3, :3] = R
        out[f, :3, 3] = pos - R @ root_rest                          # the root joint lands at pos
    chi = np.array(chi, np.float64)
    chi[:, :6] = se3_log(out)
    return chi


def crossing_scene(body: BodyModel, frames: int, people: int = 3, gap: float = 0.35,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(chis (N, F, D), alphas (N, K)): two people walking towards each other on parallel
    lines ``gap`` metres apart, crossing at the centre of the volume half way through, and
    (people=3) a third gesturing 1.2 m to the side. Shapes differ per person."""
    chis = [straight_walk(body, frames, (-1.2, 0.0), (1.2, 0.0), 0.0, seed),
            straight_walk(body, frames, (1.2, gap), (-1.2, gap), np.pi, seed + 1)]
    if people >= 3:
        chis.append(straight_walk(body, frames, (0.0, -1.2), (0.2, -1.2), np.pi / 2, seed + 2,
                                  action="gestures"))
    alphas = np.random.default_rng(seed).normal(0, 0.8, (len(chis), body.num_shape))
    return np.stack(chis), alphas


#: the crowd's cameras: 5 views on a 4.5 m ring, 640x480, wide enough for a 3 m wide scene
CROWD_RIG = {"_target_": "mocap.cameras.rigs.ring_rig", "num_cameras": 5, "radius": 4.5, "height": 2.0,
             "width": 640, "image_height": 480, "fov_deg": 60.0, "look_at": [0.0, 0.0, 0.9],
             "start_deg": 18.0}


@dataclass(frozen=True)
class Crowd:
    """A scene of several people: chis (N, F, D), alphas (N, K), present (N, F) bool, and the
    story: ``crossing`` (two ids crossing at ``crossing_frame``), ``entering`` {id: first frame},
    ``leaving`` {id: last frame}."""

    chis: np.ndarray
    alphas: np.ndarray
    present: np.ndarray
    crossing: tuple[int, int]
    crossing_frame: int
    entering: dict[int, int]
    leaving: dict[int, int]


def crowd_scene(body: BodyModel, frames: int = 80, seed: int = 0, gap: float = 0.3) -> Crowd:
    """Five people, at most four at once: 0 and 1 walk towards each other on lines ``gap``
    m apart and cross half way; 2 walks off and leaves at 45 % of the frames; 3 enters at 15 %
    and 4 at 50 % (they appear mid-stride, as through a door). Shapes differ per person."""
    if frames < 20:
        raise ValueError(f"crowd frames = {frames} is too short (>= 20: people enter at 15 % and 50 %)")
    F = frames
    walks = [((-1.3, -gap / 2), (1.3, -gap / 2), 0.0), ((1.3, gap / 2), (-1.3, gap / 2), np.pi),
             ((0.2, -0.9), (1.6, -1.5), -0.4), ((-1.6, 1.1), (0.9, 1.1), 0.0),
             ((1.5, -0.8), (-0.5, -1.0), np.pi)]
    chis = np.stack([straight_walk(body, F, a, b, yaw, seed + n) for n, (a, b, yaw) in enumerate(walks)])
    alphas = np.random.default_rng(seed).normal(0, 0.8, (len(walks), body.num_shape))
    present = np.ones((len(walks), F), bool)
    leave, enter3, enter4 = int(0.45 * F), int(0.15 * F), int(0.5 * F)
    present[2, leave + 1:] = False
    present[3, :enter3] = False
    present[4, :enter4] = False
    return Crowd(chis, alphas, present, (0, 1), F // 2, {3: enter3, 4: enter4}, {2: leave})


def false_skeletons(body: BodyModel, rig: Rig, frames: int, count: int, labels: Sequence[str],
                    seed: int = 0, noise_px: float = 1.0, confidence: float = 0.8,
                    max_views: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A detector's false people: ``count`` whole skeletons, each seen in one to ``max_views``
    views only (drawn per false person) over a stretch of the frames (a quarter to all of them),
    plausible and moving: the keypoints of a person of random shape walking a straight line
    through the volume, projected into those views alone (``noise_px`` pixel noise). Returns
    (rows (M, 7): frame, view, label, x, y, confidence, false person index, the true keypoints
    (count, frames, L, 3) world metres, NaN where absent). Seeded by ``seed`` with its own
    stream (:func:`crowd_sequence`'s real people are drawn as without false ones)."""
    rng = np.random.default_rng([seed, 0xFA15E])
    lms = make_landmark_set(body, list(labels))
    sizes = np.asarray(rig.sizes, np.float64)
    rows = []
    pts_all = np.full((count, frames, len(lms), 3), np.nan)
    for n in range(count):
        views = rng.choice(len(rig), size=int(rng.integers(1, max_views + 1)), replace=False)
        length = int(rng.integers(max(frames // 4, 2), frames + 1))
        first = int(rng.integers(0, frames - length + 1))
        start, heading = rng.uniform(-1.5, 1.5, 2), rng.uniform(-np.pi, np.pi)
        end = np.clip(start + 1.0 * np.array([np.cos(heading), np.sin(heading)]), -1.8, 1.8)
        chi = straight_walk(body, frames, start, end, heading, seed=int(rng.integers(1 << 30)))
        alpha = rng.normal(0, 0.8, body.num_shape)
        pts = lms.positions(body.shaped(alpha), chi).astype(np.float64)
        pts_all[n, first:first + length] = pts[first:first + length]
        for f in range(first, first + length):
            for c in sorted(int(v) for v in views):
                px, depth = project(rig[c], pts[f], return_depth=True)
                px = px + rng.normal(0.0, noise_px, px.shape)
                ok = (depth > 0.1) & np.all((px >= 0) & (px < sizes[c]), axis=1)
                for k in np.flatnonzero(ok):
                    rows.append((f, c, k, px[k, 0], px[k, 1], confidence, n))
    return np.array(rows, np.float64).reshape(-1, 7), pts_all


def with_false_skeletons(det: Detections, rows: np.ndarray, seed: int = 0) -> Detections:
    """``det`` with the false skeletons ``rows`` (:func:`false_skeletons`) added, sorted by
    frame and view, the detector's person index of each (frame, view) shuffled again over the
    true and the false skeletons together (seeded by ``seed``)."""
    rng = np.random.default_rng([seed, 0x5EED])
    frame = np.concatenate([det.frame, rows[:, 0].astype(np.int64)])
    view = np.concatenate([det.view, rows[:, 1].astype(np.int64)])
    label = np.concatenate([det.label, rows[:, 2].astype(np.int64)])
    xy = np.concatenate([det.xy, rows[:, 3:5]])
    conf = np.concatenate([det.confidence, rows[:, 5]])
    real = np.asarray(det.person, np.int64)
    tag = np.concatenate([real, 1_000_000 + rows[:, 6].astype(np.int64)])   # false ones apart
    order = np.lexsort((view, frame))
    frame, view, label, xy = frame[order], view[order], label[order], xy[order]
    conf, tag = conf[order], tag[order]
    person = np.empty_like(tag)
    keys = frame * (int(view.max(initial=0)) + 1) + view
    for key in np.unique(keys):
        sel = np.flatnonzero(keys == key)
        who, inverse = np.unique(tag[sel], return_inverse=True)
        person[sel] = rng.permutation(len(who))[inverse]
    return Detections(det.labels, frame, view, label, xy, conf, person)


def crowd_sequence(*, body: BodyModel, **keys) -> Sequence_:
    """The synthetic crowd (:func:`crowd_scene`) as a keypoint detector sees it: ``layout``'s
    keypoints (:data:`mocap.body.skeletons.LAYOUTS`) grouped per person, ``noise_px`` pixel
    noise, in ``cameras`` (None: :data:`CROWD_RIG`, 5 views); ``keys``: the settings that differ
    from :class:`~mocap.data.source_settings.CrowdSource`'s defaults. The sequence has no single-person
    ground truth; its several-people truth (mocap's joints per person, NaN where absent) is
    ``seq.meta["people_truth"]`` (:class:`mocap.data.people_truth.PeopleTruth`), with the
    scene's story under ``seq.meta["crowd"]``. ``false_people``: that many false skeletons
    (:func:`false_skeletons`: whole plausible moving people a detector sees in one to
    ``false_views`` views only, seeded by ``seed``; 0, the default, adds none and leaves the
    detections as they were), listed in ``seq.meta["crowd"]["false_people"]``."""
    from mocap.body.skeletons import LAYOUTS
    from mocap.cameras import rig_from_config
    from mocap.data.people_truth import KEY, PeopleTruth
    from mocap.data.source_settings import CrowdSource
    from mocap.settings import settings_from_mapping

    s = settings_from_mapping(CrowdSource, keys)
    frames, seed, noise_px, gap, cameras, layout, name = (s.frames, s.seed, s.noise_px, s.gap, s.cameras,
                                                          s.layout, s.name)
    false_people, false_views = s.false_people, s.false_views
    if layout not in LAYOUTS:
        raise ValueError(f"data.layout = {layout!r} is not a keypoint layout (allowed: {', '.join(LAYOUTS)})")
    if noise_px < 0:
        raise ValueError(f"data.noise_px = {noise_px!r} is out of range (>= 0 px)")
    if false_people < 0:
        raise ValueError(f"data.false_people = {false_people!r} is out of range (an integer >= 0)")
    if false_views < 1:
        raise ValueError(f"data.false_views = {false_views!r} is out of range (an integer >= 1)")
    rig = rig_from_config(CROWD_RIG if cameras is None else cameras)
    crowd = crowd_scene(body, frames, seed, gap)
    labels = [n for n in LAYOUTS[layout] if n is not None]
    det, _ = crowd_detections(body, rig, crowd.chis, crowd.alphas, labels, noise_px=noise_px, seed=seed,
                              present=crowd.present)
    if false_people:
        rows, _ = false_skeletons(body, rig, frames, false_people, labels, seed=seed, noise_px=noise_px,
                                  max_views=false_views)
        det = with_false_skeletons(det, rows, seed)
    joints = np.stack([body.shaped(a).pose(c).joints for c, a in zip(crowd.chis, crowd.alphas, strict=True)])
    joints = np.where(crowd.present[..., None, None], joints, np.nan).transpose(1, 0, 2, 3)     # (F, N, J, 3)
    story = {"crossing": list(crowd.crossing), "crossing_frame": crowd.crossing_frame,
             "entering": {str(k): v for k, v in crowd.entering.items()},
             "leaving": {str(k): v for k, v in crowd.leaving.items()}}
    if false_people:
        story["false_people"] = false_people
    return Sequence_(name=name, rig=rig, fps=25.0, detections=det,
                     meta={KEY: PeopleTruth(joints, body.joint_names), "crowd": story})

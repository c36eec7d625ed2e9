"""A Rerun recording of a tracking run (``recording.rrd``), with a blueprint.

What each ``recording.level`` holds (:class:`mocap.recording.settings.RecordingSettings`;
timeline ``frame``, per-layer annealing values on ``anneal_step`` = frame x layers + layer):

summary
    run/config, run/metadata, run/metrics      text documents (static)
    world/cams/<view>                          pinhole + pose (static)
    plots/energy/<term>, plots/error/mpjpe_mm, plots/timing/<stage>, plots/misalignment/...
                                               every frame's scalars
    plots/motion/chi/<dof>, plots/decisions/..., log/decisions, log/shape, run/shape
                                               the motion and the tracker's decisions (motion_log.py)
    world/body/estimate, world/skeleton/estimate|truth, world/landmarks/estimate,
    world/surface/truth                        the last tracked frame only (the final body)
standard (default): everything of summary, and on every ``every``-th frame
    world/body/estimate                        estimated mesh: triangles and colours once (static),
                                               then vertex positions only
    world/skeleton/estimate|truth              bones as line strips
    world/landmarks/estimate                   3D landmarks (marker / keypoint runs)
    world/surface/truth                        the true body surface as points (data whose gt.npz
                                               has ``surface``), beside the estimated mesh
    views/<view>/silhouette_diff               Fig. 8 of Zhang et al. at ``scale`` (a segmentation
                                               image: green = observed only, purple = estimate
                                               only, grey = both)
    views/<view>/image                         input image (when the data has images), downscaled to
                                               ``scale`` and JPEG-encoded once
    views/<view>/detections|landmarks          2D detections, reprojected 3D landmarks
    plots/layers/<value>                       every annealing layer's scalars (``anneal_step``)
full: everything of standard, and
    world/particles/layer_<m>                  joints of every particle of every layer
                                               (``particles=true``: world/particles/first|last)
    the 2D views and images at full size (``scale`` 1)

Per-frame scalars, texts, points, strips and mesh positions are gathered and sent in batches
(``send_columns``, :mod:`mocap.recording.columns`) every :data:`BATCH_FRAMES` frames and at the
end; style (colours, radii, labels) is logged once, static. The file is written to
``<path>.part`` and renamed when the run finishes; a failed run leaves ``recording.failed.rrd``
for inspection and never a file that looks complete.

A several-people run (``tracker=marker_people``, :meth:`RerunSink.people_frame`) logs, one
colour per person id (:func:`person_color`):

    world/people/<id>/skeleton|landmarks    each person's bones and fitted keypoints
    world/people_truth/<n>                  ground-truth skeletons (when the data has them)
    views/<view>/people/<id>                each person's keypoints reprojected
    plots/people/live, plots/timing/step    people tracked per frame, step time
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import cv2
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from mocap.body.model import BodyModel
from mocap.cameras import project
from mocap.data.sequence import Sequence
from mocap.energy.silhouette import downscale_masks
from mocap.recording.columns import Columns
from mocap.recording.motion_log import MotionLogger
from mocap.recording.settings import RecordingSettings
from mocap.recording.sink import RunInfo
from mocap.render import get_rasterizer
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.diagnostics import flatten_scalars

BODY_RGB = (235, 120, 40)     # the estimated mesh's base colour (orange), shaded per part
DIFF_COLORS = {"observed_only": (40, 200, 60), "estimate_only": (190, 40, 200), "both": (200, 200, 200)}
#: class ids of the silhouette difference (observed + 2 x estimate)
DIFF_CLASSES = {1: "observed_only", 2: "estimate_only", 3: "both"}
BATCH_FRAMES = 100            # frames gathered before a send_columns batch (a mesh: ~60 kB per frame) ...
BATCH_BYTES = 32_000_000      # ... or fewer when they hold more bytes (full-size images)
JPEG_QUALITY = 80


def blueprint(view_names: list[str]) -> rrb.Blueprint:
    """The layout: the 3D view over the 2D views (none: the 3D view alone), plots on the right."""
    views = [rrb.Spatial2DView(origin=f"views/{n}", name=n) for n in view_names]
    scene = rrb.Spatial3DView(origin="world", name="3D")
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(scene, rrb.Grid(*views, name="views"), row_shares=[3, 2]) if views else scene,
            rrb.Vertical(
                rrb.TimeSeriesView(origin="plots/error", name="joint error (mm)"),
                rrb.TimeSeriesView(origin="plots/energy", name="energy terms"),
                rrb.Tabs(rrb.TimeSeriesView(origin="plots/motion", name="pose (chi)"),
                         rrb.TimeSeriesView(origin="plots/decisions", name="decisions"),
                         rrb.TextLogView(origin="log", name="decision log"),
                         rrb.TimeSeriesView(origin="plots/layers", name="annealing layers (anneal_step)"),
                         rrb.TimeSeriesView(origin="plots/timing", name="timings (s)"),
                         rrb.TextDocumentView(origin="run", name="run")),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


#: one colour per person id (cycled)
PEOPLE_RGB = ((230, 25, 75), (60, 180, 75), (0, 130, 200), (245, 130, 48), (145, 30, 180), (70, 240, 240),
              (240, 50, 230), (210, 245, 60), (250, 190, 212), (0, 128, 128), (170, 110, 40), (128, 0, 0))


def person_color(person_id: int) -> tuple[int, int, int]:
    """The recording's colour of person ``person_id``."""
    return PEOPLE_RGB[int(person_id) % len(PEOPLE_RGB)]


def body_colors(body: BodyModel) -> np.ndarray:
    """(V, 3) uint8 vertex colours of the estimated mesh: one shade per body part, all in
    the body colour range (red dominant, skin-like) so a screenshot test can find the body."""
    rng = np.random.default_rng(7)
    shade = rng.uniform(0.75, 1.0, size=(body.num_joints, 1))
    palette = (shade * np.array(BODY_RGB)).astype(np.uint8)
    return palette[body.part_labels]


#: the longest wait, in seconds, for the recording to reach its file (a full disk can block the
#: writer for ever: the run then ends with :class:`RecordingWriteError` instead of hanging)
WRITE_TIMEOUT_S = 60.0
#: recordings given up on: kept referenced (dropping one would wait on its writer again); a
#: process holding any must leave with os._exit (mocap_cli.main does)
ABANDONED: list = []


class RecordingWriteError(OSError):
    """The recording could not be written (a full disk, a failing write, a writer that hangs)."""


def _bounded(fn, path: Path, what: str) -> None:
    """``fn()`` in a helper thread, waited for at most :data:`WRITE_TIMEOUT_S`."""
    done, failed = threading.Event(), []

    def work():
        try:
            fn()
        except BaseException as exc:        # re-raised in the caller's thread
            failed.append(exc)
        finally:
            done.set()

    threading.Thread(target=work, daemon=True, name=f"mocap-recording-{what}").start()
    if not done.wait(WRITE_TIMEOUT_S):
        rr.unregister_shutdown()            # nor may the exit wait on it
        raise RecordingWriteError(f"{path}: the recording could not be written within {WRITE_TIMEOUT_S:g} s "
                                  f"({what} blocked: disk full?); the run is incomplete")
    if failed:
        raise RecordingWriteError(f"{path}: the recording could not be written "
                                  f"({type(failed[0]).__name__}: {failed[0]})") from failed[0]


class RerunSink:
    """Writes a run to ``path`` with the given :class:`RecordingSettings` (level, every,
    particles, images, scale; what each level holds: the module docstring)."""

    def __init__(self, path: str | Path, settings: RecordingSettings | None = None):
        self.settings = settings if settings is not None else RecordingSettings()
        self.path = Path(path)
        self.part = self.path.with_name(self.path.name + ".part")
        self.rec: rr.RecordingStream | None = None

    # -- lifecycle -----------------------------------------------------------------------
    def start(self, info: RunInfo, body: BodyModel, seq: Sequence) -> None:
        s = self.settings
        self.body, self.seq = body, seq
        self.rig_small = seq.rig.scaled(s.scale)
        w, h = (int(v) for v in self.rig_small.sizes[0])
        self.size = (h, w)
        self.rasterizer = get_rasterizer(body.faces, body.num_vertices) if s.views else None
        self.shaped = None
        self.cols = Columns()
        self.frames_pending = 0
        self.styled: set = set()          # entities whose static style / format is logged
        self.last = None                  # the last frame's body (summary: logged at the end)
        self.motion_log = MotionLogger(body.dof_names, self.rig_small if s.views else None)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rec = rr.RecordingStream("mocap", recording_id=info.metadata.get("run_id"))
        rec.save(self.part, default_blueprint=blueprint(list(seq.rig.names) if s.views else []))
        self.rec = rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for cam in seq.rig:
            rec.log(f"world/cams/{cam.name}", rr.Transform3D(
                translation=cam.center, mat3x3=cam.R.T), static=True)
            rec.log(f"world/cams/{cam.name}", rr.Pinhole(
                image_from_camera=cam.K, resolution=[cam.width, cam.height],
                camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=0.3), static=True)
        # Only what never changes is static: static data shadows temporal data of the same
        # component in Rerun, so static vertex positions would hide the per-frame ones.
        rec.log("world/body/estimate", rr.Mesh3D.from_fields(
            triangle_indices=body.faces, vertex_colors=body_colors(body)), static=True)
        for name, color in (("estimate", (255, 200, 0)), ("truth", (60, 220, 255))):
            rec.log(f"world/skeleton/{name}", rr.LineStrips3D.from_fields(colors=[color], radii=0.01),
                    static=True)
        rec.log("world/landmarks/estimate", rr.Points3D.from_fields(radii=0.02, colors=[255, 60, 60]),
                static=True)
        self.surface = seq.gt.surface if seq.gt is not None else None
        if self.surface is not None:
            rec.log("world/surface/truth", rr.Points3D.from_fields(radii=0.004, colors=[60, 220, 255]),
                    static=True)
        if s.views:
            rec.log("views", rr.AnnotationContext([(0, "none", (0, 0, 0, 0))] + [
                (k, name, DIFF_COLORS[name]) for k, name in DIFF_CLASSES.items()]), static=True)
            for name in seq.rig.names:
                rec.log(f"views/{name}/detections", rr.Points2D.from_fields(radii=1.5, colors=[255, 0, 255]),
                        static=True)
        rec.log("run/config", rr.TextDocument(f"```yaml\n{info.config_yaml}\n```",
                                              media_type=rr.MediaType.MARKDOWN), static=True)
        rec.log("run/metadata", rr.TextDocument(json.dumps(info.metadata, indent=2)), static=True)
        # the file holds the run's config and cameras before tracking starts (frames come in
        # batches): a run that dies keeps them, and ``<path>.part`` marks a run in progress
        _bounded(rec.flush, self.part, "flush")

    def finish(self, metrics: dict | None, failed: bool = False) -> None:
        if self.rec is None:
            return
        try:
            if self.last is not None and not self.settings.per_frame_body:
                self._log_body(*self.last)            # summary: the final body
            self.cols.send(self.rec)                  # the last batch
            if metrics is not None:
                self.rec.log("run/metrics", rr.TextDocument(json.dumps(metrics, indent=2)), static=True)
        finally:                                      # the file is closed and named whatever happens
            rec, self.rec = self.rec, None
            try:                                      # waited for a bounded time (a full disk can block it)
                _bounded(rec.flush, self.part, "flush")
                _bounded(rec.disconnect, self.part, "disconnect")
            except RecordingWriteError:
                ABANDONED.append(rec)                 # <path>.part stays: the folder is visibly incomplete
                raise
            target = self.path.with_name("recording.failed.rrd") if failed else self.path
            self.part.replace(target)

    # -- per frame -----------------------------------------------------------------------
    def frame(self, frame: Frame, estimate: Estimate, joints: np.ndarray, vertices: np.ndarray,
              truth_joints: np.ndarray | None, error_mm: float | None, seconds: float) -> None:
        s, rec, cols, f = self.settings, self.rec, self.cols, frame.index
        rec.set_time("frame", sequence=f)
        d = estimate.diagnostics
        for key, value in d.scalars().items():      # energy/*, timing/*, misalignment/*, ...
            cols.scalar(f"plots/{key}", f, value)
        if error_mm is not None:
            cols.scalar("plots/error/mpjpe_mm", f, error_mm)
        cols.scalar("plots/timing/step", f, seconds)
        if frame.detections is not None:        # 0: a frame tracked without any detection
            cols.scalar("plots/input/detections", f, len(frame.detections))
        layers = d.anneal.layers if (d.anneal is not None and s.layers) else ()
        for m, layer in enumerate(layers):          # on their own timeline, not stacked on the frame
            for key, value in flatten_scalars("", layer).items():
                cols.scalar(f"plots/layers/{key}", f * len(layers) + m, value, timeline="anneal_step")
        self.motion_log.frame(rec, cols, f, estimate)
        landmarks = d.landmarks.points if d.landmarks is not None else None
        self.last = (f, joints, vertices, truth_joints, landmarks)
        if f % s.every == 0:
            if s.per_frame_body:
                self._log_body(f, joints, vertices, truth_joints, landmarks)
            if s.views and landmarks is not None:
                self.motion_log.landmarks(rec, cols, f, d.landmarks.names, landmarks)
            if s.particles and d.particles:
                self._log_particles(f, estimate.alpha, d.particles, getattr(estimate, "joint_offsets", None))
            if s.views:
                self._log_views(frame, vertices)
        self.frames_pending += 1
        if self.frames_pending >= BATCH_FRAMES or cols.nbytes > BATCH_BYTES:
            cols.send(rec)
            self.frames_pending = 0

    def _log_body(self, f, joints, vertices, truth_joints, landmarks) -> None:
        # copies (np.array): the rows wait in the batch, the caller's arrays may change meanwhile
        cols, parents = self.cols, self.body.parents
        cols.add("world/body/estimate", rr.Mesh3D, f, vertex_positions=np.array(vertices, np.float32))
        for name, J in (("estimate", joints), ("truth", truth_joints)):
            if J is not None:
                J = np.asarray(J, np.float32)
                cols.add(f"world/skeleton/{name}", rr.LineStrips3D, f,
                         strips=np.stack([J[parents[1:]], J[1:]], axis=1))          # (J-1, 2, 3)
        if landmarks is not None:
            cols.add("world/landmarks/estimate", rr.Points3D, f, positions=np.array(landmarks, np.float32))
        if self.surface is not None and f < len(self.surface):
            cols.add("world/surface/truth", rr.Points3D, f, positions=np.array(self.surface[f], np.float32))

    def _log_particles(self, f, alpha, particles, joint_offsets=None) -> None:
        shaped = self._shaped(alpha, joint_offsets)
        if self.settings.particles == "all":
            named = [(f"layer_{m:02d}", x) for m, x in enumerate(particles)]
        else:
            named = [("first", particles[0]), ("last", particles[-1])]
        for name, x in named:
            if name not in self.styled:
                self.styled.add(name)
                self.rec.log(f"world/particles/{name}", rr.Points3D.from_fields(radii=0.006), static=True)
            pts = shaped.joints(x).reshape(-1, 3).astype(np.float32)
            self.cols.add(f"world/particles/{name}", rr.Points3D, f, positions=pts)

    def people_frame(self, frame: Frame, people: dict, truth: np.ndarray | None, seconds: float) -> None:
        """One frame of several people: ``people`` {id: (estimate, joints (J, 3))} of the live
        tracks; truth: (P_gt, J, 3) joints (NaN: absent) or None (see the module docstring)."""
        rec, f = self.rec, frame.index
        rec.set_time("frame", sequence=f)
        rec.log("plots/timing/step", rr.Scalars(seconds))
        rec.log("plots/people/live", rr.Scalars(len(people)))
        gone = getattr(self, "_people_live", set()) - set(people)
        for pid in gone:                    # ended: nothing of theirs stays on screen
            rec.log(f"world/people/{pid}", rr.Clear(recursive=True))
            for name in self.seq.rig.names:
                rec.log(f"views/{name}/people/{pid}", rr.Clear(recursive=True))
        self._people_live = set(people)
        if f % self.settings.every:
            return
        parents = self.body.parents
        bones = lambda J: [np.stack([J[parents[j]], J[j]]) for j in range(1, len(parents))]  # noqa: E731
        for pid, (est, joints) in people.items():
            color = person_color(pid)
            rec.log(f"world/people/{pid}/skeleton",
                    rr.LineStrips3D(bones(joints), colors=[color], radii=0.012))
            lm = est.diagnostics.landmarks
            if lm is None:
                continue
            rec.log(f"world/people/{pid}/landmarks", rr.Points3D(lm.points, radii=0.02, colors=[color]))
            px, depth = project(self.rig_small, np.asarray(lm.points, np.float64), return_depth=True)
            for c, name in enumerate(self.seq.rig.names):
                rec.log(f"views/{name}/people/{pid}",
                        rr.Points2D(px[c][depth[c] > 0], radii=2.0, colors=[color]))
        if truth is not None:
            for g, J in enumerate(truth):
                if np.isfinite(J).all():
                    rec.log(f"world/people_truth/{g}", rr.LineStrips3D(bones(J), colors=[(200, 200, 200)],
                                                                        radii=0.006))
                else:
                    rec.log(f"world/people_truth/{g}", rr.Clear(recursive=True))
        if frame.detections is not None and len(frame.detections):
            h, w = self.size
            det = frame.detections
            for c, name in enumerate(self.seq.rig.names):
                xy = (det.xy[det.view == c] + 0.5) * (w / self.seq.rig.sizes[c][0]) - 0.5
                rec.log(f"views/{name}/detections", rr.Points2D(xy, radii=1.0, colors=[150, 150, 150]))

    def _shaped(self, alpha, joint_offsets=None):
        if self.shaped is None or not self.shaped.is_for(alpha, joint_offsets):
            self.shaped = self.body.shaped(alpha, joint_offsets)
        return self.shaped

    def _log_views(self, frame: Frame, vertices: np.ndarray) -> None:
        rec, f = self.rec, frame.index
        h, w = self.size
        names = self.seq.rig.names
        if frame.masks is not None:
            px, depth = project(self.rig_small, vertices, return_depth=True)
            est = self.rasterizer(px, h, w, depth, near=0.05)
            obs = downscale_masks(frame.masks, self.settings.scale)
            diff = obs.astype(np.uint8) + 2 * np.asarray(est, np.uint8)        # DIFF_CLASSES
            for c, name in enumerate(names):
                entity = f"views/{name}/silhouette_diff"
                if entity not in self.styled:      # the image format once, the pixels per frame
                    self.styled.add(entity)
                    rec.log(entity, rr.SegmentationImage.from_fields(format=rr.components.ImageFormat(
                        width=w, height=h, channel_datatype="U8")), static=True)
                self.cols.add(entity, rr.SegmentationImage, f, buffer=diff[c].tobytes())
        if self.settings.images and frame.images is not None:
            for c, name in enumerate(names):
                img = frame.images[c]
                if img.shape[:2] != (h, w):
                    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
                _, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(img[..., ::-1]),     # RGB -> BGR
                                       [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
                self.cols.add(f"views/{name}/image", rr.EncodedImage, f, blob=jpeg.tobytes(),
                              media_type="image/jpeg")
        if frame.detections is not None and len(frame.detections):
            det = frame.detections
            for c, name in enumerate(names):
                sel = det.view == c
                xy = (det.xy[sel] + 0.5) * (w / self.seq.rig.sizes[c][0]) - 0.5
                self.cols.add(f"views/{name}/detections", rr.Points2D, f,
                              positions=np.asarray(xy, np.float32))

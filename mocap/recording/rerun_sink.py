"""A Rerun recording of a tracking run (``recording.rrd``), with a blueprint.

Entity tree (timeline ``frame``; per-layer annealing values also on ``anneal_step`` =
frame x layers + layer):

    world                          3D, z up
      cams/<view>                  pinhole + pose (static)
      body/estimate                estimated mesh (topology static, positions per frame)
      skeleton/estimate|truth      bones as line strips
      particles/first|last         joints of every particle in the first / last layer
      landmarks/estimate           3D landmarks (marker runs)
    views/<view>/image             input image, downscaled (when the data has images)
    views/<view>/silhouette_diff   Fig. 8 of Zhang et al.: green = observed only,
                                   purple = estimate only, grey = both
    views/<view>/detections        2D detections (marker runs)
    views/<view>/landmarks         reprojected 3D landmarks (marker runs)
    plots/energy/<term>, plots/error/mpjpe_mm, plots/timing/<stage>, plots/layers/<value>
    plots/motion/chi/<dof>, plots/decisions/..., log/decisions, run/shape
                                   the motion and the tracker's decisions (motion_log.py)
    run/config, run/metadata, run/metrics   text documents

A several-people run (``tracker=marker_people``, :meth:`RerunSink.people_frame`) logs, one
colour per person id (:func:`person_color`):

    world/people/<id>/skeleton|landmarks    each person's bones and fitted keypoints
    world/people_truth/<n>                  ground-truth skeletons (when the data has them)
    views/<view>/people/<id>                each person's keypoints reprojected
    plots/people/live, plots/timing/step    people tracked per frame, step time

The file is written to ``<path>.part`` and renamed when the run finishes; a failed run
leaves ``recording.failed.rrd`` for inspection and never a file that looks complete.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from mocap.body.model import BodyModel
from mocap.cameras import project
from mocap.data.sequence import Sequence
from mocap.energy.silhouette import downscale_masks
from mocap.recording.motion_log import MotionLogger
from mocap.recording.sink import RunInfo
from mocap.render import get_rasterizer
from mocap.trackers.base import Estimate, Frame
from mocap.trackers.diagnostics import flatten_scalars

BODY_RGB = (235, 120, 40)     # the estimated mesh's base colour (orange), shaded per part
DIFF_COLORS = {"observed_only": (40, 200, 60), "estimate_only": (190, 40, 200), "both": (200, 200, 200)}


def blueprint(view_names: list[str]) -> rrb.Blueprint:
    views = [rrb.Spatial2DView(origin=f"views/{n}", name=n) for n in view_names]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(rrb.Spatial3DView(origin="world", name="3D"),
                         rrb.Grid(*views, name="views"), row_shares=[3, 2]),
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


class RerunSink:
    """Writes a run to ``path``. every: record every k-th frame (plots: every frame);
    particles: log particle clouds; images: log input images; scale: resolution of the 2D
    views relative to the camera images."""

    def __init__(self, path: str | Path, every: int = 1, particles: bool = True,
                 images: bool = True, scale: float = 0.25):
        if every < 1:
            raise ValueError(f"recording.every must be >= 1, got {every}")
        self.path = Path(path)
        self.part = self.path.with_name(self.path.name + ".part")
        self.every, self.particles, self.images, self.scale = every, particles, images, scale
        self.rec: rr.RecordingStream | None = None

    # -- lifecycle -----------------------------------------------------------------------
    def start(self, info: RunInfo, body: BodyModel, seq: Sequence) -> None:
        self.body, self.seq = body, seq
        self.rig_small = seq.rig.scaled(self.scale)
        w, h = (int(v) for v in self.rig_small.sizes[0])
        self.size = (h, w)
        self.rasterizer = get_rasterizer(body.faces, body.num_vertices)
        self.shaped = None
        self.motion_log = MotionLogger(body.dof_names, self.rig_small)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        rec = rr.RecordingStream("mocap", recording_id=info.metadata.get("run_id"))
        rec.save(self.part, default_blueprint=blueprint(list(seq.rig.names)))
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
        rec.log("run/config", rr.TextDocument(f"```yaml\n{info.config_yaml}\n```",
                                              media_type=rr.MediaType.MARKDOWN), static=True)
        rec.log("run/metadata", rr.TextDocument(json.dumps(info.metadata, indent=2)), static=True)

    def finish(self, metrics: dict | None, failed: bool = False) -> None:
        if self.rec is None:
            return
        if metrics is not None:
            self.rec.log("run/metrics", rr.TextDocument(json.dumps(metrics, indent=2)), static=True)
        self.rec.flush()
        self.rec.disconnect()
        self.rec = None
        target = self.path.with_name("recording.failed.rrd") if failed else self.path
        self.part.replace(target)

    # -- per frame -----------------------------------------------------------------------
    def frame(self, frame: Frame, estimate: Estimate, joints: np.ndarray, vertices: np.ndarray,
              truth_joints: np.ndarray | None, error_mm: float | None, seconds: float) -> None:
        rec, f = self.rec, frame.index
        rec.set_time("frame", sequence=f)
        d = estimate.diagnostics
        for key, value in d.scalars().items():      # energy/*, timing/*, misalignment/*, ...
            rec.log(f"plots/{key}", rr.Scalars(value))
        if error_mm is not None:
            rec.log("plots/error/mpjpe_mm", rr.Scalars(error_mm))
        rec.log("plots/timing/step", rr.Scalars(seconds))
        layers = d.anneal.layers if d.anneal is not None else ()
        if layers:
            rec.reset_time()            # layers on their own timeline, not stacked on the frame
        for m, layer in enumerate(layers):
            rec.set_time("anneal_step", sequence=f * len(layers) + m)
            for key, value in flatten_scalars("", layer).items():
                rec.log(f"plots/layers/{key}", rr.Scalars(value))
        if layers:
            rec.reset_time()
            rec.set_time("frame", sequence=f)
        self.motion_log.frame(rec, f, estimate)
        if f % self.every:
            return
        rec.log("world/body/estimate", rr.Mesh3D.from_fields(vertex_positions=vertices))
        parents = self.body.parents
        for name, J, color in (("estimate", joints, (255, 200, 0)), ("truth", truth_joints, (60, 220, 255))):
            if J is not None:
                strips = [np.stack([J[parents[j]], J[j]]) for j in range(1, len(parents))]
                rec.log(f"world/skeleton/{name}", rr.LineStrips3D(strips, colors=[color], radii=0.01))
        if d.landmarks is not None:
            rec.log("world/landmarks/estimate", rr.Points3D(d.landmarks.points, radii=0.02,
                                                            colors=[255, 60, 60]))
            self.motion_log.landmarks(rec, d.landmarks.names, d.landmarks.points)
        particles = d.particles
        if self.particles and particles:
            shaped = self._shaped(estimate.alpha)
            for name, x in (("first", particles[0]), ("last", particles[-1])):
                pts = shaped.joints(x).reshape(-1, 3)
                rec.log(f"world/particles/{name}", rr.Points3D(pts, radii=0.006))
        self._log_views(frame, vertices)

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
        if f % self.every:
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

    def _shaped(self, alpha):
        if self.shaped is None or not np.array_equal(self.shaped.alpha, alpha):
            self.shaped = self.body.shaped(alpha)
        return self.shaped

    def _log_views(self, frame: Frame, vertices: np.ndarray) -> None:
        rec = self.rec
        h, w = self.size
        names = self.seq.rig.names
        if frame.masks is not None:
            px, depth = project(self.rig_small, vertices, return_depth=True)
            est = self.rasterizer(px, h, w, depth, near=0.05)
            obs = downscale_masks(frame.masks, self.scale)
            for c, name in enumerate(names):
                img = np.zeros((h, w, 3), np.uint8)
                img[obs[c] & ~est[c]] = DIFF_COLORS["observed_only"]
                img[est[c] & ~obs[c]] = DIFF_COLORS["estimate_only"]
                img[obs[c] & est[c]] = DIFF_COLORS["both"]
                rec.log(f"views/{name}/silhouette_diff", rr.Image(img))
        if self.images and frame.images is not None:
            for c, name in enumerate(names):
                small = cv2.resize(frame.images[c], (w, h), interpolation=cv2.INTER_AREA)
                rec.log(f"views/{name}/image", rr.Image(small).compress(jpeg_quality=80))
        if frame.detections is not None and len(frame.detections):
            det = frame.detections
            for c, name in enumerate(names):
                sel = det.view == c
                xy = (det.xy[sel] + 0.5) * (w / self.seq.rig.sizes[c][0]) - 0.5
                rec.log(f"views/{name}/detections", rr.Points2D(xy, radii=1.5, colors=[255, 0, 255]))

"""recording.level: each level's recording opens and holds what the level promises (the
module docstring of mocap/recording/rerun_sink.py), read back from the file; bad recording
settings give one line before any work; replay reads a new recording."""

import cv2
import numpy as np
import pytest
import rerun as rr

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.energy.silhouette import downscale_masks
from mocap.recording.reader import latest_at, read_recording
from mocap.recording.rerun_sink import RerunSink
from mocap.recording.settings import LEVELS, RecordingSettings, recording_settings
from mocap.recording.sink import RunInfo
from mocap.trackers.apf import AnnealTrace, LayerTrace
from mocap.trackers.base import Estimate
from mocap.trackers.diagnostics import LandmarkReport, StepDiagnostics
from mocap.trackers.run import frame_of

F, P = 4, 5          # frames, particles per layer


@pytest.fixture(scope="module")
def seq(body):
    rig = ring_rig(2, 3.5, 1.5, 96, 72, fov_deg=45, look_at=(0, 0, 0.9))
    return make_synthetic(body, rig, motion="walk", frames=F, fps=25, seed=0, images=True)


def record(body, seq, path, settings: RecordingSettings):
    """A recording of the ground truth as the estimate, with two annealing layers (with
    particles) and three landmarks per frame; returns what was logged per frame."""
    rng = np.random.default_rng(0)
    shaped = body.shaped(seq.gt.alpha)
    sink = RerunSink(path, settings)
    sink.start(RunInfo("x: 1", {"run_id": "levels"}), body, seq)
    logged = []
    for f in range(F):
        out = shaped.pose(seq.gt.chi[f])
        particles = [seq.gt.chi[f] + 0.01 * rng.standard_normal((P, body.num_dofs)) for _ in range(2)]
        layers = tuple(LayerTrace(3.0 - m, 4.0, 0.5, 0.5, 10.0, 0.2, particles=x)
                       for m, x in enumerate(particles))
        landmarks = out.joints[0][:3] + 0.01
        d = StepDiagnostics(energy_terms={"silhouette": 1.0 + f}, anneal=AnnealTrace(layers, 10),
                            landmarks=LandmarkReport(("a", "b", "c"), landmarks, {}, (), 0.5))
        sink.frame(frame_of(seq, f), Estimate(seq.gt.chi[f], seq.gt.alpha, d), out.joints[0], out.vertices[0],
                   seq.gt.joints[f], 10.0 + f, 0.1)
        logged.append((out, particles, landmarks))
    sink.finish({"tracker": "test", "frames": F, "mpjpe_mm": 11.5})
    return logged


def temporal_frames(path, entity: str, component: str) -> list[int]:
    """Frames at which ``entity`` has ``component`` on the frame timeline."""
    frames = []
    for chunk in rr.chunk.RrdReader(str(path)).stream():
        if chunk.entity_path == entity and not chunk.is_static:
            rb = chunk.to_record_batch()
            if component in rb.schema.names and "frame" in rb.schema.names:
                frames += [f for f, v in zip(rb.column("frame").to_pylist(), rb.column(component).to_pylist(),
                                             strict=True) if v is not None]
    return sorted(frames)


def test_summary_holds_scalars_and_the_final_body_only(body, seq, tmp_path):
    path = tmp_path / "summary.rrd"
    logged = record(body, seq, path, recording_settings({"level": "summary"}))
    info = read_recording(path)
    s = info["scalars"]
    assert s["/plots/error/mpjpe_mm"] == {f: 10.0 + f for f in range(F)}
    assert s["/plots/energy/silhouette"] == {f: 1.0 + f for f in range(F)}
    assert len(s[f"/plots/motion/chi/{body.dof_names[7]}"]) == F
    assert info["metrics"]["mpjpe_mm"] == 11.5 and "/run/config" in info["entities"]
    # the body: the last frame only
    assert temporal_frames(path, "/world/body/estimate", "Mesh3D:vertex_positions") == [F - 1]
    np.testing.assert_allclose(latest_at(path, "world/body/estimate", "Mesh3D:vertex_positions", F - 1),
                               logged[-1][0].vertices[0], atol=1e-5)
    assert temporal_frames(path, "/world/skeleton/truth", "LineStrips3D:strips") == [F - 1]
    assert not [e for e in info["entities"] if e.startswith(("/views/", "/world/particles", "/plots/layers"))]


def test_standard_holds_the_mesh_views_and_images_of_every_recorded_frame(body, seq, tmp_path):
    path = tmp_path / "standard.rrd"
    logged = record(body, seq, path, recording_settings({"level": "standard"}))
    info = read_recording(path)
    assert temporal_frames(path, "/world/body/estimate", "Mesh3D:vertex_positions") == list(range(F))
    for f in range(F):
        np.testing.assert_allclose(latest_at(path, "world/body/estimate", "Mesh3D:vertex_positions", f),
                                   logged[f][0].vertices[0], atol=1e-5)
        np.testing.assert_allclose(latest_at(path, "world/landmarks/estimate", "Points3D:positions", f),
                                   logged[f][2], atol=1e-5)
        strips = latest_at(path, "world/skeleton/estimate", "LineStrips3D:strips", f)
        J = logged[f][0].joints[0]
        np.testing.assert_allclose(strips[:, 1], J[1:], atol=1e-5)                 # bone ends
        np.testing.assert_allclose(strips[:, 0], J[body.parents[1:]], atol=1e-5)   # bone starts
    # the mesh topology once, static; only positions on the timeline
    assert latest_at(path, "world/body/estimate", "Mesh3D:triangle_indices", F - 1).shape == body.faces.shape
    assert temporal_frames(path, "/world/body/estimate", "Mesh3D:triangle_indices") == []
    # the silhouette difference: observed-only 1, estimate-only 2, both 3; its observed part is
    # the downscaled observed silhouette
    w, h = (int(v) for v in seq.rig.scaled(0.25).sizes[0])
    for f in (0, F - 1):
        diff = latest_at(path, "views/cam_01/silhouette_diff", "SegmentationImage:buffer", f)
        diff = diff.astype(np.uint8).reshape(h, w)
        obs = downscale_masks(frame_of(seq, f).masks, 0.25)[1]
        np.testing.assert_array_equal((diff & 1).astype(bool), obs)
        assert (diff == 3).sum() > 0.5 * obs.sum()         # the true pose covers most of it
        # the input image, downscaled and JPEG-encoded
        blob = latest_at(path, "views/cam_01/image", "EncodedImage:blob", f).astype(np.uint8)
        img = cv2.imdecode(blob, cv2.IMREAD_COLOR)[..., ::-1]
        small = cv2.resize(frame_of(seq, f).images[1], (w, h), interpolation=cv2.INTER_AREA)
        assert img.shape == (h, w, 3) and np.abs(img.astype(int) - small).mean() < 8
    assert "/plots/layers/beta" in info["entities"]
    assert not [e for e in info["entities"] if e.startswith("/world/particles")]
    assert sorted(info["scalars"]["/plots/error/mpjpe_mm"]) == list(range(F))


def test_full_adds_every_layers_particles_and_full_size_views(body, seq, tmp_path):
    path = tmp_path / "full.rrd"
    logged = record(body, seq, path, recording_settings({"level": "full"}))
    shaped = body.shaped(seq.gt.alpha)
    for m in range(2):
        entity = f"/world/particles/layer_{m:02d}"
        assert temporal_frames(path, entity, "Points3D:positions") == list(range(F))
        pts = latest_at(path, entity, "Points3D:positions", 2)
        np.testing.assert_allclose(pts, shaped.joints(logged[2][1][m]).reshape(-1, 3), atol=1e-5)
    W, H = (int(v) for v in seq.rig.sizes[0])
    assert latest_at(path, "views/cam_00/silhouette_diff", "SegmentationImage:buffer", 0).size == H * W


def test_every_and_particles_refine_the_level(body, seq, tmp_path):
    path = tmp_path / "every2.rrd"
    record(body, seq, path, recording_settings({"level": "standard", "every": 2, "particles": True}))
    assert temporal_frames(path, "/world/body/estimate", "Mesh3D:vertex_positions") == [0, 2]
    assert temporal_frames(path, "/world/particles/last", "Points3D:positions") == [0, 2]
    assert len(read_recording(path)["scalars"]["/plots/error/mpjpe_mm"]) == F     # plots: every frame


def test_levels_order_by_size(body, seq, tmp_path):
    sizes = {}
    for level in LEVELS:
        record(body, seq, tmp_path / f"{level}.rrd", recording_settings({"level": level}))
        sizes[level] = (tmp_path / f"{level}.rrd").stat().st_size
    assert sizes["summary"] < sizes["standard"] < sizes["full"], sizes


def test_settings_take_the_levels_defaults():
    assert recording_settings(None) == LEVELS["standard"]
    assert recording_settings({"level": "full", "every": None, "particles": None}).particles == "all"
    s = recording_settings({"level": "summary", "scale": 0.5, "enabled": False})
    assert (s.level, s.scale, s.enabled, s.keep_particles) == ("summary", 0.5, False, False)
    assert recording_settings({"particles": True}).keep_particles
    assert not recording_settings(None).keep_particles      # the default level keeps no particles


@pytest.mark.parametrize("setting, words", [
    ({"level": "bogus"}, ["recording.level", "'bogus'", "summary, standard, full"]),
    ({"level": "bogus", "enabled": False}, ["recording.level", "'bogus'"]),
    ({"every": 0}, ["recording.every", "0", ">= 1"]),
    ({"particles": "some"}, ["recording.particles", "'some'", "all"]),
    ({"scale": 0}, ["recording.scale", "0", "(0, 1]"]),
    ({"scale": 1.5}, ["recording.scale", "1.5"]),
    ({"images": "yes"}, ["recording.images", "'yes'"]),
    ({"levels": "full"}, ["recording.levels", "level"]),
])
def test_bad_recording_settings_name_the_setting(setting, words):
    with pytest.raises(ValueError) as e:
        recording_settings(setting)
    assert all(w in str(e.value) for w in words) and "\n" not in str(e.value)


def test_an_unknown_level_is_one_line_before_any_work(tmp_path, capsys):
    from mocap_cli.main import main

    run_dir = tmp_path / "run"
    got = main(["track", "tracker=apf", "data=walk_small", "data.frames=3", f"hydra.run.dir={run_dir}",
                "recording.level=bogus"])
    err = capsys.readouterr().err
    assert got == 2
    (line,) = [ln for ln in err.splitlines() if ln.strip()]
    assert line == ("mocap track: error: setting recording.level = 'bogus' is not allowed "
                    "(one of summary, standard, full)")
    assert not (run_dir / "metrics.json").exists() and not list(run_dir.glob("*.rrd*"))


def test_replay_summarises_a_new_recording(body, seq, tmp_path, capsys):
    from mocap_cli.commands.replay import main as replay

    path = tmp_path / "recording.rrd"
    record(body, seq, path, recording_settings({"level": "summary"}))
    assert replay([str(path), "--summary"]) == 0
    out = capsys.readouterr().out
    assert f"frames 0..{F - 1} ({F} logged)" in out and "/world/body/estimate" in out
    assert "mpjpe_mm: 11.5" in out


def test_a_failed_run_keeps_the_frames_gathered_so_far(body, seq, tmp_path):
    """Frames wait in a batch before they are sent: a run failing on frame 2 still leaves
    frames 0 and 1 in recording.failed.rrd (and no recording.rrd)."""
    sink = RerunSink(tmp_path / "recording.rrd", recording_settings(None))
    sink.start(RunInfo("x: 1", {"run_id": "failed"}), body, seq)
    shaped = body.shaped(seq.gt.alpha)
    for f in range(2):
        out = shaped.pose(seq.gt.chi[f])
        sink.frame(frame_of(seq, f), Estimate(seq.gt.chi[f], seq.gt.alpha, StepDiagnostics()), out.joints[0],
                   out.vertices[0], None, 20.0 + f, 0.1)
    sink.finish(None, failed=True)
    assert not (tmp_path / "recording.rrd").exists()
    path = tmp_path / "recording.failed.rrd"
    assert read_recording(path)["scalars"]["/plots/error/mpjpe_mm"] == {0: 20.0, 1: 21.0}
    assert temporal_frames(path, "/world/body/estimate", "Mesh3D:vertex_positions") == [0, 1]

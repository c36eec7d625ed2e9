"""Typed step diagnostics: flattening, the old dictionary view, and what reaches a recording."""

from dataclasses import dataclass

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.recording.reader import read_recording
from mocap.recording.rerun_sink import RerunSink
from mocap.recording.settings import RecordingSettings
from mocap.recording.sink import RunInfo
from mocap.trackers.apf import AnnealTrace, LayerTrace
from mocap.trackers.base import Estimate
from mocap.trackers.diagnostics import Misalignment, StepDiagnostics
from mocap.trackers.run import frame_of

LAYERS = (LayerTrace(3.0, 4.0, 0.5, 0.5, 10.0, 0.2), LayerTrace(1.0, 2.0, 2.0, 0.5, 10.0, 0.1))
DECISION = Misalignment(("l_elbow",), {"l_elbow": 0.4, "r_knee": 0.05}, apf_called=True,
                        free_dofs=("l_elbow_flex",))


def test_scalars_flatten_every_numeric_field_including_new_ones():
    @dataclass(frozen=True)
    class Extra:                      # a tracker adds its own report: its numbers are kept
        inliers: int = 7
        note: str = "text is not a scalar"

    @dataclass(frozen=True)
    class MyDiagnostics(StepDiagnostics):
        extra: Extra = Extra()

    d = MyDiagnostics(energy_terms={"silhouette": 2.0, "prior": 0.5}, timings={"search": 0.25},
                      misalignment=DECISION, anneal=AnnealTrace(LAYERS, 20))
    s = d.scalars()
    assert s["energy/silhouette"] == 2.0 and s["energy/total"] == 2.5 and s["timing/search"] == 0.25
    assert s["misalignment/limb_errors/l_elbow"] == 0.4 and s["misalignment/apf_called"] == 1.0
    assert s["misalignment/count"] == 1.0 and s["extra/inliers"] == 7.0
    assert not any(k.startswith("extra/note") for k in s)
    assert d.energy_evaluations == 20 and d.apf_called is True


def test_the_old_dictionary_view_reads_the_typed_fields():
    d = StepDiagnostics(energy_terms={"silhouette": 2.0}, anneal=AnnealTrace(LAYERS, 20),
                        misalignment=DECISION, ignored_views=("cam_01",))
    assert d["layers"]["beta"] == [0.5, 2.0] and d["energy_evaluations"] == 20
    assert d["misaligned_limbs"] == ["l_elbow"] and d["apf_called"] == 1
    assert d["apf_free_dofs"] == ["l_elbow_flex"] and d["ignored_views"] == ["cam_01"]
    assert "landmarks" not in d and d.get("landmarks") is None
    assert StepDiagnostics(misalignment=Misalignment(("x",))).get("apf_called") is None  # local


def test_misaligned_limbs_and_layers_reach_the_recording(body, tmp_path):
    rig = ring_rig(2, 3.5, 1.5, 64, 48, fov_deg=45, look_at=(0, 0, 0.9))
    seq = make_synthetic(body, rig, motion="walk", frames=2, fps=25, seed=0)
    sink = RerunSink(tmp_path / "recording.rrd", RecordingSettings(particles=False))
    sink.start(RunInfo("x: 1", {"run_id": "test"}), body, seq)
    out = body.shaped(seq.gt.alpha).pose(seq.gt.chi[1])
    est = Estimate(seq.gt.chi[1], seq.gt.alpha, StepDiagnostics(
        energy_terms={"silhouette": 2.0}, anneal=AnnealTrace(LAYERS, 20), misalignment=DECISION))
    sink.frame(frame_of(seq, 1), est, out.joints[0], out.vertices[0], None, None, 0.1)
    sink.finish({"ok": 1})
    info = read_recording(tmp_path / "recording.rrd")
    assert info["scalars"]["/plots/misalignment/limb_errors/l_elbow"] == {1: pytest.approx(0.4)}
    assert info["scalars"]["/plots/misalignment/apf_called"] == {1: 1.0}
    assert info["scalars"]["/plots/energy/total"] == {1: 2.0}
    assert "/log/decisions" in info["entities"] and "/plots/layers/energy_mean" in info["entities"]
    assert np.isfinite(list(info["scalars"]["/plots/timing/step"].values())).all()

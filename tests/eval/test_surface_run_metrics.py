"""A run on data with a true surface is scored on it (metrics.json keys of run_metrics)."""

import dataclasses

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data.generate import make_synthetic
from mocap.eval.run_metrics import accuracy_metrics


def test_a_run_on_data_with_a_surface_reports_the_surface_metrics(body):
    rig = ring_rig(3, 3.0, 1.2, 96, 72, fov_deg=50)
    seq = make_synthetic(body, rig, motion="walk", frames=2, fps=25, seed=2)
    verts = body.shaped(seq.gt.alpha).vertices(seq.gt.chi).astype(np.float64)
    seq = dataclasses.replace(seq, gt=dataclasses.replace(seq.gt, surface=verts,
                                                          surface_faces=np.asarray(body.faces)))
    exact = accuracy_metrics(body, seq, seq.gt.chi, seq.gt.alpha)
    assert exact["surface_to_mesh_mm"] == pytest.approx(0.0, abs=1e-3)
    assert exact["mesh_to_surface_mm"] == pytest.approx(0.0, abs=1e-3)
    assert exact["silhouette_iou"] > 0.97          # the masks: the same body, rendered by the generator
    assert exact["surface_oracle_mm"] < 1.0        # started from the truth's own shape and poses
    assert set(exact["silhouette_iou_per_view"]) == set(rig.names)
    moved = seq.gt.chi.copy()
    moved[:, 0] += 0.03                            # the root 3 cm along x
    off = accuracy_metrics(body, seq, moved, seq.gt.alpha)
    assert 5.0 < off["surface_to_mesh_mm"] < 30.0 and off["silhouette_iou"] < exact["silhouette_iou"]
    assert len(off["surface_per_frame"]["surface_to_mesh_mm"]) == 2

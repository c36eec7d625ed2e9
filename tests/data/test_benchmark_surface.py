"""The benchmarks' stored true surface: consistent with its sequence, and regenerated the same by
the build tooling (the latter only where the build extra, anny and torch, is installed)."""

from pathlib import Path

import numpy as np
import pytest

from mocap.data.sequence_io import load_ground_truth

ROOT = Path(__file__).resolve().parents[2] / "data"
FOLDERS = sorted(p.parent for p in [*ROOT.glob("mismatch/*/gt.npz"), *ROOT.glob("real_motion/*/*/gt.npz")])


@pytest.mark.parametrize("folder", FOLDERS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_benchmark_sequence_keeps_a_surface_around_its_joints(folder):
    gt = load_ground_truth(folder / "gt.npz", 60)
    assert gt.surface is not None and gt.surface.shape == (60, 2002, 3)
    assert gt.surface_faces.shape == (4000, 3)
    # the skin encloses the hips' centre and reaches the head's centre within a few cm
    centre = gt.joints[:, list(gt.joint_names).index("pelvis")]
    assert (np.linalg.norm(gt.surface - centre[:, None], axis=-1).min(axis=1) < 0.2).all()
    head = gt.joints[:, list(gt.joint_names).index("head")]
    assert (np.linalg.norm(gt.surface - head[:, None], axis=-1).min(axis=1) < 0.15).all()


def test_regeneration_keeps_the_stored_surface():
    pytest.importorskip("torch")
    pytest.importorskip("anny")
    from mocap_build.mismatch.procedural import SEQUENCES, load_anny, render
    from mocap_build.mismatch.surface import _surface_subset

    model = load_anny()
    a, b = _surface_subset(model, 4000), _surface_subset(model, 4000)
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.triangle, b.triangle)
    np.testing.assert_array_equal(a.bary, b.bary)
    r = render(SEQUENCES["walk"], model, masks=False)
    with np.load(ROOT / "mismatch" / "walk" / "gt.npz") as z:
        np.testing.assert_array_equal(a.faces, z["surface_faces"])
        np.testing.assert_allclose(a.points(r.faces, r.vertices), z["surface"], rtol=0, atol=1e-6)

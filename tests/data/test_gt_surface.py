"""gt.npz field ``surface`` (+ ``surface_faces``): kept by a round trip, bad input refused by
one line naming file, field and shape, before any image is read."""

import dataclasses

import numpy as np
import pytest

from mocap.cameras import ring_rig
from mocap.data import sequence_io
from mocap.data.generate import make_synthetic
from mocap.data.sequence_io import SequenceFormatError, load_sequence, write_sequence


@pytest.fixture(scope="module")
def folder(body, tmp_path_factory):
    rig = ring_rig(2, 3.0, 1.2, 64, 48, fov_deg=50)
    seq = make_synthetic(body, rig, motion="walk", frames=3, fps=25, seed=1)
    verts = body.shaped(seq.gt.alpha).vertices(seq.gt.chi).astype(np.float64)
    gt = dataclasses.replace(seq.gt, surface=verts, surface_faces=np.asarray(body.faces, np.int64))
    return write_sequence(dataclasses.replace(seq, gt=gt), tmp_path_factory.mktemp("s") / "seq")


def _with(folder, **fields):
    z = dict(np.load(folder / "gt.npz"))
    for k, v in fields.items():
        if v is None:
            z.pop(k, None)
        else:
            z[k] = v
    np.savez(folder / "gt.npz", **z)


def test_surface_round_trips(folder, body):
    seq = load_sequence(folder)
    assert seq.gt.surface.shape == (3, body.num_vertices, 3)
    np.testing.assert_array_equal(seq.gt.surface_faces, body.faces)


def test_surface_without_faces_is_accepted(folder, tmp_path):
    import shutil

    f = shutil.copytree(folder, tmp_path / "seq")
    _with(f, surface_faces=None)
    seq = load_sequence(f)
    assert seq.gt.surface_faces is None and seq.gt.surface.shape[0] == 3


@pytest.mark.parametrize("change, words", [
    (lambda s, fc: {"surface": s[..., :2]}, ["'surface'", "(3, ", ", 2)"]),
    (lambda s, fc: {"surface": s[0]}, ["'surface'", "shape"]),
    (lambda s, fc: {"surface": s[:2]}, ["'surface'", "(2, ", "2 frames", "3"]),
    (lambda s, fc: {"surface": np.where(np.arange(len(s[0]))[None, :, None] == 7, np.nan, s)},
     ["'surface'", "NaN", "point 7"]),
    (lambda s, fc: {"surface_faces": fc + len(s[0]) - fc.max()}, ["'surface_faces'", "out of range"]),
    (lambda s, fc: {"surface_faces": fc[:, :2]}, ["'surface_faces'", ", 2)"]),
    (lambda s, fc: {"surface_faces": fc.astype(float)}, ["'surface_faces'", "integers"]),
    (lambda s, fc: {"surface": None}, ["'surface_faces'", "without field 'surface'"]),
])
def test_bad_surface_is_refused_naming_file_field_and_shape_before_any_image(folder, tmp_path, monkeypatch,
                                                                            change, words):
    import shutil

    f = shutil.copytree(folder, tmp_path / "seq")
    z = np.load(f / "gt.npz")
    _with(f, **change(z["surface"], z["surface_faces"]))

    def no_images(*a, **k):
        raise AssertionError("images read before the ground truth was checked")

    monkeypatch.setattr(sequence_io, "_read_images", no_images)
    with pytest.raises(SequenceFormatError) as e:
        load_sequence(f)
    msg = str(e.value)
    assert "\n" not in msg and str(f / "gt.npz") in msg
    for w in words:
        assert w in msg, (w, msg)

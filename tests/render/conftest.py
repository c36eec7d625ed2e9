"""Posed body silhouettes seen by a small ring of pinhole cameras."""

from __future__ import annotations

import numpy as np
import pytest

from tests.render.pinhole import project, ring_cameras


@pytest.fixture(scope="session")
def body_views(body) -> dict:
    """3 particles (zero pose + 2 random poses) seen by 4 cameras at 500 px.

    pixels (3, 4, V, 2) float32, depth (3, 4, V), faces (F, 3)."""
    rng = np.random.default_rng(7)
    chi = body.zero_pose(3)
    chi[1:, 6:] = rng.normal(0.0, 0.3, (2, chi.shape[1] - 6))
    verts = body.shaped().pose(chi).vertices
    pixels, depth = project(verts, ring_cameras(4))
    return {"pixels": pixels.astype(np.float32), "depth": depth, "faces": body.faces,
            "size": 500}

"""The surface oracle recovers a known shape and pose of our own body from its surface."""

import numpy as np

from mocap.eval.surface_oracle import SurfaceOracleSettings, fit_surface_oracle, float64_body


def test_surface_oracle_recovers_a_known_shape_and_pose_of_our_body(body):
    rng = np.random.default_rng(3)
    b64 = float64_body(body)
    alpha = rng.uniform(-1.0, 1.0, body.num_shape)
    F = 2
    chi = np.zeros((F, body.num_dofs))
    chi[:, :3] = [0.2, -0.1, 0.0]
    lo, hi = body.limits[6:, 0], body.limits[6:, 1]
    chi[:, 6:] = np.clip(rng.uniform(-0.4, 0.4, (F, body.num_dofs - 6)), 0.7 * lo, 0.7 * hi)
    truth = b64.shaped(alpha).vertices(chi)                        # "the true surface": (F, V, 3)
    start_chi = chi + rng.normal(0, 0.05, chi.shape)
    start_alpha = alpha + rng.normal(0, 0.3, alpha.shape)
    s = SurfaceOracleSettings(stride=1, shape_frames=1, rounds=10, max_nfev=30, tol=1e-6, vertex_stride=2,
                              point_stride=1)
    fit = fit_surface_oracle(body, truth, np.asarray(body.faces), start_alpha, start_chi, s)
    start = b64.shaped(start_alpha).vertices(start_chi)
    start_mm = 1e3 * np.linalg.norm(start - truth, axis=-1).mean()
    got_mm = 1e3 * np.linalg.norm(b64.shaped(fit.alpha).vertices(fit.chi) - truth, axis=-1)
    rest_mm = 1e3 * np.abs(b64.rest(fit.alpha)[0] - b64.rest(alpha)[0]).max()
    m = fit.metrics
    print(f"start {start_mm:.1f} mm -> surface {m['surface_to_mesh_mm']:.2f} / "
          f"{m['mesh_to_surface_mm']:.2f} mm, "
          f"vertices {got_mm.mean():.2f} (max {got_mm.max():.1f}) mm, rest mesh {rest_mm:.1f} mm")
    assert start_mm > 20.0                                     # the start was 2+ cm off
    assert m["surface_to_mesh_mm"] < 1.0 and m["mesh_to_surface_mm"] < 1.0, m
    assert got_mm.mean() < 2.0                                 # each vertex back where it was
    assert rest_mm < 10.0                                      # the shape: its rest mesh
    np.testing.assert_allclose(fit.chi[:, 6:], chi[:, 6:], atol=0.1)
    assert list(fit.frames) == [0, 1]

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
    s = SurfaceOracleSettings(stride=1, shape_frames=2, rounds=8, max_nfev=30, tol=1e-6, vertex_stride=2,
                              point_stride=1)
    fit = fit_surface_oracle(body, truth, np.asarray(body.faces), start_alpha, start_chi, s)
    m = fit.metrics
    assert m["surface_to_mesh_mm"] < 0.5 and m["mesh_to_surface_mm"] < 0.5, m
    start = b64.shaped(start_alpha).vertices(start_chi)
    assert np.linalg.norm(start - truth, axis=-1).mean() > 0.02      # the start was 2+ cm off
    got = b64.shaped(fit.alpha).vertices(fit.chi)
    assert np.linalg.norm(got - truth, axis=-1).max() < 0.005          # every vertex back within 5 mm
    rest_err = np.abs(b64.rest(fit.alpha)[0] - b64.rest(alpha)[0]).max()
    assert rest_err < 0.005, rest_err                                  # the shape: its rest mesh
    np.testing.assert_allclose(fit.chi[:, 6:], chi[:, 6:], atol=0.05)
    assert list(fit.frames) == [0, 1]

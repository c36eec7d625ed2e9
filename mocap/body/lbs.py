"""Linear blend skinning (Zhang et al. 2013, Eq. 2): v'_i = sum_j w_ij (G_j v_i).

For a shape shared by all particles the blend is one matrix product: with the basis
Phi[i, 4j + b] = w_ij * (v_i, 1)_b, posed coordinate a of vertex i in particle p is
sum_{j,b} Phi[i, 4j+b] G[p, j, a, b], i.e. (P*3, 4J) @ (4J, V).
"""

from __future__ import annotations

import numpy as np


def lbs_basis(weights: np.ndarray, rest_vertices: np.ndarray) -> np.ndarray:
    """Phi: weights (V, J), rest_vertices (V, 3) -> (4J, V), the transposed basis."""
    V, J = weights.shape
    homog = np.concatenate([rest_vertices, np.ones((V, 1), rest_vertices.dtype)], axis=1)
    phi = weights[:, :, None] * homog[:, None, :]                 # (V, J, 4)
    return np.ascontiguousarray(phi.reshape(V, 4 * J).T)


def lbs_apply(basis_t: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """Skinned vertices from a precomputed basis.

    basis_t: (4J, V) from :func:`lbs_basis`; transforms: (P, J, 4, 4) -> (P, V, 3).
    """
    P, J = transforms.shape[:2]
    M = transforms[:, :, :3, :].transpose(0, 2, 1, 3).reshape(P * 3, 4 * J)
    out = M.astype(basis_t.dtype, copy=False) @ basis_t          # (P*3, V)
    return out.reshape(P, 3, -1).transpose(0, 2, 1)


def lbs(weights: np.ndarray, rest_vertices: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """Reference LBS for per-particle rest meshes.

    weights: (V, J); rest_vertices: (V, 3) or (P, V, 3); transforms: (P, J, 4, 4) -> (P, V, 3).
    """
    P, J = transforms.shape[:2]
    blended = (weights @ transforms[:, :, :3, :].transpose(1, 0, 2, 3).reshape(J, -1))
    blended = blended.reshape(-1, P, 3, 4).transpose(1, 0, 2, 3)  # (P, V, 3, 4)
    rest = np.broadcast_to(rest_vertices, (P,) + rest_vertices.shape[-2:])
    out = blended[..., 3].copy()
    for b in range(3):
        out += blended[..., b] * rest[..., b, None]
    return out

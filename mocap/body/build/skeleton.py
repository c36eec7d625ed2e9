"""Skeleton reduction and rest joints as functions of the shape coefficients."""

from __future__ import annotations

import numpy as np


def reduce_weights(weights: np.ndarray, owner: np.ndarray, num_joints: int) -> np.ndarray:
    """Sum skinning weights of source bones into the joints that own them.

    weights: (V, B) rows summing to 1; owner: (B,) joint index per bone -> (V, J).
    """
    out = np.zeros((weights.shape[0], num_joints))
    for b, j in enumerate(owner):
        out[:, j] += weights[:, b]
    return out / out.sum(axis=1, keepdims=True)


def nearest_owned_ancestor(parents: np.ndarray, defining: dict[int, int]) -> np.ndarray:
    """For each source bone, the joint whose defining bone is its nearest ancestor-or-self.

    parents: (B,) source parent indices (-1 root); defining: source bone -> joint index.
    """
    owner = np.full(len(parents), -1, dtype=np.int64)
    for b in range(len(parents)):
        a = b
        while a not in defining:
            a = parents[a]
            if a < 0:
                raise ValueError(f"source bone {b} has no defining ancestor")
        owner[b] = defining[a]
    return owner


def fit_linear(alpha: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares affine map targets ~ mean + sum_k alpha_k basis_k.

    alpha: (N, K); targets: (N, *S) -> mean (*S), basis (K, *S).
    """
    n = len(alpha)
    A = np.concatenate([np.ones((n, 1)), alpha], axis=1)
    coef, *_ = np.linalg.lstsq(A, targets.reshape(n, -1), rcond=None)
    shape = targets.shape[1:]
    return coef[0].reshape(shape), coef[1:].reshape(len(alpha[0]), *shape)


def fit_vertex_regressor(meshes: np.ndarray, joints: np.ndarray, num_vertices: int = 32,
                         ridge: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Each joint as a weighted sum of its nearest mesh vertices (like SMPL's J_regressor).

    meshes: (N, V, 3); joints: (N, J, 3) -> index (J, R) int, weight (J, R). Weights are
    shared by x, y, z and fitted over the whole database with a small ridge, constrained
    to sum to one (translation equivariance) by fitting offsets from the vertex centroid.
    """
    mean_mesh, mean_joints = meshes.mean(axis=0), joints.mean(axis=0)
    J = joints.shape[1]
    index = np.zeros((J, num_vertices), dtype=np.int64)
    weight = np.zeros((J, num_vertices))
    for j in range(J):
        idx = np.argsort(np.linalg.norm(mean_mesh - mean_joints[j], axis=1))[:num_vertices]
        X = meshes[:, idx, :]                                   # (N, R, 3)
        c = X.mean(axis=1, keepdims=True)
        A = (X - c).transpose(0, 2, 1).reshape(-1, num_vertices)  # (N*3, R)
        b = (joints[:, j, :] - c[:, 0, :]).reshape(-1)
        # w = 1/R + z with sum(z) = 0: solve in the null space of the ones vector.
        Q = np.linalg.qr(np.concatenate([np.ones((num_vertices, 1)),
                                          np.eye(num_vertices)[:, :-1]], axis=1))[0][:, 1:]
        AQ = A @ Q
        z = np.linalg.solve(AQ.T @ AQ + ridge * np.eye(num_vertices - 1), AQ.T @ b)
        index[j], weight[j] = idx, 1.0 / num_vertices + Q @ z
    return index, weight


def apply_vertex_regressor(meshes: np.ndarray, index: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Joints of meshes (N, V, 3) from a vertex regressor -> (N, J, 3)."""
    return np.einsum("njrc,jr->njc", meshes[:, index, :], weight)

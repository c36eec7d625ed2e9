"""PCA of a database of registered meshes (Zhang et al. 2013, Eq. 1)."""

from __future__ import annotations

import numpy as np


def learn_pca(meshes: np.ndarray, num_components: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, principal directions and their standard deviations.

    meshes: (N, V, 3) registered rest meshes -> mean (V, 3), components (K, V, 3) orthonormal
    as flattened vectors, stddev (K,) (sample standard deviation along each direction).
    """
    meshes = np.asarray(meshes, dtype=np.float64)
    n, v, _ = meshes.shape
    if num_components > min(n - 1, 3 * v):
        raise ValueError(f"cannot learn {num_components} components from {n} meshes")
    mean = meshes.mean(axis=0)
    X = (meshes - mean).reshape(n, -1)
    _, s, vt = np.linalg.svd(X, full_matrices=False)
    stddev = s[:num_components] / np.sqrt(n - 1)
    components = vt[:num_components].reshape(num_components, v, 3)
    return mean, components, stddev


def project(meshes: np.ndarray, mean: np.ndarray, components: np.ndarray,
            stddev: np.ndarray) -> np.ndarray:
    """Standardised coefficients alpha of meshes (N, V, 3) -> (N, K)."""
    X = (np.asarray(meshes, dtype=np.float64) - mean).reshape(len(meshes), -1)
    return (X @ components.reshape(len(components), -1).T) / stddev


def reconstruct(alpha: np.ndarray, mean: np.ndarray, components: np.ndarray,
                stddev: np.ndarray) -> np.ndarray:
    """Meshes from standardised coefficients: alpha (N, K) -> (N, V, 3)."""
    flat = (np.asarray(alpha) * stddev) @ components.reshape(len(components), -1)
    return mean + flat.reshape(len(alpha), *mean.shape)

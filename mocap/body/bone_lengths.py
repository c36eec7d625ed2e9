"""Plausibility of a fitted body size: the PCA shape model's spread of every bone length.

The shape coefficients alpha are standardised (alpha ~ N(0, I) over the training bodies),
and the rest landmarks are linear in them (:func:`mocap.body.catalogue.rest_point_basis`:
R(alpha) = R0 + sum_k alpha_k B_k). To first order the length of a bone (i, j) is
l(alpha) = l0 + g . alpha with g_k = u_ij . (B_ki - B_kj), u_ij the unit bone direction, so its
standard deviation over the model's bodies is |g|. A fitted shape is *plausible* when every
bone length lies within ``n_sigma`` of its mean: l0 +- n_sigma |g| (the bounds the start-up
fit and the run's quality flags check).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LengthModel:
    """pairs: (B, 2) landmark (or joint) index pairs; mean: (B,) lengths at alpha = 0 (m);
    sigma: (B,) their standard deviation over the shape model (m)."""

    pairs: np.ndarray
    mean: np.ndarray
    sigma: np.ndarray

    def lengths(self, points: np.ndarray) -> np.ndarray:
        """(B,) lengths of the pairs in points (..., N, 3) -> (..., B)."""
        p = np.asarray(points, np.float64)
        return np.linalg.norm(p[..., self.pairs[:, 0], :] - p[..., self.pairs[:, 1], :], axis=-1)

    def z_scores(self, lengths: np.ndarray) -> np.ndarray:
        """(..., B) (l - mean) / sigma; NaN lengths stay NaN."""
        return (np.asarray(lengths, np.float64) - self.mean) / np.maximum(self.sigma, 1e-6)

    def implausible(self, lengths: np.ndarray, n_sigma: float = 3.0) -> np.ndarray:
        """(..., B) bool: lengths outside mean +- n_sigma sigma (NaN: not implausible)."""
        z = self.z_scores(lengths)
        return np.abs(np.nan_to_num(z)) > n_sigma


def length_model(rest0: np.ndarray, basis: np.ndarray, pairs: np.ndarray) -> LengthModel:
    """Linearised bone-length model of the module docstring. rest0: (N, 3) rest points at
    alpha = 0; basis: (K, N, 3) metres per standardised coefficient; pairs: (B, 2)."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    v = rest0[pairs[:, 0]] - rest0[pairs[:, 1]]
    mean = np.linalg.norm(v, axis=1)
    u = v / np.maximum(mean, 1e-12)[:, None]
    g = np.einsum("bc,kbc->bk", u, basis[:, pairs[:, 0]] - basis[:, pairs[:, 1]])
    return LengthModel(pairs, mean, np.linalg.norm(g, axis=1))


def skeleton_length_model(body) -> tuple[LengthModel, list[str]]:
    """The length model of the body's bones (joint -> parent) and their names
    ("parent-child")."""
    K = body.num_shape
    _, joints = body.rest(np.vstack([np.zeros(K), np.eye(K)]))             # (K+1, J, 3)
    joints = np.asarray(joints, np.float64)
    child = np.array([j for j, p in enumerate(body.parents) if p >= 0])
    pairs = np.stack([np.asarray(body.parents)[child], child], axis=1)
    model = length_model(joints[0], joints[1:] - joints[0], pairs)
    names = [f"{body.joint_names[a]}-{body.joint_names[b]}" for a, b in pairs]
    return model, names


def shrink_to_bounds(body, alpha: np.ndarray, model: LengthModel, n_sigma: float,
                     steps: int = 200) -> tuple[np.ndarray, float]:
    """The largest scaling s alpha (s in [0, 1], on a grid of ``steps``) whose bones (``model``:
    :func:`skeleton_length_model`) all lie within mean +- ``n_sigma`` sigma; returns
    (s alpha, s). A fit that the measurements push past the model's bounds keeps its direction
    (a tall subject stays tall) instead of falling back to the mean shape."""
    s = np.linspace(1.0, 0.0, steps + 1)
    _, joints = body.rest(s[:, None] * np.asarray(alpha, np.float64)[None])
    ok = ~model.implausible(model.lengths(np.asarray(joints, np.float64)), n_sigma).any(axis=1)
    k = int(np.argmax(ok))                                   # the first (largest) s inside the bounds
    return s[k] * np.asarray(alpha, np.float64), float(s[k])

"""A batched trust-region minimiser of a noisy energy on a quadratic model of its samples: the
two-cue shape fit's last step (``keypoints.two_cue.quadratic``, :mod:`mocap.trackers.two_cue_shape`).

The two-cue energy is a smooth bone-length term plus a rasterised silhouette term whose
curvature points elsewhere: its valley runs diagonally to any fixed coordinates, and the
silhouettes' pixel noise stops coordinate-wise line searches (Powell's) short of its floor
(docs/results/surface.md, "The two-cue hybrid's proportions": 20 % of the way from the fit to the
joint oracle's lengths lowered the energy that Powell had stopped on). Here every iteration

1. samples ``samples`` points in the ball of radius r about the current point (one batch of the
   energy, which takes (P, n) -> (P,)),
2. fits a full quadratic (1 + n + n (n + 1) / 2 coefficients) to them by least squares (which
   averages the noise the samples see),
3. takes the model's Newton step (its Hessian's eigenvalues floored at a small share of the
   largest, so that the step is one of descent) cut to the ball, and evaluates the energy at
   fractions of it (a second batch),
4. moves to the best of those when it lowers the energy (r grows by half), else stays and
   halves r.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: the fractions of the model's step evaluated in each iteration's second batch
STEP_FRACTIONS = (0.25, 0.5, 0.75, 1.0, 1.5)


def quadratic_features(d: np.ndarray) -> np.ndarray:
    """(P, n) offsets -> (P, 1 + n + n (n + 1) / 2): 1, d_i, d_i d_j (i <= j)."""
    i, j = np.triu_indices(d.shape[1])
    return np.hstack([np.ones((len(d), 1)), d, d[:, i] * d[:, j]])


def fit_quadratic(d: np.ndarray, e: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The least-squares quadratic e ~ c + g.d + d^T H d / 2 of samples at offsets ``d`` (P, n)
    with values ``e`` (P,): (c, g (n,), H (n, n) symmetric)."""
    n = d.shape[1]
    coef, *_ = np.linalg.lstsq(quadratic_features(d), e, rcond=None)
    c, g, q = float(coef[0]), coef[1:n + 1], coef[n + 1:]
    i, j = np.triu_indices(n)
    H = np.zeros((n, n))
    H[i, j] = q
    H = H + H.T          # d^T H d / 2 = sum_{i<=j} q_ij d_i d_j: off the diagonal q_ij = H_ij, on it H_ii / 2
    return c, g, H


def newton_step(g: np.ndarray, H: np.ndarray, radius: float, floor: float = 1e-6) -> np.ndarray:
    """The model's minimiser -H^-1 g with H's eigenvalues floored at ``floor`` x the largest
    (at least 1e-12), cut to length ``radius``."""
    lam, V = np.linalg.eigh(H)
    lam = np.maximum(lam, max(floor * float(np.abs(lam).max()), 1e-12))
    step = -(V / lam) @ (V.T @ g)
    length = float(np.linalg.norm(step))
    return step if length <= radius else step * (radius / length)


def quadratic_polish(energy: Callable[[np.ndarray], np.ndarray], x: np.ndarray, radius: float,
                     iterations: int, rng: np.random.Generator, samples: int | None = None,
                     lower: np.ndarray | None = None, upper: np.ndarray | None = None
                     ) -> tuple[np.ndarray, float, dict]:
    """Minimise ``energy`` ((P, n) -> (P,)) from ``x`` (n,) by the module docstring's iterations,
    starting radius ``radius``; ``samples`` per model (None: twice its coefficients); points are
    kept within ``lower`` / ``upper`` (n,) where given. Returns (x, energy(x), report: the
    energy at the start and the iterations that moved)."""
    x = np.asarray(x, np.float64).copy()
    n = len(x)
    lo = np.full(n, -np.inf) if lower is None else np.asarray(lower, np.float64)
    hi = np.full(n, np.inf) if upper is None else np.asarray(upper, np.float64)
    m = samples or 2 * (1 + n + n * (n + 1) // 2)
    e = float(energy(x[None])[0])
    report = {"start": e, "moved": 0}
    r = float(radius)
    for _ in range(iterations):
        u = rng.normal(size=(m, n))
        u *= (rng.random(m) ** (1.0 / n) / np.linalg.norm(u, axis=1))[:, None]    # uniform in the ball
        pts = np.clip(x + r * u, lo, hi)
        c, g, H = fit_quadratic(pts - x, energy(pts))
        step = newton_step(g, H, r)
        tries = np.clip(x + np.outer(STEP_FRACTIONS, step), lo, hi)
        values = energy(tries)
        k = int(np.argmin(values))
        if values[k] < e:
            x, e = tries[k], float(values[k])
            report["moved"] += 1
            r *= 1.5
        else:
            r *= 0.5
    return x, e, report

"""
The Kalman measurement update: Joseph form, an innovation gate, consider states.

Plain numpy on small matrices, no knowledge of what the states mean: the estimator passes
the innovation, its Jacobian and the states that must not be corrected.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

__all__ = ['Update', 'inverse_small', 'update']


@dataclass(frozen=True)
class Update:
    """The result of an update: the new state and covariance, and the Mahalanobis distance."""

    x: np.ndarray
    p: np.ndarray
    distance: float


def inverse_small(s: np.ndarray) -> np.ndarray | None:
    """
    Return the inverse of a 1x1..3x3 innovation covariance (cofactors), or None if singular.

    numpy's inv costs more in argument checks than the arithmetic for these sizes; larger
    matrices go to it.
    """
    n = s.shape[0]
    if n == 3:
        (a, b, c), (d, e, f), (g, h, i) = s.tolist()
        c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
        det = a * c00 + b * c01 + c * c02
        if det == 0.0 or not math.isfinite(det):
            return None
        k = 1.0 / det
        return np.array([[c00 * k, (c * h - b * i) * k, (b * f - c * e) * k],
                         [c01 * k, (a * i - c * g) * k, (c * d - a * f) * k],
                         [c02 * k, (b * g - a * h) * k, (a * e - b * d) * k]])
    if n == 2:
        (a, b), (c, d) = s.tolist()
        det = a * d - b * c
        if det == 0.0 or not math.isfinite(det):
            return None
        k = 1.0 / det
        return np.array([[d * k, -b * k], [-c * k, a * k]])
    if n == 1:
        v = float(s[0, 0])
        return None if v == 0.0 or not math.isfinite(v) else np.array([[1.0 / v]])
    try:
        return np.linalg.inv(s)
    except np.linalg.LinAlgError:
        return None


def update(x: np.ndarray, p: np.ndarray, y: np.ndarray, h: np.ndarray, r: np.ndarray, *,
           gate: float = 0.0, consider: Sequence[int] = ()) -> Update | None:
    """
    Return the update of x, P by the innovation y = z − h(x̂) with Jacobian H and noise R.

    None when the innovation covariance is singular or anything is not finite. With
    ``gate`` > 0 and a Mahalanobis distance √(yᵀS⁻¹y) beyond it, the state is returned
    unchanged with the distance negated. ``consider`` states get a zero gain (Schmidt-Kalman):
    not corrected, their covariance unchanged, their cross-covariances consistent. Joseph
    form P = (I − KH) P (I − KH)ᵀ + K R Kᵀ (valid for any gain), symmetrised.
    """
    ph = p @ h.T
    s = h @ ph + r
    s_inv = inverse_small(s)
    if s_inv is None:
        return None
    d2 = float(y @ s_inv @ y)
    if not math.isfinite(d2):
        return None
    distance = math.sqrt(max(d2, 0.0))
    if gate > 0.0 and distance > gate:
        return Update(x, p, -distance)
    k = ph @ s_inv
    for i in consider:
        k[i, :] = 0.0
    x_new = x + k @ y
    ikh = np.eye(x.size) - k @ h
    p_new = ikh @ p @ ikh.T + k @ r @ k.T
    p_new += p_new.T
    p_new *= 0.5
    if not math.isfinite(float(x_new.sum()) + float(p_new.sum())):
        return None
    return Update(x_new, p_new, distance)

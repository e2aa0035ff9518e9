"""The per-step exchange of the co-simulation: extrapolation polynomials and one numba kernel.

Each macro step the string side needs the hammer motion over the step as a
polynomial (Jacobi: extrapolated through the last communication points;
Gauss–Seidel: interpolated through the new value), and the hammer holds the
mean over the step of the interface force extrapolated the same way.  Both
use the actual spacing of the communication points (a shorter last step,
adaptive steps).  :func:`_exchange` builds the polynomial, steps the string
exactly (:mod:`hammerbit.cosim.string_side`; the kernels live in
:mod:`hammerbit.model.string_step`, which the Drillstring FMU carries), and returns the interface force, the
energy residual of the step and the force defect ``F_held - mean F_i``.
"""
from __future__ import annotations

import numpy as np

from hammerbit.model.string_step import coefficients, exchange_step, held_force, held_weights

__all__ = ["extrapolation_weights"]


def extrapolation_weights(order: int, ratio: float = 1.0, ratio_past: float = 1.0) -> np.ndarray:
    """Weights on (F_n, F_{n-1}, F_{n-2}) of the mean over [t_n, t_n + h] of the
    extrapolation polynomial of the given order.

    ``ratio = h / (t_n - t_{n-1})`` and ``ratio_past = (t_{n-1} - t_{n-2}) / (t_n - t_{n-1})``;
    with uniform steps (both 1) these are the Adams–Bashforth weights.
    """
    w = np.zeros(3)
    _held_weights(order, 1.0, ratio_past, ratio, w)
    return w


#: the exchange kernels (:mod:`hammerbit.model.string_step`, shared with the Drillstring FMU)
_held_weights = held_weights
_held_force = held_force
_coefficients = coefficients
_exchange = exchange_step

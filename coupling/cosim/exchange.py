"""The per-step exchange of the co-simulation: extrapolation polynomials and the exchange kernel.

Each macro step the string side needs the hammer motion over the step as a
polynomial (Jacobi: extrapolated through the last communication points;
Gauss–Seidel: interpolated through the new value), and the hammer holds the
mean over the step of the interface force extrapolated the same way.  Both
use the actual spacing of the communication points (a shorter last step,
adaptive steps).  :func:`exchange_step` builds the polynomial, steps the string
exactly (:mod:`hammerbit.cosim.string_side`; the kernels are those of
:mod:`hammerbit.model.string_kernels`, which the Drillstring FMU carries), and returns the interface force, the
energy residual of the step and the force defect ``F_held - mean F_i``.  Its arguments are
records (:class:`ExchangeScheme`, :class:`Interface`, :class:`ModalForm` or :class:`DenseForm`,
:class:`ExchangeHistory`, :class:`HammerStep`), documented in :mod:`hammerbit.model.string_kernels`.
"""
from __future__ import annotations

import numpy as np

from hammerbit.model.string_kernels import (HAMMER_ARG, DenseForm, ExchangeHistory, ExchangeScheme, HammerStep,
                                            Interface, ModalForm, exchange_kernel, exchange_step, held_force,
                                            held_weights, taylor_coefficients)

__all__ = ["HAMMER_ARG", "extrapolation_weights", "held_force", "exchange_step", "exchange_kernel",
           "taylor_coefficients", "ExchangeScheme", "Interface", "ModalForm", "DenseForm", "ExchangeHistory", "HammerStep",
           "EXCHANGE_OUT_FORCE", "EXCHANGE_OUT_ENERGY_RESIDUAL", "EXCHANGE_OUT_STRING_FORCE", "EXCHANGE_OUT_DEFECT"]

#: Slots of :func:`exchange_step`'s ``hist.out``: the interface force at the step's end [N], the
#: energy residual of the step [J], ``frow . xi`` (the string's part of the interface force) [N]
#: and the force defect ``F_held - mean F_i`` [N].
EXCHANGE_OUT_FORCE, EXCHANGE_OUT_ENERGY_RESIDUAL, EXCHANGE_OUT_STRING_FORCE, EXCHANGE_OUT_DEFECT = 0, 1, 2, 3


def extrapolation_weights(order: int, ratio: float = 1.0, ratio_past: float = 1.0) -> np.ndarray:
    """Weights on (F_n, F_{n-1}, F_{n-2}) of the mean over [t_n, t_n + h] of the
    extrapolation polynomial of the given order.

    ``ratio = h / (t_n - t_{n-1})`` and ``ratio_past = (t_{n-1} - t_{n-2}) / (t_n - t_{n-1})``;
    with uniform steps (both 1) these are the Adams–Bashforth weights.
    """
    w = np.zeros(3)
    held_weights(order, 1.0, ratio_past, ratio, w)
    return w


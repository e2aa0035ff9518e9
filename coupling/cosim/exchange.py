"""The per-step exchange of the co-simulation: extrapolation polynomials and one numba kernel.

Each macro step the string side needs the hammer motion over the step as a
polynomial (Jacobi: extrapolated through the last communication points;
Gauss–Seidel: interpolated through the new value), and the hammer holds the
mean over the step of the interface force extrapolated the same way.  Both
use the actual spacing of the communication points (a shorter last step,
adaptive steps).  :func:`exchange_step` builds the polynomial, steps the string
exactly (:mod:`hammerbit.cosim.string_side`), and returns the interface force, the
energy residual of the step and the force defect ``F_held - mean F_i``.
"""
from __future__ import annotations

import numpy as np
from numba import njit as _njit

from hammerbit.cosim.string_side import string_step_dense, string_step_modal

__all__ = ["extrapolation_weights", "held_force", "exchange_step", "taylor_coefficients", "EXCHANGE_OUT_FORCE",
           "EXCHANGE_OUT_ENERGY_RESIDUAL", "EXCHANGE_OUT_STRING_FORCE", "EXCHANGE_OUT_DEFECT"]

#: Slots of :func:`exchange_step`'s ``out``: the interface force at the step's end [N], the
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
    _held_weights(order, 1.0, ratio_past, ratio, w)
    return w


# ---------------------------------------------------------------------------
# per-step exchange kernels (numba): coefficients, exact string step, residual
# ---------------------------------------------------------------------------


@_njit(cache=True)
def _held_weights(order, a, a2, h, w):
    """Weights on (F_n, F_{n-1}, F_{n-2}) of the mean over [t_n, t_n + h] of the
    polynomial of degree ``order`` through them; ``a = t_n - t_{n-1}``,
    ``a2 = t_{n-1} - t_{n-2}`` (Newton form)."""
    if order == 0:
        w[0], w[1], w[2] = 1.0, 0.0, 0.0
    elif order == 1:
        r = 0.5 * h / a
        w[0], w[1], w[2] = 1.0 + r, -r, 0.0
    else:
        m2 = h * h / 3.0 + 0.5 * a * h          # mean of s (s + a) over [0, h]
        q = 1.0 / (a + a2)
        w[0] = 1.0 + 0.5 * h / a + m2 * q / a
        w[1] = -0.5 * h / a - m2 * q * (1.0 / a + 1.0 / a2)
        w[2] = m2 * q / a2


@_njit(cache=True)
def held_force(order, th, Fh, h, w):
    """The force the hammer holds over [t_n, t_n + h]: :func:`_held_weights` on the history."""
    _held_weights(order, th[0] - th[1], th[1] - th[2], h, w)
    return w[0] * Fh[0] + w[1] * Fh[1] + w[2] * Fh[2]


@_njit(cache=True)
def taylor_coefficients(gs, order, a, a2, h, wh, x_new, v_new, c):
    """Taylor coefficients (x, v, x', v', x'', v'') at t_n of the hammer motion over
    the step ``h``: Jacobi extrapolates through the history ``wh`` (t_n, t_{n-1},
    t_{n-2}; spacings ``a``, ``a2``), Gauss–Seidel interpolates through the new value."""
    for k in range(2):
        w0 = wh[0, k]
        w1 = wh[1, k]
        w2 = wh[2, k]
        wn = x_new if k == 0 else v_new
        c[k] = w0
        c[2 + k] = 0.0
        c[4 + k] = 0.0
        if not gs:
            if order == 1:
                c[2 + k] = (w0 - w1) / a
            elif order == 2:
                f01 = (w0 - w1) / a
                f012 = (f01 - (w1 - w2) / a2) / (a + a2)
                c[2 + k] = f01 + f012 * a
                c[4 + k] = 2.0 * f012
        else:
            if order == 0:
                c[k] = wn
            elif order == 1:
                c[2 + k] = (wn - w0) / h
            else:
                f0h = (wn - w0) / h
                f3 = (f0h - (w0 - w1) / a) / (h + a)
                c[2 + k] = f0h - f3 * h
                c[4 + k] = 2.0 * f3


@_njit(cache=True)
def exchange_step(gs, order, h, modal, P, xi, buf, tmp, d, G, irow, icol, eta, frow, ki, ci, W,
                  th, wh, Fh, x_new, v_new, F_held, c, out):
    """One macro step of the string side after the hammer's step.

    ``th`` (3,): communication times t_n, t_{n-1}, t_{n-2}; ``wh`` (3, 2): hammer
    (x deviation, v) at those times; ``Fh`` (3,): interface forces.  Builds the
    Taylor coefficients of the hammer motion, advances the string (modal ``eta``
    or dense ``xi``), shifts the histories and writes ``out = [F(t_{n+1}), energy
    residual of the step, frow.xi at t_{n+1}, force defect F_held - mean F_i]``;
    ``out[2]`` on entry is ``frow.xi`` at ``t_n``.
    """
    a = th[0] - th[1]
    a2 = th[1] - th[2]
    taylor_coefficients(gs, order, a, a2, h, wh, x_new, v_new, c)
    F_start = W + out[2] - ki * c[0] - ci * c[1]
    if modal:
        imp, f_xi = string_step_modal(d, G, irow, icol, eta, c, frow)
    else:
        n = xi.shape[0]
        for k in range(6):
            buf[n + k] = c[k]
        imp = string_step_dense(P, xi, buf, tmp)
        f_xi = 0.0
        for i in range(n):
            f_xi += frow[i].real * xi[i]
    xe = c[0] + c[2] * h + 0.5 * c[4] * h * h
    ve = c[1] + c[3] * h + 0.5 * c[5] * h * h
    F_end = W + f_xi - ki * xe - ci * ve
    e_string = 0.5 * h * (F_start * c[1] + F_end * ve)
    e_hammer = F_held * (x_new - wh[0, 0])
    F = W + f_xi - ki * x_new - ci * v_new
    for j in (2, 1):
        th[j] = th[j - 1]
        wh[j, 0] = wh[j - 1, 0]
        wh[j, 1] = wh[j - 1, 1]
        Fh[j] = Fh[j - 1]
    th[0] = th[0] + h
    wh[0, 0] = x_new
    wh[0, 1] = v_new
    Fh[0] = F
    out[0] = F
    out[1] = e_string - e_hammer
    out[2] = f_xi
    out[3] = F_held - (W + imp / h)

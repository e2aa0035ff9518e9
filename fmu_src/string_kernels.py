"""The numba kernels of the string side: its exact step and its per-step exchange with the hammer.

The exact step advances the string's state over a step (:func:`string_step_modal`,
:func:`string_step_dense`; :class:`string_step.ExactStep` builds their matrices).  Each macro
step ``[t_n, t_n + h]`` of a Jacobi or Gauss-Seidel scheme the string side takes the hammer
motion as a polynomial (Taylor coefficients, :func:`taylor_coefficients`), steps exactly, and
gives the interface force at ``t_{n+1}``, the energy residual of the step and the force defect
``F_held - mean F_i``; the hammer holds, over the next step, the mean of the interface force
extrapolated the same way (:func:`held_mean`).

Every kernel here calls only kernels of this module: numba's cache entry of a kernel holds its
callees' code, and numba invalidates it on a change of the kernel's own file only.

The exchange's arguments are records (named tuples of arrays and scalars, which numba
compiles as such): :class:`ExchangeScheme` and :class:`Interface` fixed for a run, a
:class:`ModalForm` or :class:`DenseForm` per step length, the :class:`ExchangeHistory` it
shifts, and the :class:`HammerStep` of each step.  The co-simulation master's lanes
(``hammerbit.cosim.lane``), the ``Drillstring`` FMU (:mod:`string_slave`) and its native
flavour (``hammerbit.fmu.native_string_kernels``) all step through these kernels.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator)

__all__ = ["N_COEFFS", "HAMMER_ARG", "EXCHANGE_HELD", "DENSE_LANES", "string_step_dense", "string_step_modal",
           "held_weights", "held_weight_values", "held_mean", "held_force", "taylor_coefficients",
           "exchange_step", "exchange_kernel", "exchange_step_modal", "exchange_step_dense", "exchange_begin",
           "exchange_end", "ExchangeScheme", "Interface", "ModalForm", "DenseForm", "ExchangeHistory",
           "HammerStep", "HISTORY_SPACING", "continue_polynomial"]


#: Taylor coefficients of the hammer motion over a step: (x, v, x', v', x'', v'')
N_COEFFS = 6
#: position of the :class:`HammerStep` in the exchange's arguments (the one new every step)
HAMMER_ARG = 5
#: the held force of a next step of the same length in the exchange's returned tuple
EXCHANGE_HELD = 3
#: in the FMI form (a user's master drives the string FMU), a step shorter than this fraction of
#: the history's newest spacing (a master's leftover step to land on an output point) replaces
#: the newest point instead of shifting the history: divided differences over a tiny spacing
#: would amplify the rounding of the hammer's motion.  The library's own adaptive master never
#: takes leftover steps, and its short steps after a rejection are real steps whose new input
#: the extrapolation must go through, so the rule is the FMI form's only
HISTORY_SPACING = 1e-2


@njit(cache=True)
def is_leftover(scheme, h, newest_spacing):
    """Whether a step of length ``h`` is a master's leftover step (see :data:`HISTORY_SPACING`)."""
    return scheme.fmi and h < HISTORY_SPACING * newest_spacing


# ---------------------------------------------------------------------------
# the exact step
# ---------------------------------------------------------------------------
#: independent partial sums of the dense step's dot products (a fixed order: see string_step_dense)
DENSE_LANES = 4


@njit(cache=True)
def string_step_dense(P, xi, buf, tmp):
    """xi <- P[:n] [xi, c]; returns int (F_i - W) dt (row n).  ``buf[n:]`` holds c.

    Each dot product sums in :data:`DENSE_LANES` fixed partial sums, without fastmath: the
    order does not depend on the CPU's vector width, so every machine (and the native FMU,
    compiled for the baseline x86-64) gets the same bits, while the lanes keep the loop fast.
    The auto-driller's dense step turns a last-bit difference of its state into 1e-7 N of force."""
    n = xi.shape[0]
    m = buf.shape[0]
    for i in range(n):
        buf[i] = xi[i]
    # P @ buf by hand: no BLAS call (its thread pool costs more than this small mat-vec)
    m4 = m - m % DENSE_LANES
    for i in range(n + 1):
        row = P[i]                     # a contiguous row: the loads vectorise without reordering
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        a3 = 0.0
        for k in range(0, m4, DENSE_LANES):
            a0 += row[k] * buf[k]
            a1 += row[k + 1] * buf[k + 1]
            a2 += row[k + 2] * buf[k + 2]
            a3 += row[k + 3] * buf[k + 3]
        for k in range(m4, m):
            a0 += row[k] * buf[k]
        tmp[i] = (a0 + a1) + (a2 + a3)
    for i in range(n):
        xi[i] = tmp[i]
    return tmp[n]


@njit(cache=True)
def string_step_modal(d, G, irow, icol, eta, c, frow):
    """eta <- d * eta + G c (modal exact step); returns (int (F_i - W) dt, Re(frow . eta) after
    the step), the second in the same pass."""
    imp = 0.0
    for k in range(6):
        imp += icol[k] * c[k]
    f_xi = 0.0
    for i in range(eta.shape[0]):
        e0 = eta[i]
        imp += (irow[i] * e0).real
        e = d[i] * e0
        # G c with c real: its real and imaginary parts apart (a complex product would also
        # multiply by c's zero imaginary part, which numba cannot drop without fastmath)
        er = e.real
        ei = e.imag
        for k in range(6):
            g = G[i, k]
            er += g.real * c[k]
            ei += g.imag * c[k]
        e = complex(er, ei)
        eta[i] = e
        f_xi += (frow[i] * e).real
    return imp, f_xi


# ---------------------------------------------------------------------------
# the records
# ---------------------------------------------------------------------------
class ExchangeScheme(NamedTuple):
    """How the string side takes the hammer motion over a step (fixed for a run)."""

    #: True: Gauss-Seidel (the polynomial interpolates through the hammer's new value); False: Jacobi
    gauss_seidel: bool
    #: degree of the extrapolation polynomial: 0, 1 or 2
    order: int
    #: True: the force at the step's end takes the step's own polynomial (what a string FMU outputs)
    fmi: bool
    #: True: the hammer motion's derivatives at t_n (``coeffs[2:]``: x', v', x'', v'') are given by
    #: the caller (the hammer's output derivatives, FMI input derivatives), not extrapolated
    given: bool = False


class Interface(NamedTuple):
    """The interface spring-dashpot, the static load and a feed top (fixed for a run)."""

    #: interface stiffness [N/m]
    ki: float
    #: interface damping [N s/m]
    ci: float
    #: weight on bit of the static equilibrium [N]
    wob: float
    #: (2,): ``(V [m/s], t0 [s])`` of a feed top: its block moves as ``V (t - t0)``; ``V = 0``: a
    #: fixed hook, or an auto-driller whose block is a state of the string side
    feed: np.ndarray


class ModalForm(NamedTuple):
    """The string's exact step over one step length in modal form, and the state it advances."""

    #: (m,) complex: ``exp(lam h)`` of the kept modes
    d: np.ndarray
    #: (m, 6) complex: the modes' response to the Taylor coefficients
    G: np.ndarray
    #: (m,) complex: ``int (F_i - W) dt`` over the step from the modes
    irow: np.ndarray
    #: (6,): ... and from the coefficients
    icol: np.ndarray
    #: (m,) complex: the modal state (advanced in place)
    eta: np.ndarray
    #: (m,) complex: ``frow`` on the modes (weight 2 on a conjugate pair's kept half)
    frow: np.ndarray


class DenseForm(NamedTuple):
    """The string's exact step over one step length in dense form, and the state it advances."""

    #: (n + 1, n + 6): maps ``[xi, c]`` to ``[xi, int (F_i - W) dt]``
    P: np.ndarray
    #: (n,): the state (advanced in place)
    xi: np.ndarray
    #: (n + 6,): scratch
    buf: np.ndarray
    #: (n + 1,): scratch
    tmp: np.ndarray
    #: (n,): ``F_i - W = frow . xi - k_i x_h - c_i v_h``
    frow: np.ndarray


class ExchangeHistory(NamedTuple):
    """The exchange's histories (shifted each step), its outputs and its scratch."""

    #: (3,): communication times t_n, t_{n-1}, t_{n-2} [s]
    th: np.ndarray
    #: (3, 2): hammer (x deviation [m], v [m/s]) at those times
    wh: np.ndarray
    #: (3,): interface forces at those times [N]
    Fh: np.ndarray
    #: (4,): ``[F(t_{n+1}), energy residual of the step, frow.xi at t_{n+1}, force defect
    #: F_held - mean F_i]``; ``out[2]`` on entry is ``frow.xi`` at ``t_n``
    out: np.ndarray
    #: (6,): the Taylor coefficients of the hammer motion over a step; after it, its polynomial
    #: re-expanded at t_{n+1} (a leftover step takes it on)
    coeffs: np.ndarray


class HammerStep(NamedTuple):
    """What the hammer did over the step: its new motion and the force it held."""

    #: hammer position at t_{n+1}, deviation from the static equilibrium [m]
    x_new: float
    #: hammer velocity at t_{n+1} [m/s]
    v_new: float
    #: the interface force the hammer held over the step [N]
    F_held: float


# ---------------------------------------------------------------------------
# the held force and the polynomial of the hammer motion
# ---------------------------------------------------------------------------
@njit(cache=True)
def held_weight_values(order, a, a2, h):
    """Weights ``(w0, w1, w2)`` on (F_n, F_{n-1}, F_{n-2}) of the mean over [t_n, t_n + h] of the
    polynomial of degree ``order`` through them; ``a = t_n - t_{n-1}``,
    ``a2 = t_{n-1} - t_{n-2}`` (Newton form)."""
    if order == 0:
        return 1.0, 0.0, 0.0
    if order == 1:
        r = 0.5 * h / a
        return 1.0 + r, -r, 0.0
    m2 = h * h / 3.0 + 0.5 * a * h          # mean of s (s + a) over [0, h]
    q = 1.0 / (a + a2)
    return (1.0 + 0.5 * h / a + m2 * q / a,
            -0.5 * h / a - m2 * q * (1.0 / a + 1.0 / a2),
            m2 * q / a2)


@njit(cache=True)
def held_weights(order, a, a2, h, w):
    """:func:`held_weight_values` into ``w`` (3,)."""
    w[0], w[1], w[2] = held_weight_values(order, a, a2, h)


@njit(cache=True)
def held_mean(order, th, Fh, h):
    """The force the hammer holds over [t_n, t_n + h]: the mean of the polynomial through the
    history (``th`` times, ``Fh`` forces, newest first)."""
    w0, w1, w2 = held_weight_values(order, th[0] - th[1], th[1] - th[2], h)
    return w0 * Fh[0] + w1 * Fh[1] + w2 * Fh[2]


@njit(cache=True)
def held_force(order, th, Fh, h, w):
    """:func:`held_mean`, its weights left in ``w`` (3,)."""
    held_weights(order, th[0] - th[1], th[1] - th[2], h, w)
    return w[0] * Fh[0] + w[1] * Fh[1] + w[2] * Fh[2]


@njit(cache=True)
def taylor_coefficients(gs, order, a, a2, h, wh, x_new, v_new, c):
    """Taylor coefficients (x, v, x', v', x'', v'') at t_n of the hammer motion over
    the step ``h``: Jacobi extrapolates through the history ``wh`` (t_n, t_{n-1},
    t_{n-2}; spacings ``a``, ``a2``), Gauss-Seidel interpolates through the new value."""
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


# ---------------------------------------------------------------------------
# the exchange
# ---------------------------------------------------------------------------
@njit(cache=True)
def continue_polynomial(c, s):
    """Taylor coefficients ``c`` of a polynomial motion re-expanded ``s`` later (in place)."""
    for k in range(2):
        c[k] = c[k] + c[2 + k] * s + 0.5 * c[4 + k] * s * s
        c[2 + k] = c[2 + k] + c[4 + k] * s


@njit(cache=True)
def exchange_begin(scheme, h, iface, hist, hammer):
    """The first half of :func:`exchange_step`: the Taylor coefficients of the hammer motion
    relative to a feed's block into ``hist.coeffs``; returns ``(u_top, F_start)``, the block's
    position at t_n and the interface force at t_n.  A leftover step (shorter than
    :data:`HISTORY_SPACING` of the newest spacing) takes the last step's polynomial on (the
    coefficients :func:`exchange_end` left at t_n): its new input is no point to extrapolate
    through.  With ``scheme.given`` the derivatives in ``hist.coeffs[2:]`` (absolute, as the hammer
    gives them) are the polynomial's, set by the caller before each step."""
    th, c = hist.th, hist.coeffs
    a = th[0] - th[1]
    a2 = th[1] - th[2]
    V = iface.feed[0]
    u_top = V * (th[0] - iface.feed[1])
    if not is_leftover(scheme, h, a):
        if scheme.given:                   # the motion's value at t_n; its derivatives as given
            c[0] = hist.wh[0, 0]
            c[1] = hist.wh[0, 1]
        else:
            taylor_coefficients(scheme.gauss_seidel, scheme.order, a, a2, h, hist.wh, hammer.x_new,
                                hammer.v_new, c)
        c[0] -= u_top
        c[1] -= V
        c[2] -= V
    F_start = iface.wob + hist.out[2] - iface.ki * c[0] - iface.ci * c[1]
    return u_top, F_start


@njit(cache=True)
def exchange_end(scheme, h, iface, hist, hammer, u_top, F_start, imp, f_xi):
    """The second half of :func:`exchange_step`, after the string's step (``imp`` its
    ``int (F_i - W) dt``, ``f_xi`` its ``frow . xi`` at the end): the interface force, the
    energy residual and the force defect into ``hist.out``; the histories shifted.  Returns
    :func:`exchange_step`'s ``(F, residual, defect, held)``."""
    c, th, wh, Fh, out = hist.coeffs, hist.th, hist.wh, hist.Fh, hist.out
    ki, ci, W, V = iface.ki, iface.ci, iface.wob, iface.feed[0]
    x_new, v_new, F_held = hammer.x_new, hammer.v_new, hammer.F_held
    xe = c[0] + c[2] * h + 0.5 * c[4] * h * h
    ve = c[1] + c[3] * h + 0.5 * c[5] * h * h
    F_end = W + f_xi - ki * xe - ci * ve
    e_string = 0.5 * h * (F_start * (c[1] + V) + F_end * (ve + V))
    e_hammer = F_held * (x_new - wh[0, 0])
    F = F_end if scheme.fmi else W + f_xi - ki * (x_new - (u_top + V * h)) - ci * (v_new - V)
    # a leftover step (shorter than HISTORY_SPACING of the newest spacing) moves the newest point
    # instead of adding one: the history keeps spacings that divided differences can take
    shift = not is_leftover(scheme, h, th[0] - th[1])
    if shift:
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
    # after a leftover step the next step is one of the run's own length: the newest spacing
    h_next = h if shift else th[0] - th[1]
    continue_polynomial(c, h)              # the step's polynomial at t_{n+1}: a leftover takes it on
    return F, out[1], out[3], held_mean(scheme.order, th, Fh, h_next)


@njit(cache=True)
def exchange_step_modal(scheme, h, form, iface, hist, hammer):
    """:func:`exchange_step` on a :class:`ModalForm`."""
    u_top, F_start = exchange_begin(scheme, h, iface, hist, hammer)
    imp, f_xi = string_step_modal(form.d, form.G, form.irow, form.icol, form.eta, hist.coeffs, form.frow)
    return exchange_end(scheme, h, iface, hist, hammer, u_top, F_start, imp, f_xi)


@njit(cache=True)
def exchange_step_dense(scheme, h, form, iface, hist, hammer):
    """:func:`exchange_step` on a :class:`DenseForm`."""
    u_top, F_start = exchange_begin(scheme, h, iface, hist, hammer)
    xi, buf, frow, c = form.xi, form.buf, form.frow, hist.coeffs
    n = xi.shape[0]
    for k in range(N_COEFFS):
        buf[n + k] = c[k]
    imp = string_step_dense(form.P, xi, form.buf, form.tmp)
    f_xi = 0.0
    for i in range(n):
        f_xi += frow[i] * xi[i]
    return exchange_end(scheme, h, iface, hist, hammer, u_top, F_start, imp, f_xi)


def exchange_kernel(form):
    """The compiled :func:`exchange_step` of a string form (:class:`ModalForm` or :class:`DenseForm`)."""
    return exchange_step_modal if isinstance(form, ModalForm) else exchange_step_dense


def exchange_step(scheme: ExchangeScheme, h: float, form, iface: Interface, hist: ExchangeHistory,
                  hammer: HammerStep) -> tuple:
    """One macro step of the string side after the hammer's step.

    Builds the Taylor coefficients of the hammer motion over ``[t_n, t_n + h]`` from the
    histories ``hist`` (Jacobi extrapolates, Gauss-Seidel interpolates through the hammer's
    new value ``hammer``), advances the string (``form``: a :class:`ModalForm` or a
    :class:`DenseForm` over ``h``), shifts the histories and writes ``hist.out``.  The hammer
    motion the string sees is relative to a feed's block (``iface.feed``): an exact
    polynomial whatever the extrapolation order.

    ``scheme.fmi``: the interface force at ``t_{n+1}`` takes the hammer motion of the
    step's own polynomial at ``t_{n+1}`` instead of the new value: what a string FMU can
    output at the end of its step, whose inputs a fixed-step master sets only before the
    next step.  A stepping loop calls :func:`exchange_kernel` once instead (this dispatch
    per call costs a lookup).

    A step shorter than :data:`HISTORY_SPACING` times the newest spacing of the history (a
    master's leftover step to land on an output point) takes the last step's polynomial on
    instead of one through its new input, and moves the newest point of the history to
    ``t_{n+1}`` instead of shifting it: the next step's divided differences then span the run's
    own spacing, not the leftover, and the run is the run without the leftover.

    Returns ``(F, residual, defect, held)``: ``hist.out``'s interface force, energy residual and
    force defect, and :func:`held_mean` over a next step of the same length ``h`` (a loop with a
    fixed step needs no other call for the force the hammer holds; after a leftover step, of
    the length of the newest spacing).
    """
    return exchange_kernel(form)(scheme, h, form, iface, hist, hammer)


"""Exact step of a linear string side over any communication step (closed form per mode).

The string side is the drillstring plus the interface spring-dashpot
``(k_i, c_i)`` to the hammer.  Its state ``xi`` (deviation from the static
equilibrium) obeys ``xi' = A1 xi + E w(s)`` with ``w = (x_h, v_h)`` the hammer
motion (deviation, velocity).  Over a step ``[t_n, t_n + h]`` the hammer motion
is a polynomial of degree <= 2 given by its Taylor coefficients
``c = (x, v, x', v', x'', v'')`` at ``t_n``.  Appending the coefficients as a
nilpotent chain and the time integral of the interface force as one more
state gives one autonomous linear system; its matrix exponential maps
``[xi_n, c]`` exactly to ``[xi_{n+1}, int (F_i - W) dt]``.  With
``A1 = V diag(lam) V^-1`` the step is ``eta <- exp(lam h) eta + G c`` per mode
(one of each conjugate pair kept): O(n) per step.

This module is the one source of that step: the co-simulation master's string
side (``hammerbit.cosim.string_side``) and the ``Drillstring`` FMU
(:mod:`string_slave`) both use :class:`ExactStep`, :class:`StringState` and
the kernels below, including :func:`exchange_step`, the per-step exchange of a
Jacobi or Gauss-Seidel scheme (coefficients, string step, interface force,
energy residual, force defect).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Optional

import contextlib

import numpy as np
from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator)

__all__ = ["ExactStep", "Discretisation", "StringState", "string_step_dense", "string_step_modal",
           "held_weights", "held_weight_values", "held_mean", "held_force", "taylor_coefficients", "exchange_step",
           "exchange_kernel",
           "exchange_step_modal", "exchange_step_dense", "exchange_begin", "exchange_end", "ExchangeScheme",
           "Interface", "ModalForm", "DenseForm", "ExchangeHistory", "HammerStep", "N_COEFFS",
           "MODAL_TOLERANCE", "step_key", "one_blas_thread"]

#: Taylor coefficients of the hammer motion over a step: (x, v, x', v', x'', v'')
N_COEFFS = 6
#: the modal form is used when the eigenbasis reproduces the dense step to this (relative)
MODAL_TOLERANCE = 1e-10
#: significant digits of a step length in the cache key (steps that differ by rounding share one)
_KEY_DIGITS = 12
#: squaring depth: a step h may be built from a cached step h / 2^k, k up to this
_MAX_SQUARINGS = 12


def one_blas_thread():
    """The string's dense linear algebra on one BLAS thread (a context): a 441-state eigenproblem
    is several times slower with the default thread pool on a loaded machine, and one thread
    gives the same bits in every process."""
    try:
        from threadpoolctl import threadpool_limits  # noqa: PLC0415 -- optional in an FMU's host
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def step_key(h: float) -> float:
    """Cache key of a step length [s]: ``h`` to 12 significant digits."""
    return float(f"{h:.{_KEY_DIGITS}g}")


@dataclass
class Discretisation:
    """The exact step over ``h``: dense ``P`` (n + 1 rows: xi and int (F_i - W) dt) and,
    when the eigenbasis reproduces it, the modal form."""

    h: float
    P: np.ndarray
    modal: bool = False
    m_d: Optional[np.ndarray] = None
    m_G: Optional[np.ndarray] = None
    m_irow: Optional[np.ndarray] = None
    m_icol: Optional[np.ndarray] = None


class ExactStep:
    """The exact step of a string side ``(A1, E, frow)`` over any step length (cached per length).

    Parameters
    ----------
    A1 : ndarray (n, n)
        State matrix with the interface closed on a fixed hammer.
    E : ndarray (n, 2)
        Input matrix of the hammer motion ``(x_h, v_h)``.
    frow : ndarray (n,)
        ``F_i - W = frow . xi - k_i x_h - c_i v_h``.
    ki, ci : float
        Interface stiffness [N/m] and damping [N s/m].
    rows3 : ndarray (3, n)
        Output rows: string bottom displacement, velocity, top tension.
    hook_eq : float
        Hook load of the equilibrium [N] (added to the tension row).
    dense : bool
        Never use the modal form.
    feed : (2,) array, optional
        ``(V, t0)`` of a feed top: the block moves down as ``V (t - t0)`` and the string's
        state is relative to it (default: no feed).

    Subclasses may override :meth:`decompose` and :meth:`exponential` (the library
    remembers them across sides built from the same matrices).
    """

    def __init__(self, A1, E, frow, ki: float, ci: float, rows3, hook_eq: float, *, dense: bool = False,
                 feed=None):
        self.A1 = np.ascontiguousarray(A1, dtype=float)
        self.E = np.ascontiguousarray(E, dtype=float)
        self.frow = np.ascontiguousarray(frow, dtype=float)
        self.ki, self.ci = float(ki), float(ci)
        self.rows3 = np.ascontiguousarray(rows3, dtype=float)
        self.hook_eq = float(hook_eq)
        self.feed = np.zeros(2) if feed is None else np.asarray(feed, dtype=float).copy()
        self.n = self.A1.shape[0]
        self._disc = {}
        self._phi = {}                # step length -> expm(Z h) (the squaring base of longer steps)
        self._eig = None
        self.modal = False if dense else None    # decided at the first discretisation
        self.m_Vinv = None

    # -- hooks -----------------------------------------------------------------
    def decompose(self):
        """``(lam, V, V^-1)`` of ``A1`` (raises ``LinAlgError`` when it has none)."""
        with one_blas_thread():
            lam, V = np.linalg.eig(self.A1)
            return lam, V, np.linalg.inv(V)

    def exponential(self, Z: np.ndarray, h: float) -> np.ndarray:
        """``expm(Z h)``."""
        import scipy.linalg as sla  # noqa: PLC0415 -- a slow import, needed only here
        with one_blas_thread():
            return sla.expm(Z * h)

    def eigen(self):
        """:meth:`decompose`, once; False when ``A1`` has no eigenbasis."""
        if self._eig is None:
            try:
                self._eig = self.decompose()
            except np.linalg.LinAlgError:
                self._eig = False
        return self._eig

    # -- discretisation ------------------------------------------------------
    def discretisation(self, h: float) -> Discretisation:
        """The exact step over ``h`` [s] (cached by :func:`step_key`)."""
        key = step_key(h)
        d = self._disc.get(key)
        if d is None:
            with one_blas_thread():
                d = self._disc[key] = self._discretise(key)
        return d

    def _discretise(self, h: float) -> Discretisation:
        """``expm(Z h)``; by squaring ``expm(Z h 2^-k)`` when a step ``h 2^-k`` is cached
        (the adaptive step and the companion use powers of two: one ``expm`` for all)."""
        n = self.n
        N = n + N_COEFFS + 1
        Phi = None
        for k in range(1, _MAX_SQUARINGS + 1):
            base = self._phi.get(step_key(h / 2 ** k))
            if base is not None:
                Phi = base
                for _ in range(k):
                    Phi = Phi @ Phi
                break
        if Phi is None:
            Z = np.zeros((N, N))
            Z[:n, :n] = self.A1
            Z[:n, n:n + 2] = self.E
            Z[n:n + 2, n + 2:n + 4] = np.eye(2)
            Z[n + 2:n + 4, n + 4:n + 6] = np.eye(2)
            Z[N - 1, :n] = self.frow
            Z[N - 1, n:n + 2] = (-self.ki, -self.ci)
            Phi = self.exponential(Z, h)
        self._phi[step_key(h)] = Phi
        rows = np.r_[np.arange(n), N - 1]
        d = Discretisation(h=h, P=np.ascontiguousarray(Phi[np.ix_(rows, np.arange(n + N_COEFFS))]))
        self._modal(Phi, h, d)
        return d

    def _modal(self, Phi: np.ndarray, h: float, d: Discretisation) -> None:
        """Diagonal (modal) form of the exact step: O(n) per step instead of O(n^2).

        Decided once, at the first step length: used only when the eigenvector
        basis reproduces the dense step to :data:`MODAL_TOLERANCE` (otherwise
        every step is the dense ``P``)."""
        n = self.n
        if self.modal is False:
            return
        eig = self.eigen()
        if eig is False:
            self.modal = False
            return
        lam, V, Vinv = eig
        ex = np.exp(lam * h)
        if self.modal is None:
            recon = (V * ex[None, :]) @ Vinv
            scale = max(np.max(np.abs(Phi[:n, :n])), 1.0)
            tol = 1e-12 * max(np.max(np.abs(lam)), 1.0)
            if (not np.all(np.isfinite(recon)) or np.max(np.abs(recon - Phi[:n, :n])) > MODAL_TOLERANCE * scale
                    or np.count_nonzero(lam.imag > tol) != np.count_nonzero(lam.imag < -tol)):
                self.modal = False
                return
            # A1 is real: its complex modes come in conjugate pairs, whose two halves
            # carry conjugate states.  Keep one of each pair with weight 2 on every
            # real output (and the real modes with weight 1): half the work.
            keep = np.flatnonzero((lam.imag > tol) | (np.abs(lam.imag) <= tol))
            wgt = np.where(lam[keep].imag > tol, 2.0, 1.0)
            Vk_w = V[:, keep] * wgt[None, :]
            self.modal_keep = keep
            self.m_frow = np.ascontiguousarray(self.frow @ Vk_w)
            self.m_rows3 = np.ascontiguousarray(np.vstack([r @ Vk_w for r in self.rows3]))
            self.m_V = Vk_w                       # xi = Re(m_V @ eta)
            self.m_Vinv = Vinv[keep]              # eta = m_Vinv @ xi
            self.modal = True
        keep = self.modal_keep
        N = n + N_COEFFS + 1
        d.modal = True
        d.m_d = np.ascontiguousarray(ex[keep])
        d.m_G = np.ascontiguousarray((Vinv @ Phi[:n, n:n + N_COEFFS])[keep])
        d.m_irow = np.ascontiguousarray(Phi[N - 1, :n] @ self.m_V)    # int (F_i - W) dt from eta
        d.m_icol = np.ascontiguousarray(Phi[N - 1, n:n + N_COEFFS])   # ... and from the coefficients


class StringState:
    """The state of one run on an :class:`ExactStep`: modal ``eta`` when it has a modal form, else ``xi``.

    ``h_first`` is the first step length (it decides the form)."""

    def __init__(self, side: ExactStep, h_first: float, xi0: Optional[np.ndarray] = None):
        self.side = side
        xi0 = np.zeros(side.n) if xi0 is None else np.asarray(xi0, dtype=float)
        side.discretisation(h_first)       # decides the form
        self.modal = bool(side.modal)
        if self.modal:
            self.eta = (side.m_Vinv @ xi0).astype(np.complex128)
            self.v = self.eta
        else:
            self.v = xi0.copy()
        self.buf = np.zeros(side.n + N_COEFFS)
        self.tmp = np.zeros(side.n + 1)
        self.c = np.zeros(N_COEFFS)

    def xi(self) -> np.ndarray:
        return (self.side.m_V @ self.v).real if self.modal else self.v.copy()

    def f_xi(self) -> float:
        """frow . xi: the string's share of F_i - W [N]."""
        s = self.side
        if self.modal:
            return float((s.m_frow @ self.v).real)
        return float(s.frow @ self.v)

    def outputs(self, t: Optional[float] = None) -> np.ndarray:
        """(displacement deviation [m], velocity [m/s]) of the string's bottom node and the
        hook load [N] at time ``t`` [s] (it places a feed's block), in one product."""
        s = self.side
        o = (s.m_rows3 @ self.v).real if self.modal else s.rows3 @ self.v
        o[2] += s.hook_eq
        V, t0 = s.feed
        if V != 0.0 and t is not None:
            o[0] += V * (t - t0)
            o[1] += V
        return o

    def copy_state(self):
        return self.v.copy()

    def restore(self, v) -> None:
        self.v[:] = v

    def advance(self, d: Discretisation, coeffs: np.ndarray) -> float:
        """Advance with given coefficients; returns int (F_i - W) dt [N s]."""
        if self.modal:
            return string_step_modal(d.m_d, d.m_G, d.m_irow, d.m_icol, self.v, coeffs, self.side.m_frow)[0]
        self.buf[self.side.n:] = coeffs
        return string_step_dense(d.P, self.v, self.buf, self.tmp)


# ---------------------------------------------------------------------------
# kernels
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
        for k in range(6):
            e += G[i, k] * c[k]
        eta[i] = e
        f_xi += (frow[i] * e).real
    return imp, f_xi


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
# the exchange: its records and kernels
# ---------------------------------------------------------------------------
class ExchangeScheme(NamedTuple):
    """How the string side takes the hammer motion over a step (fixed for a run)."""

    #: True: Gauss-Seidel (the polynomial interpolates through the hammer's new value); False: Jacobi
    gauss_seidel: bool
    #: degree of the extrapolation polynomial: 0, 1 or 2
    order: int
    #: True: the force at the step's end takes the step's own polynomial (what a string FMU outputs)
    fmi: bool


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
    #: (6,): scratch for the Taylor coefficients
    coeffs: np.ndarray


class HammerStep(NamedTuple):
    """What the hammer did over the step: its new motion and the force it held."""

    #: hammer position at t_{n+1}, deviation from the static equilibrium [m]
    x_new: float
    #: hammer velocity at t_{n+1} [m/s]
    v_new: float
    #: the interface force the hammer held over the step [N]
    F_held: float


@njit(cache=True)
def exchange_begin(scheme, h, iface, hist, hammer):
    """The first half of :func:`exchange_step`: the Taylor coefficients of the hammer motion
    relative to a feed's block into ``hist.coeffs``; returns ``(u_top, F_start)``, the block's
    position at t_n and the interface force at t_n."""
    th, c = hist.th, hist.coeffs
    a = th[0] - th[1]
    a2 = th[1] - th[2]
    taylor_coefficients(scheme.gauss_seidel, scheme.order, a, a2, h, hist.wh, hammer.x_new, hammer.v_new, c)
    V = iface.feed[0]
    u_top = V * (th[0] - iface.feed[1])
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
    return F, out[1], out[3], held_mean(scheme.order, th, Fh, h)


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

    Returns ``(F, residual, defect, held)``: ``hist.out``'s interface force, energy residual and
    force defect, and :func:`held_mean` over a next step of the same length ``h`` (a loop with a
    fixed step needs no other call for the force the hammer holds).
    """
    return exchange_kernel(form)(scheme, h, form, iface, hist, hammer)

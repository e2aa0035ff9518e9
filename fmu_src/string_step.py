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

Steps of any length.  A run carries the exponentials of its *built* steps
(:data:`BUILT_STEPS`; scipy's ``expm``, as above).  A step within
:data:`BUILT_STEP_MATCH` (relative) of one uses that step's exponentials; any
other gets its own, computed by the kernels of :mod:`string_exponentials`
(:func:`step_exponentials`):

* the modal form in closed form per mode (:func:`modal_exponentials`): each
  kept mode is a scalar system ``eta' = lam eta + b . w(s)``, so its step is
  ``exp(lam h)`` and ``phi_k(lam h)`` functions of the polynomial input, with
  no product by ``V`` or ``V^-1``.  The modal form is used at all only where it
  is well conditioned: :meth:`ExactStep._modal` accepts it when ``V e^(lam h)
  V^-1`` reproduces ``expm(A1 h)`` to :data:`MODAL_TOLERANCE` (relative to its
  largest entry) at the first built step and the eigenvalues pair up as
  conjugates.  The eigenbasis enters a step of any length only through the
  input map ``V^-1 E`` and the output rows ``. V``, both fixed for the run and
  checked there; the per-mode exponentials themselves are exact to rounding.
* the dense form by scaling and squaring the [13/13] Pade approximant of
  ``expm(Z h)`` (:func:`dense_exponential`; Higham 2005).

Both are numba kernels, compiled into the native Drillstring FMU as they run
in the Python one; :class:`StepTable` keeps a run's exponentials (built steps,
and a bounded cache of the others).

This module is the one source of that step: the co-simulation master's string
side (``hammerbit.cosim.string_side``) and the ``Drillstring`` FMU
(:mod:`string_slave`) both use :class:`ExactStep`, :class:`StringState` and
the kernels of :mod:`string_kernels`, which also hold the per-step exchange of a
Jacobi or Gauss-Seidel scheme.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import contextlib

import numpy as np
from .string_exponentials import N_PHI, PADE_WORK, dense_exponential, modal_exponentials
from .string_kernels import N_COEFFS, string_step_dense, string_step_modal

__all__ = ["ExactStep", "Discretisation", "StringState", "StepTable", "MODAL_TOLERANCE", "BUILT_STEPS",
           "BUILT_STEP_MATCH", "STEP_CACHE", "step_key", "one_blas_thread", "step_exponentials"]

#: the modal form is used when the eigenbasis reproduces the dense step to this (relative)
MODAL_TOLERANCE = 1e-10
#: significant digits of a step length in the cache key (steps that differ by rounding share one)
_KEY_DIGITS = 12
#: squaring depth: a step h may be built from a cached step h / 2^k, k up to this
_MAX_SQUARINGS = 12
#: the step lengths a Drillstring FMU carries the exponentials of by default [s] (its default experiment's)
BUILT_STEPS = (1e-3,)
#: a step within this (relative) of a built step uses the built step's exponentials
BUILT_STEP_MATCH = 1e-9
#: step lengths other than the built ones whose exponentials a run keeps (the oldest goes first)
STEP_CACHE = 8


def one_blas_thread():
    """The string's dense linear algebra on one BLAS thread (a context): a 441-state eigenproblem
    is several times slower with the default thread pool on a loaded machine, and one thread
    gives the same bits in every process, whatever its core count.

    threadpoolctl limits the BLAS libraries loaded when the limit is set, so scipy's (loaded with
    ``scipy.linalg``, which the bodies import where they need it) is loaded first: else the first
    body in a process would run on every core and give other bits than the later ones."""
    try:
        from threadpoolctl import threadpool_limits  # noqa: PLC0415 -- optional in an FMU's host
    except ImportError:
        return contextlib.nullcontext()
    try:
        import scipy.linalg  # noqa: F401, PLC0415 -- loads scipy's BLAS (see above)
    except ImportError:
        pass
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
            self.m_lam = np.ascontiguousarray(lam[keep])              # a step of any length: the modes'
            self.m_B = np.ascontiguousarray(self.m_Vinv @ self.E)     # eigenvalues and inputs
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


def step_exponentials(side: ExactStep, h: float) -> Discretisation:
    """The exact step of ``side`` over ``h`` [s] computed by the kernels (:func:`modal_exponentials`
    in the modal form, :func:`dense_exponential` in the dense one); ``side``'s form must be decided
    (a first :meth:`ExactStep.discretisation`)."""
    h = float(h)
    if not (0.0 < h < np.inf):
        raise ValueError(f"step length h = {h!r} s: allowed a finite h > 0")
    k2 = np.array([side.ki, side.ci])
    if side.modal:
        m = side.m_lam.shape[0]
        d = Discretisation(h=h, P=None, modal=True, m_d=np.empty(m, np.complex128),
                           m_G=np.empty((m, N_COEFFS), np.complex128), m_irow=np.empty(m, np.complex128),
                           m_icol=np.empty(N_COEFFS))
        modal_exponentials(h, side.m_lam, side.m_B, side.m_frow, k2, d.m_d, d.m_G, d.m_irow, d.m_icol,
                           np.empty(N_PHI, np.complex128))
        return d
    n = side.n
    N = n + N_COEFFS + 1
    P = np.empty((n + 1, n + N_COEFFS))
    dense_exponential(h, side.A1, side.E, side.frow, k2, P, np.empty((PADE_WORK, N, N)))
    return Discretisation(h=h, P=P)


class StepTable:
    """The exponentials a run steps with: those of its built steps (:data:`BUILT_STEPS`, by
    :meth:`ExactStep.discretisation`), and of up to :data:`STEP_CACHE` other step lengths (by
    :func:`step_exponentials`; the oldest is dropped first).

    A step within :data:`BUILT_STEP_MATCH` (relative) of a built one uses the built one's."""

    def __init__(self, side: ExactStep, built=BUILT_STEPS, limit: int = STEP_CACHE):
        self.side = side
        self.built = tuple(float(h) for h in built)
        self.limit = int(limit)
        self.cache = {}
        side.discretisation(self.built[0])           # decides the form

    def built_step(self, h: float) -> Optional[float]:
        """The built step ``h`` [s] takes the exponentials of, or None."""
        for hb in self.built:
            if abs(h - hb) <= BUILT_STEP_MATCH * hb:
                return hb
        return None

    def get(self, h: float) -> Discretisation:
        """The exponentials of a step ``h`` [s]."""
        hb = self.built_step(h)
        if hb is not None:
            return self.side.discretisation(hb)
        d = self.cache.get(h)
        if d is None:
            if len(self.cache) >= self.limit:
                del self.cache[next(iter(self.cache))]
            d = self.cache[h] = step_exponentials(self.side, h)
        return d

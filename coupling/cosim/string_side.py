"""The string side of the co-simulation: the drillstring and the interface spring, stepped exactly.

Over a macro step ``[t_n, t_n + h]`` the hammer motion seen by the string is
a polynomial (degree 0, 1 or 2) given by its Taylor coefficients
``c = (x, v, x', v', x'', v'')`` at ``t_n``.  The string state ``xi``
(deviation from static equilibrium) obeys ``xi' = A' xi + E w(s)``,
``A' = A - B (k_i C_u + c_i C_v)``, ``E = B [k_i, c_i]``.  Appending the
polynomial's coefficients as a nilpotent chain and the time integral of the
interface force as one more state gives one linear autonomous system whose
matrix exponential ``expm(Z h)`` (:func:`scipy.linalg.expm`, once per step
length) maps ``[xi_n, c]`` exactly to ``[xi_{n+1}, int (F_i - W) dt]``.

When the eigenvectors of ``A'`` reproduce that step to 1e-10 the state is
kept in modal coordinates (``eta <- exp(lam h) eta + G c``, one of each
conjugate pair kept: O(n) per step); otherwise the dense mat-vec is used.
:class:`StringSide` holds the model and the discretisations (cached per step
length, shared by a run and its half-step companion); :class:`StringState`
holds one run's state.
"""
from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import Optional

import numpy as np
import scipy.linalg as sla
from numba import njit as _njit

__all__ = ["StringSide", "StringState", "string_step_dense", "string_step_modal"]

#: eigendecompositions and matrix exponentials of recent string models, shared by every side built
#: from the same matrices (a sweep, a run and its reference, a study's repeated runs)
_MEMO: "OrderedDict[bytes, object]" = OrderedDict()
_MEMO_SIZE = 32


def _memo(key: bytes, compute):
    """``compute()``, remembered under ``key`` (its arrays made read-only: they are shared)."""
    hit = _MEMO.get(key)
    if hit is not None:
        _MEMO.move_to_end(key)
        return hit
    value = compute()
    for a in (value if isinstance(value, tuple) else (value,)):
        if isinstance(a, np.ndarray):
            a.setflags(write=False)
    _MEMO[key] = value
    while len(_MEMO) > _MEMO_SIZE:
        _MEMO.popitem(last=False)
    return value


def _digest(tag: str, *arrays, extra=()) -> bytes:
    h = hashlib.sha1(tag.encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr((a.shape, a.dtype.str)).encode())
        h.update(a.tobytes())
    h.update(repr(extra).encode())
    return h.digest()


class StringSide:
    """The drillstring plus interface spring and its exact step over any macro step.

    Holds the model and the discretisations (one per step length, cached);
    the state of a run lives in :class:`StringState` (a run and its
    companion share one side).

    Parameters
    ----------
    string : DrillString
    config : CosimConfig

    Attributes
    ----------
    ss : StateSpace
        Exported model (``hammerbit.drillstring.state_space``) at the WOB.
    A1, E : ndarray
        Closed-interface state matrix and the input matrix of ``(x_h, v_h)``.
    Cu, Cv, Ct : ndarray
        Output rows: bit displacement, bit velocity, top tension.
    """

    def __init__(self, string, config):
        from hammerbit.drillstring import Boundary, state_space
        self.config = config
        ki, ci = config.interface_stiffness, config.interface_damping
        self.ki, self.ci = ki, ci
        self.wob = config.weight_on_bit
        ss = state_space(string, None, Boundary.hammer(ki, ci), mass=config.mass,
                         wob=self.wob, f_max=config.f_max)
        if ss.x0 is None:
            raise ValueError("the string has a rigid-body mode: the top must hold it (fixed or spring hook)")
        self.ss = ss
        B = ss.B[:, 0]
        self.Cu, self.Cv, self.Ct = ss.C[0].copy(), ss.C[1].copy(), ss.C[2].copy()
        self.A1 = ss.A - np.outer(B, ki * self.Cu + ci * self.Cv)
        self.E = np.column_stack((B * ki, B * ci))
        self.n = ss.A.shape[0]
        self.frow = ki * self.Cu + ci * self.Cv   # F_i - W = frow.xi - ki x_dev - ci v
        self.rows3 = np.ascontiguousarray(np.vstack((self.Cu, self.Cv, self.Ct)))  # bit u, v; top tension
        self.hook_eq = float(ss.hook_load)
        self._disc = {}
        self._phi = {}                # step length -> expm(Z h) (the squaring base of longer steps)
        self._eig = None
        self.modal = False if config.string_step == "dense" else None  # decided at the first discretisation
        self.m_Vinv = None
        self.xi = np.zeros(self.n)    # state of :meth:`step` (the single-run helper)

    # -- modes ---------------------------------------------------------------
    def _eigen(self):
        if self._eig is None:
            def decompose():
                lam, V = np.linalg.eig(self.A1)
                return lam, V, np.linalg.inv(V)
            try:
                self._eig = _memo(_digest("eig", self.A1), decompose)
            except np.linalg.LinAlgError:
                self._eig = False
        return self._eig

    def exchange_frequency(self, share: float = 1e-3) -> float:
        """Highest mode [Hz] of the string side carrying at least ``share`` of the
        interface's static compliance (the string modes the exchange sees)."""
        key = ("exchange_frequency", share)
        if key not in self._phi:
            self._phi[key] = self._exchange_frequency(share)
        return self._phi[key]

    def _exchange_frequency(self, share: float) -> float:
        eig = self._eigen()
        if eig is False:
            return float(np.max(np.abs(np.linalg.eigvals(self.A1).imag)) / (2 * math.pi))
        lam, V, Vinv = eig
        r = np.abs((self.frow @ V) * (Vinv @ self.E[:, 0]) / np.where(lam == 0, 1.0, lam))
        if not np.any(r > 0):
            return 0.0
        keep = r >= share * r.sum()
        return float(np.max(np.abs(lam.imag[keep])) / (2 * math.pi))

    # -- discretisation ------------------------------------------------------
    def discretisation(self, h: float) -> "_Discretisation":
        """The exact step over ``h`` [s] (cached by ``h`` to 12 significant digits: steps that
        differ by rounding only, e.g. ``t_end - t``, share one)."""
        key = float(f"{h:.12g}")
        d = self._disc.get(key)
        if d is None:
            d = self._disc[key] = self._discretise(key)
        return d

    def _discretise(self, h: float) -> "_Discretisation":
        """``expm(Z h)``; by squaring ``expm(Z h 2^-k)`` when a step ``h 2^-k`` is cached
        (the adaptive step and the companion use powers of two: one ``expm`` for all)."""
        n = self.n
        N = n + 6 + 1
        Phi = None
        for k in range(1, 13):
            base = self._phi.get(float(f"{h / 2 ** k:.12g}"))
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
            Phi = _memo(_digest("expm", Z, extra=h), lambda: sla.expm(Z * h))
        self._phi[float(f"{h:.12g}")] = Phi
        rows = np.r_[np.arange(n), N - 1]
        d = _Discretisation(h=h, P=np.ascontiguousarray(Phi[np.ix_(rows, np.arange(n + 6))]))
        self._modal(Phi, h, d)
        return d

    def _modal(self, Phi: np.ndarray, h: float, d: "_Discretisation") -> None:
        """Diagonal (modal) form of the exact step: O(n) per macro step instead of O(n^2).

        With ``A1 = V diag(lam) V^-1`` the step is ``eta <- exp(lam h) * eta + G c``
        in modal coordinates ``eta = V^-1 xi``, and the interface force row is
        ``frow V``.  Decided once, at the first step length: used only when the
        eigenvector basis reproduces the dense step to 1e-10 (otherwise every
        step is the dense ``P``).
        """
        n = self.n
        if self.modal is False:
            return
        eig = self._eigen()
        if eig is False:
            self.modal = False
            return
        lam, V, Vinv = eig
        ex = np.exp(lam * h)
        if self.modal is None:
            recon = (V * ex[None, :]) @ Vinv
            scale = max(np.max(np.abs(Phi[:n, :n])), 1.0)
            tol = 1e-12 * max(np.max(np.abs(lam)), 1.0)
            if (not np.all(np.isfinite(recon)) or np.max(np.abs(recon - Phi[:n, :n])) > 1e-10 * scale
                    or np.count_nonzero(lam.imag > tol) != np.count_nonzero(lam.imag < -tol)):
                self.modal = False
                return
            # A1 is real: its complex modes come in conjugate pairs, whose two halves
            # carry conjugate states.  Keep one of each pair with weight 2 on every
            # real output (and the real modes with weight 1): half the work.
            keep = np.flatnonzero((lam.imag > tol) | (np.abs(lam.imag) <= tol))
            wgt = np.where(lam[keep].imag > tol, 2.0, 1.0)
            Vk = V[:, keep]
            self._keep = keep
            self._Vk_w = Vk * wgt[None, :]
            self.m_frow = np.ascontiguousarray(self.frow @ self._Vk_w)
            self.m_rows3 = np.ascontiguousarray(np.vstack([r @ self._Vk_w for r in (self.Cu, self.Cv, self.Ct)]))
            self.m_V = self._Vk_w                 # xi = Re(m_V @ eta)
            self.m_Vinv = Vinv[keep]              # eta = m_Vinv @ xi
            self.modal = True
        keep = self._keep
        N = n + 6 + 1
        d.modal = True
        d.m_d = np.ascontiguousarray(ex[keep])
        d.m_G = np.ascontiguousarray((Vinv @ Phi[:n, n:n + 6])[keep])
        d.m_irow = np.ascontiguousarray(Phi[N - 1, :n] @ self._Vk_w)   # int (F_i - W) dt from eta
        d.m_icol = np.ascontiguousarray(Phi[N - 1, n:n + 6])           # ... and from the coefficients

    # -- single-run helper (tests, one step from xi) -------------------------
    def step(self, coeffs: np.ndarray, h: float) -> float:
        """Advance ``self.xi`` over ``h`` with hammer-motion Taylor coefficients
        (6,) = (x, v, x', v', x'', v''); x as deviation from equilibrium.
        Returns the integral of (F_i - W) over the step [N s].  The same kernels
        as the master (modal form when available)."""
        st = StringState(self, self.xi)
        imp = st.advance(self.discretisation(h), np.asarray(coeffs, dtype=float))
        self.xi = st.xi()
        return imp


@dataclass
class _Discretisation:
    """The exact step over ``h``: dense ``P`` (n + 1 rows: xi and int (F_i - W) dt) and,
    when the eigenbasis reproduces it, the modal form."""

    h: float
    P: np.ndarray
    modal: bool = False
    m_d: Optional[np.ndarray] = None
    m_G: Optional[np.ndarray] = None
    m_irow: Optional[np.ndarray] = None
    m_icol: Optional[np.ndarray] = None


class StringState:
    """The string's state in one run: modal ``eta`` when the side has a modal form, else ``xi``."""

    def __init__(self, side: StringSide, xi0: Optional[np.ndarray] = None):
        self.side = side
        xi0 = np.zeros(side.n) if xi0 is None else np.asarray(xi0, dtype=float)
        side.discretisation(side.config.step)       # decides the form
        self.modal = bool(side.modal)
        if self.modal:
            self.eta = (side.m_Vinv @ xi0).astype(np.complex128)
            self.v = self.eta
        else:
            self.v = xi0.copy()
        self.buf = np.zeros(side.n + 6)
        self.tmp = np.zeros(side.n + 1)
        self.c = np.zeros(6)

    def xi(self) -> np.ndarray:
        return (self.side.m_V @ self.v).real if self.modal else self.v.copy()

    def f_xi(self) -> float:
        """frow . xi: the string's share of F_i - W [N]."""
        s = self.side
        if self.modal:
            return float((s.m_frow @ self.v).real)
        return float(s.frow @ self.v)

    def outputs(self) -> np.ndarray:
        """(displacement deviation [m], velocity [m/s]) of the string's bottom node and the
        hook load [N], in one product."""
        s = self.side
        o = (s.m_rows3 @ self.v).real if self.modal else s.rows3 @ self.v
        o[2] += s.hook_eq
        return o

    def copy_state(self):
        return self.v.copy()

    def restore(self, v) -> None:
        self.v[:] = v

    def advance(self, d: _Discretisation, coeffs: np.ndarray) -> float:
        """Advance with given coefficients; returns int (F_i - W) dt [N s]."""
        if self.modal:
            return string_step_modal(d.m_d, d.m_G, d.m_irow, d.m_icol, self.v, coeffs, self.side.m_frow)[0]
        self.buf[self.side.n:] = coeffs
        return string_step_dense(d.P, self.v, self.buf, self.tmp)


@_njit(cache=True, fastmath=True)
def string_step_dense(P, xi, buf, tmp):
    """xi <- P[:n] [xi, c]; returns int (F_i - W) dt (row n).  ``buf[n:]`` holds c."""
    n = xi.shape[0]
    m = buf.shape[0]
    for i in range(n):
        buf[i] = xi[i]
    # P @ buf by hand: no BLAS call (its thread pool costs more than this small mat-vec)
    for i in range(n + 1):
        acc = 0.0
        for k in range(m):
            acc += P[i, k] * buf[k]
        tmp[i] = acc
    for i in range(n):
        xi[i] = tmp[i]
    return tmp[n]


@_njit(cache=True)
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

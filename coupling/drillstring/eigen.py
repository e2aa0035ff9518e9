"""Selected eigenpairs of a symmetric tridiagonal pencil ``K phi = lam M phi``.

The string's stiffness and mass are tridiagonal (a chain), ``M`` positive
definite.  By Sylvester's law of inertia the number of negative pivots of the
``LDL^T`` factorisation of ``K - s M`` equals the number of eigenvalues below
``s`` (the Sturm count).  Bisection on that count gives any eigenvalue by
index to near machine precision in ``O(n)`` per step; inverse iteration on the
same tridiagonal factorisation gives its vector.  Only the modes asked for
are computed: the cost is ``O(n m)`` for ``m`` modes of an ``n``-node chain,
against ``O(n^2 m)`` and worse for dense or Lanczos solvers on the long,
fine meshes a 200 Hz check needs.

Kernels are numba nopython functions writing into preallocated arrays;
:func:`pencil_eigenpairs` validates and allocates.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["sturm_count", "pencil_eigenvalues", "pencil_eigenpairs", "assembly_eigenpairs", "has_rigid_mode"]


@njit(cache=True)
def _count(kd, ke, md, me, s):
    """Number of eigenvalues of the pencil below ``s``."""
    n = kd.size
    tiny = 1e-300
    cnt = 0
    d = kd[0] - s * md[0]
    if d < 0.0:
        cnt += 1
    for i in range(1, n):
        if d == 0.0:
            d = -tiny
        off = ke[i - 1] - s * me[i - 1]
        d = (kd[i] - s * md[i]) - off * off / d
        if d < 0.0:
            cnt += 1
    return cnt


@njit(cache=True)
def _bisect(kd, ke, md, me, lo, hi, first, rtol, out):
    """Eigenvalues with indices ``first .. first + out.size - 1`` into ``out``
    to relative width ``rtol``; ``lo``/``hi`` bracket all of them.  Every
    count also tightens the upper brackets of the later eigenvalues."""
    m = out.size
    ub = np.full(m, hi)
    for j in range(m):
        idx = first + j
        a = lo if j == 0 else max(lo, out[j - 1])
        b = ub[j]
        for _ in range(400):
            mid = 0.5 * (a + b)
            if mid <= a or mid >= b or b - a <= rtol * max(abs(a), abs(b)):
                break
            c = _count(kd, ke, md, me, mid)
            if c <= idx:
                a = mid
            else:
                b = mid
                for k in range(j + 1, min(c - first, m)):
                    if mid < ub[k]:
                        ub[k] = mid
        out[j] = 0.5 * (a + b)


@njit(cache=True)
def _tridiagonal_row(d, e, x, i):
    """(A x)_i for the symmetric tridiagonal A with diagonal ``d`` and off-diagonal ``e``."""
    v = d[i] * x[i]
    if i > 0:
        v += e[i - 1] * x[i - 1]
    if i < d.size - 1:
        v += e[i] * x[i + 1]
    return v


@njit(cache=True)
def _quadratic_form(d, e, x):
    """x^T A x for the symmetric tridiagonal A with diagonal ``d`` and off-diagonal ``e``."""
    q = 0.0
    for i in range(d.size):
        q += x[i] * _tridiagonal_row(d, e, x, i)
    return q


@njit(cache=True)
def _inverse_iteration(kd, ke, md, me, lam, out):
    """M-normalised eigenvectors ``out[:, j]`` of the eigenvalues ``lam[j]``;
    ``lam[j]`` is replaced by the Rayleigh quotient of its vector."""
    n = kd.size
    m = lam.size
    piv = np.empty(n)
    low = np.empty(n)
    x = np.empty(n)
    y = np.empty(n)
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(kd[i]))
    eps = 1e-15 * scale
    for j in range(m):
        s = lam[j]
        # LDL^T of K - s M (no pivoting; a vanishing pivot is nudged)
        d = kd[0] - s * md[0]
        if abs(d) < eps:
            d = eps
        piv[0] = d
        for i in range(1, n):
            off = ke[i - 1] - s * me[i - 1]
            low[i] = off / piv[i - 1]
            d = (kd[i] - s * md[i]) - low[i] * off
            if abs(d) < eps:
                d = eps
            piv[i] = d
        for i in range(n):  # deterministic start, not orthogonal to a smooth mode
            x[i] = 1.0 + 0.5 * math.sin(1.7 * i + 0.3)
        for _ in range(3):
            # y = M x
            for i in range(n):
                y[i] = _tridiagonal_row(md, me, x, i)
            # solve L D L^T z = y
            for i in range(1, n):
                y[i] -= low[i] * y[i - 1]
            for i in range(n):
                y[i] /= piv[i]
            for i in range(n - 2, -1, -1):
                y[i] -= low[i + 1] * y[i + 1]
            big = 0.0
            for i in range(n):
                big = max(big, abs(y[i]))
            for i in range(n):
                x[i] = y[i] / big
        # M-normalise
        nrm = _quadratic_form(md, me, x)
        lam[j] = _quadratic_form(kd, ke, x) / nrm
        nrm = math.sqrt(nrm)
        for i in range(n):
            out[i, j] = x[i] / nrm


def sturm_count(kd, ke, md, me, s: float) -> int:
    """Number of eigenvalues of the tridiagonal pencil below ``s``."""
    return int(_count(*_arrays(kd, ke, md, me), float(s)))


def _arrays(kd, ke, md, me):
    out = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in (kd, ke, md, me))
    n = out[0].size
    if out[2].size != n or out[1].size != n - 1 or out[3].size != n - 1 or n < 1:
        raise ValueError("tridiagonal pencil: diagonals of length n, off-diagonals of length n-1")
    if not all(np.all(np.isfinite(a)) for a in out):
        raise ValueError("tridiagonal pencil: non-finite entries")
    return out


def _upper_bound(kd, ke, md, me) -> float:
    """An upper bound of the largest eigenvalue (Gershgorin row sums of K over
    the smallest Gershgorin lower bound of M, which is positive definite here)."""
    rk = np.abs(kd).copy()
    rk[:-1] += np.abs(ke)
    rk[1:] += np.abs(ke)
    rm = md.copy()
    rm[:-1] -= np.abs(me)
    rm[1:] -= np.abs(me)
    lo_m = float(rm.min())
    if lo_m <= 0.0:  # not diagonally dominant: fall back to doubling with the count
        return math.inf
    return float(rk.max()) / lo_m


def pencil_eigenvalues(kd, ke, md, me, *, upper: float | None = None,
                       count: int | None = None, rtol: float = 4e-16, first: int = 0) -> np.ndarray:
    """Ascending eigenvalues below ``upper`` and/or the ``count`` lowest,
    starting at index ``first`` (bisection to relative width ``rtol``)."""
    kd, ke, md, me = _arrays(kd, ke, md, me)
    n = kd.size
    bound = _upper_bound(kd, ke, md, me)
    if not math.isfinite(bound):
        bound = float(np.max(np.abs(kd) / md)) * 4.0 + 1.0
        while _count(kd, ke, md, me, bound) < n:
            bound *= 2.0
    bound = bound * (1.0 + 1e-12) + 1e-300
    lo = -1e-9 * bound  # below a rigid-body eigenvalue that round-off pushed under 0
    hi = bound if upper is None else min(float(upper), bound)
    m = _count(kd, ke, md, me, hi) if upper is not None else n
    if count is not None:
        m = min(m, int(count))
    m -= int(first)
    out = np.empty(max(m, 0))
    if m > 0:
        _bisect(kd, ke, md, me, lo, hi if upper is not None else bound, int(first), float(rtol), out)
    return out


def pencil_eigenpairs(kd, ke, md, me, *, upper: float | None = None,
                      count: int | None = None, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(lam (m,), Phi (n, m))`` with ``Phi^T M Phi = I``, eigenvalues below
    ``upper`` and/or the ``count`` lowest, from index ``first`` on."""
    kd, ke, md, me = _arrays(kd, ke, md, me)
    # bisection to 1e-8, then inverse iteration (three steps, each shrinking
    # the error by (1e-8 lam / gap)); the Rayleigh quotient of the converged
    # vector gives the eigenvalue to round-off
    lam = pencil_eigenvalues(kd, ke, md, me, upper=upper, count=count, rtol=1e-8, first=first)
    phi = np.empty((kd.size, lam.size))
    if lam.size:
        _inverse_iteration(kd, ke, md, me, lam, phi)
        order = np.argsort(lam, kind="stable")
        lam, phi = lam[order], phi[:, order]
    return lam, phi


def assembly_eigenpairs(asm, f_max: float | None, count: int | None, *,
           all_modes: bool = False, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Lowest eigenpairs ``(omega^2 (n,), Phi (n_dof, n))`` of an assembled string
    (:class:`~.assembly.Assembly`) with ``Phi^T M Phi = I``.

    Only eigenvalues ``omega <= 2 pi f_max`` and/or the ``count`` lowest are
    computed (both given: both limits apply; neither: 10).  ``all_modes``:
    the whole spectrum (dense ``eigh``).
    """
    import scipy.linalg as sla  # noqa: PLC0415 -- imported where needed (a slow import)
    kd, ke = asm.tridiagonal("K")
    md, me = asm.tridiagonal("M")
    n = kd.size
    if all_modes:
        lam, phi = sla.eigh(asm.K, asm.M)
    else:
        if f_max is None and count is None:
            count = 10
        hi = None if f_max is None else (2.0 * math.pi * f_max) ** 2
        lam, phi = pencil_eigenpairs(kd, ke, md, me, upper=hi,
                                     count=None if count is None else min(int(count), n), first=first)
    lam = np.where(lam < 0.0, 0.0, lam)
    if lam.size and first == 0 and has_rigid_mode(asm.top, asm.bottom):
        lam[0] = 0.0  # exact zero instead of round-off (~eps * max eigenvalue)
    # deterministic sign: bit (last DOF) displacement >= 0, else largest entry > 0
    ref = phi[-1].copy()
    weak = np.abs(ref) < 1e-9 * np.max(np.abs(phi), axis=0, initial=0.0)
    ref[weak] = phi[np.argmax(np.abs(phi), axis=0), np.arange(phi.shape[1])][weak]
    phi = phi * np.where(ref < 0.0, -1.0, 1.0)
    return lam, phi


def has_rigid_mode(top, bottom) -> bool:
    """Both ends (:class:`~.boundary.Boundary`) unrestrained: no fixed end, no ground spring."""
    return (not top.is_fixed and top.ground_stiffness == 0.0
            and not bottom.is_fixed and bottom.ground_stiffness == 0.0)

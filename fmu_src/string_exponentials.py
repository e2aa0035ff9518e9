"""The exponentials of the string side's exact step over any length: numba kernels.

:func:`modal_exponentials` gives the modal form's arrays in closed form per mode
(``exp(lam h)`` and the ``phi`` functions of the polynomial hammer motion),
:func:`dense_exponential` the dense form's by scaling and squaring the balanced
[13/13] Pade approximant.  :mod:`string_step` calls them for a step length
whose exponentials a run does not carry (:class:`string_step.StepTable`); the
native Drillstring FMU compiles them (``hammerbit.fmu.native_string_kernels``).
Every kernel here calls only kernels of this module (numba's cache entry of a
kernel holds its callees' code).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator)
from .string_kernels import N_COEFFS

__all__ = ["N_PHI", "PADE_WORK", "PADE13_THETA", "phi_functions", "modal_exponentials", "dense_exponential"]
#: phi_0 .. phi_4 (the Taylor coefficients reach s^2 / 2, their time integral phi_4)
N_PHI = 5
#: below this |z| the phi functions are summed as their series (the recurrence cancels there)
PHI_SERIES_RADIUS = 1.0
#: terms of the series: |z|^k / (k + 1)! < 1e-20 for |z| < 1 and k = 20
PHI_SERIES_TERMS = 20
#: Higham (2005): the [13/13] Pade approximant of exp is exact to double precision for ||A||_1 <= this
PADE13_THETA = 5.371920351148152
#: the [13/13] Pade coefficients b_0 .. b_13
PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
          129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
          40840800.0, 960960.0, 16380.0, 182.0, 1.0)
#: planes (N x N, N = n + 7) of the work array of :func:`dense_exponential`
PADE_WORK = 8


@njit(cache=True)
def phi_functions(z, phi):
    """``phi[k] = phi_k(z)`` for k = 0 .. 4, ``phi_0 = exp``, ``phi_{k+1}(z) = (phi_k(z) - 1/k!) / z``.

    Near zero the recurrence cancels: there the series ``sum_j z^j / (j + k)!``."""
    phi[0] = np.exp(z)
    if z.real * z.real + z.imag * z.imag < PHI_SERIES_RADIUS * PHI_SERIES_RADIUS:
        for k in range(1, N_PHI):
            inv_fact = 1.0
            for j in range(2, k + 1):
                inv_fact /= j
            term = complex(inv_fact, 0.0)
            acc = term
            for j in range(1, PHI_SERIES_TERMS):
                term = term * z / (j + k)
                acc += term
            phi[k] = acc
    else:
        inv_fact = 1.0
        for k in range(1, N_PHI):
            phi[k] = (phi[k - 1] - inv_fact) / z
            inv_fact /= k


@njit(cache=True)
def modal_exponentials(h, lam, B, frow, k2, d, G, irow, icol, phi):
    """The modal form's arrays over a step ``h`` [s] into ``d, G, irow, icol`` (as
    :class:`ModalForm` takes them), in closed form per mode: each mode is the scalar system
    ``eta' = lam eta + B (x_h, v_h)`` driven by the polynomial hammer motion, so
    ``d = exp(lam h)``, ``G[:, k] = B[:, k % 2] h^(j+1) phi_(j+1)(lam h)`` and its time
    integrals ``h^(j+2) phi_(j+2)`` (``j = k // 2``, the power of the coefficient's term
    ``s^j / j!``).  ``lam`` (m,) and ``B`` (m, 2) are the kept modes' eigenvalues and inputs
    ``V^-1 E``, ``frow`` (m,) ``frow V`` (weight 2 on a conjugate pair's kept half), ``k2``
    ``(k_i, c_i)``; ``phi`` (N_PHI,) complex scratch."""
    hp = np.empty(N_PHI)               # h^k
    hp[0] = 1.0
    for k in range(1, N_PHI):
        hp[k] = hp[k - 1] * h
    fact = 1.0
    for k in range(N_COEFFS):
        j = k // 2
        if k % 2 == 0:
            fact *= j + 1                  # (j + 1)!
        icol[k] = -(k2[0] if k % 2 == 0 else k2[1]) * hp[j + 1] / fact
    for i in range(lam.shape[0]):
        phi_functions(lam[i] * h, phi)
        d[i] = phi[0]
        irow[i] = frow[i] * (h * phi[1])
        for k in range(N_COEFFS):
            j = k // 2
            b = B[i, k % 2]
            G[i, k] = b * (hp[j + 1] * phi[j + 1])
            icol[k] += (frow[i] * b * (hp[j + 2] * phi[j + 2])).real


@njit(cache=True)
def _matmul(A, B, C):
    """C <- A @ B (square, C distinct from A and B), rows of C accumulated in a fixed order."""
    N = A.shape[0]
    for i in range(N):
        for j in range(N):
            C[i, j] = 0.0
        for k in range(N):
            a = A[i, k]
            if a != 0.0:
                for j in range(N):
                    C[i, j] += a * B[k, j]


@njit(cache=True)
def _solve_in_place(Q, X, piv):
    """X <- Q^-1 X by Gaussian elimination with partial pivoting (Q overwritten by its LU)."""
    N = Q.shape[0]
    for k in range(N):
        p = k
        best = abs(Q[k, k])
        for i in range(k + 1, N):
            if abs(Q[i, k]) > best:
                best = abs(Q[i, k])
                p = i
        piv[k] = p
        if p != k:
            for j in range(N):
                Q[k, j], Q[p, j] = Q[p, j], Q[k, j]
                X[k, j], X[p, j] = X[p, j], X[k, j]
        inv = 1.0 / Q[k, k]
        for i in range(k + 1, N):
            f = Q[i, k] * inv
            if f != 0.0:
                Q[i, k] = f
                for j in range(k + 1, N):
                    Q[i, j] -= f * Q[k, j]
                for j in range(N):
                    X[i, j] -= f * X[k, j]
    for k in range(N - 1, -1, -1):
        inv = 1.0 / Q[k, k]
        for j in range(N):
            X[k, j] *= inv
        for i in range(k):
            f = Q[i, k]
            if f != 0.0:
                for j in range(N):
                    X[i, j] -= f * X[k, j]


@njit(cache=True)
def _balance(A, scale):
    """A <- D^-1 A D with D = diag(scale) of powers of 2 (exact) that bring each row and column
    to similar norms (the scaling of LAPACK's dgebal): a string side mixes displacements and
    velocities, whose entries differ by ten orders of magnitude."""
    N = A.shape[0]
    for i in range(N):
        scale[i] = 1.0
    done = False
    while not done:
        done = True
        for i in range(N):
            c = 0.0
            r = 0.0
            for j in range(N):
                if j != i:
                    c += abs(A[j, i])
                    r += abs(A[i, j])
            if c == 0.0 or r == 0.0:
                continue
            total = c + r
            f = 1.0
            g = r / 2.0
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c > g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * total:
                done = False
                scale[i] *= f
                for j in range(N):
                    A[i, j] /= f
                    A[j, i] *= f


@njit(cache=True)
def _norm1(A):
    """||A||_1: the largest column sum of |A|."""
    N = A.shape[0]
    norm = 0.0
    for j in range(N):
        col = 0.0
        for i in range(N):
            col += abs(A[i, j])
        norm = max(norm, col)
    return norm


@njit(cache=True)
def _pade_exponential(A, A2, A4, A6, U, T, V, piv):
    """expm(A) into ``T`` (A and the other N x N arrays destroyed) by scaling and squaring the
    [13/13] Pade approximant (Higham 2005, with the scaling of Al-Mohy & Higham 2009);
    ``piv`` (N,) scratch."""
    N = A.shape[0]
    _matmul(A, A, A2)
    _matmul(A2, A2, A4)
    _matmul(A4, A2, A6)
    # Al-Mohy & Higham (2009): the scaling from ||A^8||^(1/8) and ||A^10||^(1/10), which can be far
    # below ||A||_1 for a non-normal A: fewer squarings, less rounding carried through them
    _matmul(A4, A4, U)
    _matmul(A4, A6, T)
    eta = max(_norm1(U) ** 0.125, _norm1(T) ** 0.1)
    if not eta < np.inf:                 # the powers overflowed: the plain norm
        eta = _norm1(A)
    s = 0
    scale = 1.0
    while eta * scale > PADE13_THETA:    # the fewest halvings that bring eta within theta
        s += 1
        scale *= 0.5
    if s:
        for i in range(N):
            for j in range(N):
                A[i, j] *= scale
                A2[i, j] *= scale ** 2
                A4[i, j] *= scale ** 4
                A6[i, j] *= scale ** 6
    b = PADE13
    for i in range(N):                   # T <- A6 (b13 A6 + b11 A4 + b9 A2) + ..., U <- A T
        for j in range(N):
            V[i, j] = b[13] * A6[i, j] + b[11] * A4[i, j] + b[9] * A2[i, j]
    _matmul(A6, V, T)
    for i in range(N):
        for j in range(N):
            T[i, j] += b[7] * A6[i, j] + b[5] * A4[i, j] + b[3] * A2[i, j]
        T[i, i] += b[1]
    _matmul(A, T, U)                     # U: the odd part
    for i in range(N):
        for j in range(N):
            T[i, j] = b[12] * A6[i, j] + b[10] * A4[i, j] + b[8] * A2[i, j]
    _matmul(A6, T, V)
    for i in range(N):                   # V: the even part
        for j in range(N):
            V[i, j] += b[6] * A6[i, j] + b[4] * A4[i, j] + b[2] * A2[i, j]
        V[i, i] += b[0]
    for i in range(N):                   # (V - U) X = V + U; X in T, V - U in A
        for j in range(N):
            T[i, j] = V[i, j] + U[i, j]
            A[i, j] = V[i, j] - U[i, j]
    _solve_in_place(A, T, piv)
    for _ in range(s):
        _matmul(T, T, A)
        for i in range(N):
            for j in range(N):
                T[i, j] = A[i, j]


@njit(cache=True)
def dense_exponential(h, A1, E, frow, k2, P, work):
    """The dense form's ``P`` over a step ``h`` [s] (as :class:`DenseForm` takes it): the rows
    ``[xi, int (F_i - W) dt]`` and columns ``[xi, c]`` of ``expm(Z h)``, ``Z`` the string side
    with the hammer motion's Taylor chain and the force integral appended (as
    :class:`ExactStep` builds it): balanced (:func:`_balance`), then the [13/13] Pade
    approximant scaled and squared (:func:`_pade_exponential`).  ``work``: ``(PADE_WORK, N, N)``,
    ``N = n + 7``."""
    n = A1.shape[0]
    N = n + N_COEFFS + 1
    A = work[0]
    D = work[PADE_WORK - 1, 1]
    for i in range(N):
        for j in range(N):
            A[i, j] = 0.0
    for i in range(n):
        for j in range(n):
            A[i, j] = A1[i, j] * h
        A[i, n] = E[i, 0] * h
        A[i, n + 1] = E[i, 1] * h
        A[N - 1, i] = frow[i] * h
    for k in range(2):
        A[n + k, n + 2 + k] = h
        A[n + 2 + k, n + 4 + k] = h
    A[N - 1, n] = -k2[0] * h
    A[N - 1, n + 1] = -k2[1] * h
    _balance(A, D)
    T = work[5]
    _pade_exponential(A, work[1], work[2], work[3], work[4], T, work[6], work[PADE_WORK - 1, 0])
    for i in range(n + 1):               # expm(Z h) = D expm(D^-1 Z h D) D^-1
        r = i if i < n else N - 1
        for j in range(n + N_COEFFS):
            P[i, j] = D[r] * T[r, j] / D[j]

"""Butcher order conditions of the tableaux in ``hammerbit.model.tableaux``.

The conditions are built here from rooted trees, without code shared with the
generator of the tableaux or with the kernels:

* a rooted tree is a sorted tuple of its subtrees (the leaf is ``()``);
* the stage vector of a tree is ``g(leaf) = 1`` and
  ``g([t1, ..., tm]) = (A g(t1)) * ... * (A g(tm))`` (elementwise);
* its density is ``gamma(t) = |t| * gamma(t1) * ... * gamma(tm)``;
* a method with weights ``b`` has order ``p`` iff ``b . g(t) = 1 / gamma(t)``
  for every tree with ``|t| <= p`` (Butcher; Hairer, Norsett & Wanner, *Solving
  ODEs I*, Thm. II.2.13);
* a continuous extension ``b(x)`` has order ``q`` iff
  ``b(x) . g(t) = x^|t| / gamma(t)`` for ``|t| <= q`` and every x in [0, 1];
* an error estimator ``E = b - b_hat`` of an embedded order ``q`` has
  ``E . g(t) = 0`` for ``|t| <= q``.

The dense output is read in the nested form the kernels evaluate
(``y0 + x (F0 + (1-x) (F1 + x (F2 + ...))))``, ``F0 = y1 - y0``,
``F_k = h W[k] . K``), so the weights are ``b(x) = x (B + (1-x) (W1 + x (W2 + ...)))``.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pytest

from hammerbit.model import tableaux as T

# ------------------------------------------------------------------ rooted trees
#: number of rooted trees with n nodes (OEIS A000081), a check on the generator below
A000081 = [1, 1, 2, 4, 9, 20, 48, 115, 286]


@lru_cache(maxsize=None)
def trees_of_order(n: int) -> tuple:
    """All rooted trees with ``n`` nodes, each a sorted tuple of subtrees."""
    if n == 1:
        return ((),)
    out = set()

    def extend(children, remaining, max_key):
        if remaining == 0:
            out.add(tuple(sorted(children)))
            return
        for m in range(1, remaining + 1):
            for sub in trees_of_order(m):
                key = (m, sub)
                if key <= max_key:          # non-increasing: each multiset once
                    extend(children + [sub], remaining - m, key)

    extend([], n - 1, (math.inf,))
    return tuple(sorted(out))


def order(t) -> int:
    return 1 + sum(order(c) for c in t)


def density(t) -> int:
    return order(t) * math.prod(density(c) for c in t)


def stage_vector(t, A):
    g = np.ones(A.shape[0])
    for c in t:
        g = g * (A @ stage_vector(c, A))
    return g


def residuals(b, A, p):
    """max |b . g(t) - 1/gamma(t)| over the trees of each order 1..p (a list)."""
    return [max(abs(b @ stage_vector(t, A) - 1.0 / density(t)) for t in trees_of_order(k))
            for k in range(1, p + 1)]


def dense_weights(W, B_ext, x):
    """b(x) of the nested dense output (rows W[1:] of the kernels' weights)."""
    acc = np.zeros_like(B_ext)
    for k in range(W.shape[0] - 1, 0, -1):
        acc = acc + W[k]
        acc = acc * (x if k % 2 == 0 else 1.0 - x)
    return x * (B_ext + acc)


def dense_residuals(W, B_ext, A, q, xs):
    out = []
    for k in range(1, q + 1):
        worst = 0.0
        for t in trees_of_order(k):
            g = stage_vector(t, A)
            for x in xs:
                worst = max(worst, abs(dense_weights(W, B_ext, x) @ g - x ** k / density(t)))
        out.append(worst)
    return out


def test_tree_generator_counts_and_densities():
    assert [len(trees_of_order(n)) for n in range(1, 10)] == A000081
    # hand values: the bushy tree [tau^3] has gamma 4, the tall tree [[[tau]]] has gamma 24
    assert density(((), (), ())) == 4
    assert density(((((),),),)) == 4 * 3 * 2
    # the explicit Euler method has order 1 exactly
    A = np.zeros((1, 1))
    b = np.ones(1)
    r = residuals(b, A, 2)
    assert r[0] < 1e-15 and r[1] == pytest.approx(0.5)


# ------------------------------------------------------------------ the methods
# (name, A main stages, B, C, stated order)
METHODS = {
    "dop853": (T.DOP853_A, T.DOP853_B, T.DOP853_C, T.DOP853_N_STAGES, 8),
    "dp54": (T.DP54_A, T.DP54_B, T.DP54_C, T.DP54_N_STAGES, 5),
    "rk4": (T.RK4_A, T.RK4_B, T.RK4_C, T.RK4_N_STAGES, 4),
}

#: the coefficients are rounded to double precision: every condition holds to ~1e-15
#: (a coefficient perturbed by 1e-12 already breaks this)
TOL = 1e-13


@pytest.mark.parametrize("name", list(METHODS))
def test_row_sums_are_the_nodes(name):
    """c_i = sum_j a_ij, on the main and the extra (dense-output) stages."""
    A, _, C, _, _ = METHODS[name]
    assert A.shape[0] == A.shape[1] == C.shape[0]
    assert np.max(np.abs(A.sum(axis=1) - C)) < 1e-14
    assert np.all(np.triu(A) == 0.0)                 # explicit


@pytest.mark.parametrize("name", list(METHODS))
def test_order_conditions(name):
    A, B, _, ns, p = METHODS[name]
    Am = A[:ns, :ns]
    assert B.shape == (ns,)
    r = residuals(B, Am, p + 1)
    assert max(r[:p]) < TOL, (name, r)
    # the stated order is exact: some condition of order p + 1 fails by far more
    assert r[p] > 1e-6, (name, r)


def test_fsal_stage_is_the_step_end():
    """The stage after the main ones is f(t0 + h, y1): its row of A is B, its node 1."""
    for name, (A, B, C, ns, _) in METHODS.items():
        assert np.array_equal(A[ns, :ns], B), name
        assert C[ns] == 1.0, name


@pytest.mark.parametrize("E, q, name", [
    (T.DOP853_E, 5, "dop853"),     # Hairer's 5th-order estimator of DOP853
    (T.DOP853_E3, 3, "dop853"),    # and its 3rd-order companion
    (T.DP54_E, 4, "dp54"),         # the embedded 4th-order solution of Dormand-Prince
])
def test_error_estimators_vanish_to_their_order(E, q, name):
    """E = b - b_hat (over the main stages and the FSAL stage) annihilates every
    condition up to the embedded order, and not beyond (else it estimates nothing)."""
    A, _, _, ns, p = METHODS[name]
    n = E.shape[0]
    assert n == ns + 1
    Ae = A[:n, :n]
    sums = [max(abs(E @ stage_vector(t, Ae)) for t in trees_of_order(k)) for k in range(1, q + 2)]
    assert max(sums[:q]) < 1e-13, sums
    assert sums[q] > 1e-6, sums


# ------------------------------------------------------------------ dense output
# (W, stated order of the continuous extension)
DENSE = {"dop853": (T.DOP853_W, 7), "dp54": (T.DP54_W, 4), "rk4": (T.RK4_W, 3)}
XS = np.linspace(0.0, 1.0, 9)


@pytest.mark.parametrize("name", list(DENSE))
def test_dense_output_reproduces_the_step_end(name):
    A, B, _, ns, _ = METHODS[name]
    W, _ = DENSE[name]
    B_ext = np.zeros(A.shape[0])
    B_ext[:ns] = B
    assert W.shape[1] == A.shape[0]
    assert np.max(np.abs(W[0, :ns] - B)) < 1e-14 and not np.any(W[0, ns:])
    assert np.max(np.abs(dense_weights(W, B_ext, 1.0) - B_ext)) == 0.0
    assert not np.any(dense_weights(W, B_ext, 0.0))


@pytest.mark.parametrize("name", list(DENSE))
def test_dense_output_order(name):
    A, B, _, ns, _ = METHODS[name]
    W, q = DENSE[name]
    B_ext = np.zeros(A.shape[0])
    B_ext[:ns] = B
    r = dense_residuals(W, B_ext, A, q + 1, XS)
    assert max(r[:q]) < TOL, (name, r)
    assert r[q] > 1e-6, (name, r)


@pytest.mark.parametrize("name", list(DENSE))
def test_dense_output_order_on_a_scalar_problem(name):
    """The nested interpolant built from one step of y' = y^2 (exact y = 1 / (1 - t)):
    the error at the midpoint falls as h^(q+1) with the stated dense order q."""
    A, B, C, ns, _ = METHODS[name]
    W, q = DENSE[name]
    n_ext = A.shape[0]

    def interp_error(h, x):
        k = np.zeros(n_ext)
        for s in range(n_ext):
            k[s] = (0.5 + h * (A[s, :s] @ k[:s])) ** 2      # y0 = 0.5 at t0 = 0
        y1 = 0.5 + h * (B @ k[:ns])
        F = [y1 - 0.5] + [h * (W[j] @ k) for j in range(1, W.shape[0])]
        acc = 0.0
        for j in range(len(F) - 1, -1, -1):
            acc += F[j]
            acc *= x if j % 2 == 0 else 1.0 - x
        exact = 1.0 / (2.0 - x * h)                         # y(t) = 1 / (2 - t)
        return abs(0.5 + acc - exact)

    hs = np.array([0.2, 0.1])
    e = np.array([interp_error(h, 0.37) for h in hs])
    slope = math.log(e[0] / e[1]) / math.log(2.0)
    assert slope == pytest.approx(q + 1, abs=0.6), (name, e, slope)

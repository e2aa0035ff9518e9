"""``partial.bind``: a kernel with some arguments bound as compile-time constants."""
import numpy as np
import pytest
from numba import njit

from hammerbit.model import kernel_driver, kernel_layouts
from hammerbit.model.presets import preset
from hammerbit.model.numba_partial import bind
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper


def _poly(x, c, n):
    acc = 0.0
    for k in range(n):
        acc = acc * x + c[k]
    return acc


def test_bound_copy_computes_what_the_original_computes():
    c = np.array([2.0, -3.0, 0.5, 7.0])
    bound = njit(bind(_poly, "poly_c", c=c, n=4))
    for x in (-1.5, 0.0, 0.3, 11.0):
        assert bound(x) == _poly(x, c, 4)
    assert bound.py_func.__code__.co_varnames[:1] == ("x",)


@njit
def _callee(k):
    return k + 1


def _caller(x, k):
    return x + _callee(k)


def test_bound_integers_are_literal_types_for_the_callees():
    njit(bind(_caller, "caller_k", k=3))(1.0)
    assert [str(sig[0]) for sig in _callee.signatures] == ["Literal[int](3)"]


def test_a_closure_is_refused():
    n = 2

    def inner(x):
        return x * n

    with pytest.raises(TypeError, match="closure"):
        bind(inner, "inner2")


def test_unknown_parameter_is_refused():
    with pytest.raises(TypeError, match="no positional parameter"):
        bind(_poly, "p", degree=3)


@pytest.mark.parametrize("method", ["adaptive", "dp54", "rk4"])
def test_bound_entry_points_equal_the_general_driver_bit_for_bit(method):
    """Each hammer-only entry point (its method, no subsystem, no energy block, all constants)
    and the general ``advance`` given the same arrays as arguments take identical steps."""
    g = preset("paper-fig9").replace(a=0.083)
    o = SolverOptions(method=method, rtol=1e-8, atol=1e-10)
    bound = Stepper(g, solver=o)
    general = Stepper(g, solver=o)
    assert bound.entry == kernel_driver.HAMMER_ENTRY[method] != "advance"
    assert bound.fast == (method == "adaptive")
    general.entry = "advance"
    t_end = 40 * g.period
    poin = {st: np.zeros((41, 5)) for st in (bound, general)}
    for st in (bound, general):
        st.advance(t_end, poincare=poin[st])
    assert np.array_equal(bound.y, general.y)
    assert np.array_equal(bound.istate, general.istate)
    assert np.array_equal(bound.fstate, general.fstate)
    assert np.array_equal(poin[bound], poin[general])
    assert bound.istate[kernel_layouts.I_STEPS] > 100

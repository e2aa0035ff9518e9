"""The Drillstring FMU's step of any length: its exponentials against scipy's ``expm``, the built
steps' reuse, the bounded cache, and a master's leftover steps that must not spoil the run.

Oracles: scipy's ``expm`` of each mode's own augmented system (the modal form: a scalar mode
driven by the polynomial hammer motion, 8 x 8) and of the string side's augmented matrix (the
dense form); for the lab auto-driller, whose exponential is ill conditioned at millisecond
steps, a 34-digit mpmath exponential (slow set).
"""
import math
import zipfile

import numpy as np
import pytest
import scipy.linalg as sla

from hammerbit.model.string_step import (BUILT_STEP_MATCH, STEP_CACHE, ExactStep, StepTable,
                                         step_exponentials)

REL = 1e-12
#: step lengths [s]: a leftover, tiny ones, libcosim's clock after 4 s, others up to 0.1 s
STEPS = (1e-13, 1e-9, 1e-6, 3.3e-4, 0.0009999999999994458, 7e-3, 0.1)


@pytest.fixture(scope="module")
def lab():
    from hammerbit.fmu.build_string import string_build
    return string_build("lab")


def _side(build, form, dense=False):
    from hammerbit.model.string_model import string_matrices
    sc = build.info["scalars"]
    A1, E, frow, rows = string_matrices(build.arrays, form, build.arrays["build_values"])
    side = ExactStep(A1, E, frow, sc["interface_stiffness"], sc["interface_damping"], rows, 0.0, dense=dense)
    side.discretisation(1e-3)                    # decides the form, as the FMU's first built step
    return side


def _augmented(side):
    n = side.n
    N = n + 7
    Z = np.zeros((N, N))
    Z[:n, :n] = side.A1
    Z[:n, n:n + 2] = side.E
    Z[n:n + 2, n + 2:n + 4] = np.eye(2)
    Z[n + 2:n + 4, n + 4:n + 6] = np.eye(2)
    Z[N - 1, :n] = side.frow
    Z[N - 1, n:n + 2] = (-side.ki, -side.ci)
    return Z


def _scipy_P(side, h):
    n = side.n
    Phi = sla.expm(_augmented(side) * h)
    return Phi[np.ix_(np.r_[np.arange(n), n + 6], np.arange(n + 6))]


def _rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("h", STEPS)
def test_modal_exponentials_are_scipys_expm_of_each_mode(lab, h):
    """Each kept mode ``eta' = lam eta + b . (x_h, v_h)``, the hammer motion's Taylor chain and the
    force integral ``frow_m eta`` as an 8 x 8 complex system: its expm gives d, G, irow and the
    modes' share of icol."""
    side = _side(lab, "fixed")
    assert side.modal
    d = step_exponentials(side, h)
    m = side.m_lam.shape[0]
    want_d = np.empty(m, complex)
    want_G = np.empty((m, 6), complex)
    want_irow = np.empty(m, complex)
    want_icol = -np.array([side.ki * h, side.ci * h, side.ki * h ** 2 / 2, side.ci * h ** 2 / 2,
                           side.ki * h ** 3 / 6, side.ci * h ** 3 / 6])
    for i in range(m):
        Z = np.zeros((8, 8), complex)
        Z[0, 0] = side.m_lam[i]
        Z[0, 1:3] = side.m_B[i]
        Z[1, 3] = Z[2, 4] = Z[3, 5] = Z[4, 6] = 1.0
        Z[7, 0] = side.m_frow[i]
        Phi = sla.expm(Z * h)
        want_d[i], want_G[i], want_irow[i] = Phi[0, 0], Phi[0, 1:7], Phi[7, 0]
        want_icol += Phi[7, 1:7].real
    for name, got, want in (("d", d.m_d, want_d), ("G", d.m_G, want_G), ("irow", d.m_irow, want_irow),
                            ("icol", d.m_icol, want_icol)):
        assert _rel(got, want) <= REL, (name, h, _rel(got, want))


def _scipy_spread(side, h):
    """How far scipy's expm moves under an exact similarity (its own balancing, powers of 2): the
    conditioning floor of any double-precision exponential of this matrix."""
    n = side.n
    Z = _augmented(side) * h
    B, (d, _) = sla.matrix_balance(Z, permute=False, separate=True)
    Phi = sla.expm(B) * d[:, None] / d[None, :]
    rows, cols = np.r_[np.arange(n), n + 6], np.arange(n + 6)
    return _rel(Phi[np.ix_(rows, cols)], sla.expm(Z)[np.ix_(rows, cols)])


@pytest.mark.parametrize("h", STEPS)
def test_dense_exponential_is_scipys_expm(lab, h):
    """The balanced [13/13] Pade exponential of the lab string's fixed-hook side in the dense form:
    within 1e-12 of scipy's, or, where this matrix's exponential is conditioned worse than that
    (h >= 1 ms: scipy's own result moves by 4e-12 at 7 ms, 3e-9 at 0.1 s under an exact
    balancing), within twice scipy's own spread."""
    side = _side(lab, "fixed", dense=True)
    assert not side.modal
    got, want = step_exponentials(side, h).P, _scipy_P(side, h)
    tol = max(REL, 2.0 * _scipy_spread(side, h))
    assert tol <= 1e-8
    assert _rel(got, want) <= tol, (_rel(got, want), tol)


@pytest.mark.parametrize("h", STEPS[:3])
def test_the_auto_drillers_dense_exponential_is_scipys_expm_at_short_steps(lab, h):
    """The lab auto-driller's side steps in the dense form (its eigenbasis fails the modal check)."""
    side = _side(lab, "auto")
    assert not side.modal
    got, want = step_exponentials(side, h).P, _scipy_P(side, h)
    assert _rel(got, want) <= REL, _rel(got, want)


@pytest.mark.slow
def test_the_auto_drillers_dense_exponential_at_a_millisecond_against_34_digits(lab):
    """At h = 0.33 ms the lab auto-driller's exponential is ill conditioned: scipy's is 9e-9 off the
    exact exponential of the same matrix (mpmath, 34 digits), the kernel's 2e-8 (measured); within
    three times scipy's error."""
    mpmath = pytest.importorskip("mpmath")
    side = _side(lab, "auto")
    h = 3.3e-4
    n = side.n
    mpmath.mp.dps = 34
    exact = np.array(mpmath.expm(mpmath.matrix(_augmented(side) * h)).tolist(), dtype=float)
    exact = exact[np.ix_(np.r_[np.arange(n), n + 6], np.arange(n + 6))]
    ours, scipys = _rel(step_exponentials(side, h).P, exact), _rel(_scipy_P(side, h), exact)
    assert ours <= 3.0 * max(scipys, REL), (ours, scipys)


def test_a_step_near_a_built_one_takes_its_exponentials_and_the_cache_is_bounded(lab):
    side = _side(lab, "fixed")
    table = StepTable(side, (1e-3,))
    built = table.get(1e-3)
    assert table.get(1e-3 * (1 + 0.5 * BUILT_STEP_MATCH)) is built
    assert table.get(0.0009999999999994458) is built
    other = table.get(1e-3 * (1 + 2 * BUILT_STEP_MATCH))
    assert other is not built and other.h == 1e-3 * (1 + 2 * BUILT_STEP_MATCH)
    for k in range(3 * STEP_CACHE):
        table.get(1e-4 * (k + 1.5))
    assert len(table.cache) == STEP_CACHE


# ---------------------------------------------------------------------------
# a master's leftover steps
# ---------------------------------------------------------------------------
H = 1e-3
EPS = 1e-13
POINTS = 200
#: a run with a leftover step before every output point equals the run without them to this
LEFTOVER_REL = 1e-9
OUT = ("interface_force", "held_force", "hook_load", "top_position", "top_velocity")
TOPS = {"fixed": 0, "auto-driller": 2}


def _drive(t, rest, scale=1.0):
    """The hammer's motion about its rest: a 25 Hz periodic parabola of 50 um (SI), times ``scale``."""
    u = 25.0 * t
    s = u - math.floor(u)
    return rest + scale * 2e-4 * s * (1.0 - s), scale * 5e-3 * (1.0 - 2.0 * s)


def _points(path, top, leftover, scale=1.0):
    """Outputs at the output points k H; with ``leftover`` each step is H - 1e-13 s and 1e-13 s."""
    from hammerbit.fmu.host import FMUInstance
    fmu = FMUInstance(path, "string", init=False)
    fmu.fmu.setInteger([fmu.vr["top_condition"]], [TOPS[top]])
    try:
        fmu.fmu.exitInitializationMode()
        rest = fmu.get("hammer_position_at_rest")[0]
        rows = []
        for k in range(POINTS):
            t = k * H
            for h in ((H - EPS, EPS) if leftover else (H,)):
                fmu.set(**dict(zip(("hammer_position", "hammer_velocity"), _drive(fmu.t, rest, scale))))
                fmu.step(h)
            fmu.t = t + H                        # the master's clock: the output point itself
            rows.append(fmu.get(*OUT))
    finally:
        fmu.close()
    return np.array(rows)


def _differences(got, want):
    scale = np.maximum(np.max(np.abs(want), axis=0), [0, 0, 0, 1e-4, 1e-2])
    return np.max(np.abs(got - want), axis=0) / scale


@pytest.fixture(scope="module")
def native_lab(built_native_string_fmu):
    """The lab string's native Drillstring.fmu (the session's shared build)."""
    return built_native_string_fmu


def test_a_leftover_step_before_every_output_point_changes_nothing(native_lab):
    """The native FMU (the kernels of the Python flavour, compiled), fixed hook (modal form): the
    leftover takes the last step's polynomial on and moves the history's newest point instead of
    adding one 1e-13 s from the last, so no divided difference spans it."""
    want, got = _points(native_lab, "fixed", False), _points(native_lab, "fixed", True)
    assert np.ptp(want[:, 0]) > 10.0
    err = _differences(got, want)
    assert np.all(err <= LEFTOVER_REL), dict(zip(OUT, err))


def test_a_leftover_step_changes_the_auto_driller_no_more_than_rounding_does(native_lab):
    """The lab's auto-driller (dense form) turns a 1e-15 relative change of the hammer motion into
    ~3e-7 of force in 0.2 s: no run of it is reproducible to 1e-9.  The leftover steps change it
    no more than that rounding-size change of the input does."""
    want = _points(native_lab, "auto-driller", False)
    got = _points(native_lab, "auto-driller", True)
    rounding = _differences(_points(native_lab, "auto-driller", False, scale=1.0 + 1e-15), want)
    err = _differences(got, want)
    assert np.max(rounding) < 1e-5                      # the floor is rounding's, not a failure's
    assert np.all(err <= np.maximum(3.0 * rounding, LEFTOVER_REL)), (dict(zip(OUT, err)), rounding)


def test_the_native_fmu_ships_only_what_it_reads(native_lab):
    names = set(zipfile.ZipFile(native_lab).namelist())
    resources = {n for n in names if n.startswith("resources/")}
    assert resources == {"resources/string_native.bin", "resources/string_info.json"}, resources

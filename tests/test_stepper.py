"""The stepper boundary: bad input is refused quickly and loudly, never hangs.

``Stepper`` validates ``y0`` and ``t_end`` in Python before the kernels see
them; the kernels check finiteness themselves on every path (a direct call
with NaN input returns a status instead of looping).  Every call that could
hang runs under a deadline: a daemon thread for the Python-level checks, a
subprocess with ``timeout=`` for direct kernel calls.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from hammerbit.model import kernel_driver, kernel_layouts
from hammerbit.model.presets import preset
from hammerbit.model.solver_errors import MaxStepsError, NonFiniteStateError, StepSizeError
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper
from hammerbit.model.validation import ParameterError

#: hang guard of a refusal: a check that runs before any integration returns at once, a hang never
#: does; generous, so a busy machine never fails it (the fast set asserts no wall time)
HANG_GUARD_S = 120.0


def within(seconds, fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` in a daemon thread; its exception or result, or fail after ``seconds``."""
    box = {}

    def target():
        t0 = time.perf_counter()
        try:
            box["result"] = fn(*args, **kwargs)
        except BaseException as e:  # noqa: BLE001 - handed to the test
            box["error"] = e
        box["elapsed"] = time.perf_counter() - t0

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(seconds)
    if th.is_alive():
        pytest.fail(f"{getattr(fn, '__name__', fn)} did not return within {seconds} s")
    return box


def _groups():
    return preset("paper-fig9").replace(a=0.083)


# ---------------------------------------------------------------------------
# y0
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("index", [0, 1, 2, 3])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_initial_state_is_refused_before_any_step(index, bad):
    y0 = [0.0, 0.0, 0.0, 0.0]
    y0[index] = bad
    box = within(HANG_GUARD_S, Stepper, _groups(), y0=y0)
    err = box.get("error")
    assert isinstance(err, ParameterError), box
    assert err.name.startswith(f"y0[{index}]")
    assert "finite" in err.allowed
    assert str(bad) in str(err)


def test_infinite_initial_velocity_is_a_parameter_error_not_a_step_size_error():
    box = within(HANG_GUARD_S, Stepper, _groups(), y0=[0.0, math.inf, 0.0, 0.0])
    assert isinstance(box.get("error"), ParameterError)
    assert not isinstance(box.get("error"), StepSizeError)
    assert "hammer velocity" in str(box["error"])


def test_negative_bit_velocity_is_refused():
    with pytest.raises(ParameterError) as ei:
        Stepper(_groups(), y0=[0.0, 0.0, 0.0, -1e-3])
    assert ei.value.name == "y0[3] (bit velocity x4)"
    assert ei.value.allowed.startswith("[0,")


def test_out_of_range_position_is_refused():
    with pytest.raises(ParameterError) as ei:
        Stepper(_groups(), y0=[2e12, 0.0, 0.0, 0.0])
    assert ei.value.name == "y0[0] (hammer position x1)"
    assert ei.value.value == 2e12


@pytest.mark.parametrize("y0", [[0.0, 0.0, 0.0], [0.0] * 5, [[0.0, 0.0], [0.0, 0.0]], "abcd", [0, 0, "x", 0]])
def test_wrong_shape_or_type_of_initial_state_is_refused(y0):
    with pytest.raises(ParameterError) as ei:
        Stepper(_groups(), y0=y0)
    assert ei.value.name == "y0"
    assert "4 real numbers" in ei.value.allowed


def test_valid_initial_state_is_taken_as_given():
    y0 = [0.25, -0.5, 0.125, 0.0]
    st = Stepper(_groups(), y0=np.array(y0))
    assert st.y.tolist() == y0


# ---------------------------------------------------------------------------
# t_end
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("t_end", [math.nan, math.inf, -math.inf, -1.0, 2e12, "soon", None])
def test_bad_end_time_is_refused_and_leaves_the_state_alone(t_end):
    st = Stepper(_groups())
    before = st.get_state()
    box = within(HANG_GUARD_S, st.advance, t_end)
    err = box.get("error")
    assert isinstance(err, ParameterError), box
    assert err.name == "t_end"
    assert np.array_equal(st.get_state(), before, equal_nan=True)


def test_end_time_before_the_current_time_is_refused():
    g = _groups()
    st = Stepper(g)
    st.advance(2.0 * g.period)
    with pytest.raises(ParameterError) as ei:
        st.advance(1.0 * g.period)
    assert "not before the current time" in ei.value.allowed
    assert st.time == 2.0 * g.period


def test_a_refused_call_does_not_perturb_the_run():
    """Refused calls in between leave the result bit-identical to a run without them."""
    g = _groups()
    ref = Stepper(g)
    ref.advance(10.0 * g.period)
    ref.advance(20.0 * g.period)
    st = Stepper(g)
    st.advance(10.0 * g.period)
    for bad in (math.nan, math.inf, 0.0):
        with pytest.raises(ParameterError):
            st.advance(bad)
    st.advance(20.0 * g.period)
    assert np.array_equal(st.y, ref.y)
    assert st.counts == ref.counts


# ---------------------------------------------------------------------------
# max_steps raises, and the run resumes where it stopped
# ---------------------------------------------------------------------------
def test_max_steps_raises_and_the_stepper_resumes():
    g = _groups()
    ref = Stepper(g)
    ref.advance(30.0 * g.period)
    st = Stepper(g, solver=SolverOptions(max_steps=50))
    raised = 0
    while True:
        try:
            st.advance(30.0 * g.period)
            break
        except MaxStepsError as e:
            raised += 1
            assert e.time == st.time < 30.0 * g.period
            assert "max_steps=50" in str(e)
    # a cut at max_steps ends the current step where it is; the resumed run takes the same
    # steps (the proposal is carried in the state), so the result is the same to round-off
    assert raised >= ref.istate[kernel_layouts.I_STEPS] // 50 - 1
    np.testing.assert_allclose(st.y, ref.y, rtol=1e-9, atol=1e-12)
    assert st.counts == ref.counts


# ---------------------------------------------------------------------------
# set_state
# ---------------------------------------------------------------------------
def test_set_state_refuses_a_non_finite_state():
    st = Stepper(_groups())
    s = st.get_state()
    s[1] = math.nan
    with pytest.raises(ParameterError):
        st.set_state(s)
    assert math.isfinite(st.y[1])


# ---------------------------------------------------------------------------
# direct kernel calls: finiteness checks on every path (a subprocess with a timeout)
# ---------------------------------------------------------------------------
_KERNEL_PROBE = r"""
import json, math, sys, time
import numpy as np
from hammerbit.model import kernel_driver, kernel_layouts
from hammerbit.model.presets import preset
from hammerbit.model.stepping import Stepper

g = preset("paper-fig9").replace(a=0.083)

def run(t_end, y=None, p_change=None):
    st = Stepper(g)
    if y is not None:
        st.y[:] = y
    if p_change is not None:
        st.p[p_change[0]] = p_change[1]
    t0 = time.perf_counter()
    status = kernel_driver.advance_hammer(st.y, st.istate, st.fstate, t_end, st.p, st.opts,
                              (np.zeros((0, 5)), np.zeros(0), np.zeros((0, kernel_layouts.N_SAMPLE_COLS)),
                              np.zeros((0, kernel_layouts.N_LOG_COLS))))
    return {"status": int(status), "seconds": time.perf_counter() - t0, "time": float(st.fstate[kernel_layouts.F_T]),
            "finite": bool(np.all(np.isfinite(st.y)))}

run(0.0)  # compile or load the kernels
T = g.period
out = {
    "t_end_nan": run(math.nan),
    "t_end_inf": run(math.inf),
    "t_end_before": run(-T),
    "y_nan": run(T, y=[math.nan, 0.0, 0.0, 0.0]),
    "v_inf": run(T, y=[0.0, math.inf, 0.0, 0.0]),
    # a NaN forcing amplitude reaches the state first through the exact stick chunk
    "stick_nan": run(T, p_change=(kernel_layouts.P_A, math.nan)),
    "ok": run(T),
}
codes = {n: getattr(kernel_layouts, n) for n in ("ST_DONE", "ST_BAD_INPUT", "ST_NONFINITE")}
print(json.dumps({"runs": out, "codes": codes}))
"""


@pytest.fixture(scope="module")
def kernel_probe():
    r = subprocess.run([sys.executable, "-c", _KERNEL_PROBE], capture_output=True, text=True,
                       timeout=1200, env=dict(os.environ))
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("case,code", [("t_end_nan", "ST_BAD_INPUT"), ("t_end_inf", "ST_BAD_INPUT"),
                                       ("t_end_before", "ST_BAD_INPUT"), ("y_nan", "ST_NONFINITE"),
                                       ("v_inf", "ST_NONFINITE"), ("stick_nan", "ST_NONFINITE"),
                                       ("ok", "ST_DONE")])
def test_kernel_refuses_non_finite_input(kernel_probe, case, code):
    run = kernel_probe["runs"][case]
    assert run["status"] == kernel_probe["codes"][code], run
    assert run["seconds"] < HANG_GUARD_S
    if case == "ok":
        assert run["finite"]
    if case.startswith("t_end"):
        assert run["time"] == 0.0  # the clock did not move


def test_stepper_reports_a_nan_parameter_as_non_finite_state():
    """A NaN that gets past validation (written into p directly) ends in NonFiniteStateError."""
    g = _groups()
    st = Stepper(g)
    st.p[kernel_layouts.P_A] = math.nan
    box = within(600.0, st.advance, g.period)  # first call may compile the kernels
    assert isinstance(box.get("error"), NonFiniteStateError), box


def test_load_changes_nothing_and_the_run_is_the_same():
    """``load`` only loads the compiled kernel: state and later results are those of a stepper without it."""
    g = preset("paper-fig9").replace(a=0.083)
    loaded, plain = Stepper(g), Stepper(g)
    before = loaded.get_state()
    assert loaded.load() is True  # the test session has compiled the kernels
    assert np.array_equal(loaded.get_state(), before)
    loaded.advance(20 * g.period)
    plain.advance(20 * g.period)
    assert np.array_equal(loaded.get_state(), plain.get_state())


def test_load_never_compiles(monkeypatch):
    import hammerbit.model.stepping as S
    monkeypatch.setattr(S, "kernels_cached", lambda entry: False)
    st = Stepper(preset("paper-fig9"))
    monkeypatch.setattr(S.Stepper, "advance", lambda *a, **k: pytest.fail("load() ran the kernel"))
    assert st.load() is False


def test_a_full_event_log_returns_log_full_and_the_next_call_resumes():
    """With room for 3 events the stepper stops at the log's end and says 'log_full'; a call with
    a fresh buffer goes on from there, and the two logs together are the one-call log."""
    g = preset("paper-fig12").replace(a=0.06)
    ref = Stepper(g)
    big = np.zeros((500, kernel_layouts.N_LOG_COLS))
    assert ref.advance(5 * g.period, log=big) == "done"
    n_ref = int(ref.istate[kernel_layouts.I_NLOG])
    assert n_ref > 6
    st = Stepper(g)
    small = np.zeros((3, kernel_layouts.N_LOG_COLS))
    assert st.advance(5 * g.period, log=small) == "log_full"
    assert st.time < 5 * g.period
    st.istate[kernel_layouts.I_NLOG] = 0
    rest = np.zeros((500, kernel_layouts.N_LOG_COLS))
    assert st.advance(5 * g.period, log=rest) == "done"
    joined = np.vstack([small, rest[:int(st.istate[kernel_layouts.I_NLOG])]])
    assert np.array_equal(joined, big[:n_ref])
    assert np.array_equal(st.y, ref.y)

"""The FMI 3.0 native HammerBitRock.fmu (``hammerbit fmu build --runtime native --fmi-version 3``).

Oracles: the FMI 3.0 schema fmpy ships and ``fmpy validate``; the FMI 2.0 native FMU (the same
model layer behind the FMI 2.0 front); the library's ``Stepper`` advanced over the same
communication points with a one-row event log, which stops it at the first event as the FMU's
early return does; the library's own simulation for Model Exchange.
"""
from __future__ import annotations

import ctypes
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402

from hammerbit.model import kernel_layouts as KL  # noqa: E402
from hammerbit.model.presets import preset  # noqa: E402
from hammerbit.model.solver_options import SolverOptions  # noqa: E402
from hammerbit.model.stepping import Stepper  # noqa: E402

#: the FMU's default tolerance (its ``tolerance`` parameter) as the library's solver options
FMU_SOLVER = SolverOptions(rtol=1e-8, atol=1e-10)
H = 1e-3


@pytest.fixture(scope="module")
def fmu3(built_native_fmu3):
    return built_native_fmu3


@pytest.fixture(scope="module")
def fmu3_dir(fmu3, tmp_path_factory):
    d = tmp_path_factory.mktemp("fmi3_unzipped")
    with zipfile.ZipFile(fmu3) as zf:
        zf.extractall(d)
    return d


def scene_start_values(groups) -> dict:
    """FMU start values of a scene of the library (SI, FMU names)."""
    rig = groups.to_rig()
    names = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
             "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
             "contact_damping", "amplitude", "frequency", "phase", "preload")
    sv = {n: getattr(rig, n) for n in names}
    if math.isfinite(rig.gap):
        sv.update(gap=rig.gap, impact_enabled=True)
    return sv


#: a scene with impacts and stick-slip: paper Fig. 12 (a = 0.06, gap closed by impacts)
def impact_scene():
    return preset("paper-fig12").replace(a=0.06)


# ---------------------------------------------------------------------------------------------
# the model description
# ---------------------------------------------------------------------------------------------
def test_model_description_is_valid_fmi3(fmu3):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmu3)) == []
    etree = pytest.importorskip("lxml.etree")
    xsd = Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3ModelDescription.xsd"
    schema = etree.XMLSchema(etree.parse(str(xsd)))
    with zipfile.ZipFile(fmu3) as zf:
        doc = etree.fromstring(zf.read("modelDescription.xml"))
        names = set(zf.namelist())
    assert schema.validate(doc), str(schema.error_log)
    assert "binaries/x86_64-linux/HammerBitRock.so" in names


def test_variables_are_fmi2s_in_fmi3_types(fmu3, built_native_fmu):
    md3, md2 = read_model_description(str(fmu3)), read_model_description(str(built_native_fmu))
    v3 = {v.name: v for v in md3.modelVariables}
    expect = {"Real": "Float64", "Boolean": "Boolean", "String": "String"}
    for v in md2.modelVariables:
        w = v3[v.name]
        want = expect.get(v.type) or ("UInt64" if v.name.endswith("_count") else "Int32")
        assert (w.type, w.valueReference, w.causality, w.variability, w.unit, w.start) == \
            (want, v.valueReference, v.causality, v.variability, v.unit, v.start), v.name
    assert {v3[n].type for n in ("impact_count", "slip_count", "bounce_count")} == {"UInt64"}
    assert v3["stick_slip"].type == "Int32" and v3["in_contact"].type == "Boolean"
    assert md3.coSimulation.mightReturnEarlyFromDoStep and md3.coSimulation.hasEventMode
    assert md3.coSimulation.canHandleVariableCommunicationStepSize
    assert len(md3.eventIndicators) == KL.N_EVENT_KINDS and len(md3.derivatives) == 4
    assert [v.name for v in md3.modelVariables if v.causality == "independent"] == ["time"]


# ---------------------------------------------------------------------------------------------
# Co-Simulation
# ---------------------------------------------------------------------------------------------
OUTS = ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity", "rock_force",
        "stick_slip", "in_contact", "impact_count", "slip_count")


def _run(fmu, seconds, start_values=None, **kw):
    return simulate_fmu(str(fmu), stop_time=seconds, output_interval=H, step_size=H,
                        start_values=start_values or {}, output=list(OUTS), **kw)


@pytest.mark.parametrize("seconds", [2.0, pytest.param(10.0, marks=pytest.mark.slow)])
def test_cs_without_flags_is_bit_identical_to_fmi2(fmu3, built_native_fmu, seconds):
    sv = scene_start_values(impact_scene())
    r2, r3 = _run(built_native_fmu, seconds, sv), _run(fmu3, seconds, sv)
    assert r2["impact_count"][-1] > 0                     # the scene has impacts
    for n in OUTS:
        assert np.array_equal(r2[n].astype(float), r3[n].astype(float)), n


def stepper_events(rig, t_grid):
    """The oracle: event times [s] of the library's Stepper advanced to each point of t_grid and
    stopped at the first event inside each advance (a one-row event log), as the FMU's early
    return stops; an event at the start of an advance was reported by the one before."""
    g, F0 = rig.to_groups(), rig.scales.friction_force
    st = Stepper(g.replace(b=0.0), solver=FMU_SOLVER)
    st.p[KL.P_B] = rig.preload / F0
    om, log, events = rig.scales.omega, np.zeros((1, KL.N_LOG_COLS)), []
    for t in t_grid:
        while True:
            tau0 = st.time
            st.istate[KL.I_NLOG] = 0
            status = st.advance(t * om, log=log)
            if status == "done":
                break
            if st.time > tau0:
                events.append((st.time / om, int(log[0, KL.L_KIND])))
    return events, st.y.copy() * np.array([rig.scales.length, rig.scales.velocity] * 2)


def fmu_events(fmu_dir, rig_sv, t_grid, event_mode):
    """Early-return times of the FMU stepped to each point of t_grid, and its final state."""
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(fmu_dir),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="er")
    s.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=True)
    s.enterInitializationMode(startTime=0.0)
    for name, v in rig_sv.items():
        if isinstance(v, bool):
            s.setBoolean([vr[name]], [v])
        else:
            s.setFloat64([vr[name]], [float(v)])
    s.exitInitializationMode()
    if event_mode:
        assert s.updateDiscreteStates()[0] is False
        s.enterStepMode()
    t, events, handled = 0.0, [], 0
    for target in t_grid:
        while t < target:
            need, term, early, t_new = s.doStep(t, target - t)
            assert not term and t_new > t                  # time always advances
            if early:
                events.append(t_new)
                assert need == event_mode
                if event_mode:
                    s.enterEventMode()
                    s.updateDiscreteStates()
                    s.enterStepMode()
                    handled += 1
            else:
                assert t_new == target and not need
            t = t_new
    y = s.getFloat64([vr[n] for n in OUTS[:4]])
    s.terminate()
    s.freeInstance()
    return events, np.array(y), handled


@pytest.mark.parametrize("event_mode", [False, True])
@pytest.mark.parametrize("seconds", [1.5, pytest.param(10.0, marks=pytest.mark.slow)])
def test_early_return_at_the_steppers_events(fmu3_dir, event_mode, seconds):
    rig = impact_scene().to_rig()
    grid = [(k + 1) * H for k in range(round(seconds / H))]
    lib, y_lib = stepper_events(rig, grid)
    got, y, handled = fmu_events(fmu3_dir, scene_start_values(impact_scene()), grid, event_mode)
    kinds = {k for _, k in lib}
    assert {KL.EV_IMPACT, KL.EV_SEPARATION, KL.EV_SLIP_START, KL.EV_STICK} <= kinds
    assert len(got) == len(lib) and handled == (len(lib) if event_mode else 0)
    np.testing.assert_allclose(got, [t for t, _ in lib], rtol=1e-12, atol=0)
    np.testing.assert_allclose(y, y_lib, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("early,event_mode", [(True, False), (True, True), (False, True)])
@pytest.mark.parametrize("seconds", [1.5, pytest.param(10.0, marks=pytest.mark.slow)])
def test_fmpy_with_early_return_and_event_mode_ends_as_fmi2(fmu3, built_native_fmu, early, event_mode,
                                                            seconds):
    sv = scene_start_values(impact_scene())
    r2 = _run(built_native_fmu, seconds, sv)
    r3 = _run(fmu3, seconds, sv, early_return_allowed=early, use_event_mode=event_mode)
    n_events = r2["impact_count"][-1] + r2["slip_count"][-1]
    assert (len(r3) > len(r2)) == early and (len(r3) - len(r2) >= n_events if early else True)
    for n in OUTS[:4]:
        assert r3[n][-1] == pytest.approx(r2[n][-1], rel=1e-12, abs=1e-15), n
    for n in OUTS[5:]:
        assert r3[n][-1] == r2[n][-1], n


# ---------------------------------------------------------------------------------------------
# Model Exchange
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scene,a,periods", [
    ("paper-fig9", 0.083, 20),
    pytest.param("paper-fig9", 0.083, 100, marks=pytest.mark.slow),
    pytest.param("paper-fig12", 0.06, 100, marks=pytest.mark.slow)])
def test_model_exchange_with_cvode_reproduces_co_simulation(fmu3, scene, a, periods):
    from hammerbit.scene.analysis import detect_period
    g = preset(scene).replace(a=a)
    sc, sv = g.scales, scene_start_values(g)
    out = ["hammer_position", "hammer_velocity", "bit_position", "bit_velocity"]
    kw = dict(stop_time=periods * g.period_s, output_interval=g.period_s, output=out)
    me = simulate_fmu(str(fmu3), fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10,
                      record_events=False, start_values=sv, **kw)
    cs = simulate_fmu(str(fmu3), fmi_type="CoSimulation", start_values={**sv, "tolerance": 1e-10}, **kw)
    x_me, x_cs = me["bit_position"][-1], cs["bit_position"][-1]
    assert x_cs > 0.0 and abs(x_me - x_cs) <= 1e-6 * abs(x_cs)

    def poincare(r):
        return np.column_stack([r["time"], r["hammer_position"] / sc.length, r["hammer_velocity"] / sc.velocity,
                                r["bit_position"] / sc.length, r["bit_velocity"] / sc.velocity])
    if periods >= 100:
        n_cs = detect_period(poincare(cs))
        assert n_cs is not None and detect_period(poincare(me)) == n_cs


# ---------------------------------------------------------------------------------------------
# FMU states, calls out of place
# ---------------------------------------------------------------------------------------------
def _slave(fmu_dir, **kw):
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(fmu_dir), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="t")
    messages = []
    s.instantiate(logMessage=lambda env, status, cat, msg: messages.append((status, msg.decode())), **kw)
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    return s, vr, messages


def test_fmu_state_round_trip_and_serialisation(fmu3_dir):
    s, vr, _ = _slave(fmu3_dir)
    outs = [vr[n] for n in OUTS[:4]]
    for k in range(50):
        s.doStep(k * H, H)
    state = s.getFMUState()
    blob = s.serializeFMUState(state)
    for k in range(50, 120):
        s.doStep(k * H, H)
    y_a, n_a = s.getFloat64(outs), s.getUInt64([vr["slip_count"]])
    s.setFMUState(s.deserializeFMUState(blob))
    assert s.getFloat64([vr["time"]]) == [50 * H]
    for k in range(50, 120):
        s.doStep(k * H, H)
    assert s.getFloat64(outs) == y_a and s.getUInt64([vr["slip_count"]]) == n_a
    s.freeFMUState(state)
    s.terminate()
    s.freeInstance()


def test_calls_out_of_place_are_errors_with_messages(fmu3_dir):
    s, vr, messages = _slave(fmu3_dir)
    with pytest.raises(FMICallException):                 # a UInt64 read as Int32
        s.getInt32([vr["impact_count"]])
    assert "impact_count" in messages[-1][1] and "UInt64" in messages[-1][1]
    s.reset()
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    with pytest.raises(FMICallException):                 # Event Mode was not asked for
        s.enterEventMode()
    assert "eventModeUsed" in messages[-1][1]
    s.reset()
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    with pytest.raises(FMICallException):                 # the time is the independent variable
        s.setFloat64([vr["time"]], [1.0])
    assert "'time'" in messages[-1][1] and "cannot be set" in messages[-1][1]
    s.freeInstance()
    e, _, _ = _slave(fmu3_dir, eventModeUsed=True)        # after initialisation: Event Mode
    with pytest.raises(FMICallException):
        e.doStep(0.0, H)
    e.freeInstance()


@pytest.mark.parametrize("argv", [["fmu", "build", "--fmi-version", "3"],
                                  ["fmu", "build-string", "--string", "lab", "--fmi-version", "3"],
                                  ["fmu", "build", "--runtime", "native", "--fmi-version", "4"]])
def test_cli_refuses_fmi3_without_the_native_runtime(argv, capsys, tmp_path):
    from cli_run import run_cli
    code, out, err = run_cli([*argv, "--out", str(tmp_path / "x.fmu")], capsys)
    assert code == 2 and "Traceback" not in err and "--fmi-version" in err
    assert not (tmp_path / "x.fmu").exists()


def test_model_exchange_time_and_states_round_trip(fmu3_dir):
    from fmpy.fmi3 import FMU3Model
    md = read_model_description(str(fmu3_dir / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    m = FMU3Model(guid=md.guid, unzipDirectory=str(fmu3_dir), modelIdentifier=md.modelExchange.modelIdentifier,
                  instanceName="me")
    m.instantiate()
    m.enterInitializationMode(startTime=0.0)
    m.exitInitializationMode()
    m.updateDiscreteStates()
    m.enterContinuousTimeMode()
    m.setTime(0.25)
    state = m.getFMUState()
    z = m.getFloat64([vr[f"event_indicator_{n}"] for n in KL.EVENT_NAMES])
    buf = (ctypes.c_double * KL.N_EVENT_KINDS)()
    m.getEventIndicators(buf, KL.N_EVENT_KINDS)
    assert list(buf) == z                                # the variables are the indicators
    m.setTime(0.5)
    assert m.getFloat64([vr["time"]]) == [0.5]
    m.setFMUState(state)
    assert m.getFloat64([vr["time"]]) == [0.25]         # the time is part of the FMU state
    assert m.getFloat64([vr[f"event_indicator_{n}"] for n in KL.EVENT_NAMES]) == z
    m.freeFMUState(state)
    m.terminate()
    m.freeInstance()


def test_fmi3_reference_results_equal_its_run_in_fmpy(fmu3):
    """The FMI-LS-REF results the FMI 3.0 build ships (the library's slave) against fmpy's run
    of its default experiment (tests/reference_check.py says how close and why)."""
    from reference_check import compare_with_fmpy
    compare_with_fmpy(fmu3)


def test_regime_is_an_int32_output_with_the_fmi2_flavours_bits(fmu3_dir):
    """The runaway scene of tests/test_fmu_regime.py: the FMI 3.0 front reads the same ``regime``
    (Int32) as the in-process slave after every forcing period, logs the same one warning, and a
    restored state brings back its regime."""
    from test_fmu_regime import SCENES, _regime_warnings, _run
    from test_fmu_regime import _slave as regime_slave
    groups, periods = SCENES["runaway"]
    sv = scene_start_values(groups)
    s, vr, messages = _slave(fmu3_dir)
    s.reset()
    s.enterInitializationMode(startTime=0.0)
    for name, value in sv.items():
        if isinstance(value, bool):
            s.setBoolean([vr[name]], [value])
        else:
            s.setFloat64([vr[name]], [float(value)])
    s.exitInitializationMode()
    h = 1.0 / sv["frequency"]
    seen, state, t = [], None, 0.0
    for k in range(periods):
        s.doStep(t, h)
        t += h
        seen.append(s.getInt32([vr["regime"]])[0])
        if k == 1:
            state = s.getFMUState()
    ref, _ = regime_slave(groups)
    assert seen == _run(ref, h, periods)
    assert [m for _, m in messages if m.startswith("regime at t")] == _regime_warnings(ref)
    s.setFMUState(state)
    assert s.getInt32([vr["regime"]])[0] == seen[1] == 0
    s.freeFMUState(state)
    s.freeInstance()

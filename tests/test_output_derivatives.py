"""Output derivatives of the native HammerBitRock.fmu (fmi2GetRealOutputDerivatives, FMI 3's
fmi3GetOutputDerivatives) and the input derivatives of the native Drillstring.fmu.

Oracle: finite differences of a fine-step run of the same FMU at a tight tolerance (a polynomial
through the outputs at five points ``t + k eps`` inside one hybrid mode), in slip, stick and
contact.  The derivatives come from the vector field and its closed-form derivative; the
finite differences only from the outputs, so they share no formula.  Their own error is measured
by the same fit over twice the spacing.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi1 import FMICallException  # noqa: E402

from hammerbit.fmu.host import FMUInstance  # noqa: E402
from hammerbit.model.presets import preset  # noqa: E402

#: the Real outputs of HammerBitRock
OUTPUTS = ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity", "spring_force",
           "contact_force", "rock_force", "friction_force", "rate_of_penetration")
#: points of the finite-difference fit
N_FIT = 5
#: fine steps of the oracle per mode [s]: the contact's time scale is far shorter than the free flight's
FD_STEP = {"slip": 1e-5, "stick": 1e-5, "contact": 2e-7}
RIG_NAMES = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic", "friction_decay",
             "normal_force", "contact_stiffness", "contact_exponent", "contact_damping", "amplitude",
             "frequency", "phase", "preload")


def impact_values() -> dict:
    """FMU start values of paper Fig. 12 at a = 0.06 (impacts, stick and slip), tolerance 1e-12."""
    rig = preset("paper-fig12").replace(a=0.06).to_rig()
    sv = {n: getattr(rig, n) for n in RIG_NAMES}
    sv.update(gap=rig.gap, tolerance=1e-12)
    return sv


def open_hammer(fmu) -> FMUInstance:
    return FMUInstance(fmu, "hammer", reals=impact_values(), booleans={"impact_enabled": True})


def mode_of(inst) -> tuple:
    """(kind, everything discrete): the hybrid mode and the counters."""
    stick_slip, impacts, slips, bounces = inst.get_int("stick_slip", "impact_count", "slip_count",
                                                      "bounce_count")
    contact = bool(inst.get_bool("in_contact")[0])
    kind = "contact" if contact else ("slip" if stick_slip == 1 else "stick")
    return kind, (stick_slip, impacts, slips, bounces, contact)


def fd_derivatives(inst, eps: float):
    """Orders 1 and 2 of the outputs at the instance's time from the outputs at t + k eps
    (k < N_FIT), or None if a mode changes on the way; the instance is rolled back."""
    f = inst.fmu
    state, t0 = f.getFMUState(), inst.t
    _, discrete = mode_of(inst)
    rows, same = [inst.get(*OUTPUTS)], True
    for _ in range(1, N_FIT):
        inst.step(eps)
        rows.append(inst.get(*OUTPUTS))
        same = same and mode_of(inst)[1] == discrete
    f.setFMUState(state)
    f.freeFMUState(state)
    inst.set_time(t0)
    if not same:
        return None
    s = np.arange(N_FIT) * eps
    taylor = np.array([[sk ** j / math.factorial(j) for j in range(N_FIT)] for sk in s])
    c = np.linalg.solve(taylor, np.array(rows))
    return c[1], c[2]


def points_by_mode(inst, t_min=0.05, t_max=1.0, h=2e-4) -> dict:
    """{mode: (t, fmu derivatives of orders 1 and 2, their finite differences, the finite
    differences over twice the spacing)} at the first point of each mode whose fit stays in it."""
    vrs = [inst.vr[n] for n in OUTPUTS]
    found = {}
    while inst.t < t_max and len(found) < 3:
        inst.step(h)
        kind, _ = mode_of(inst)
        if kind in found or inst.t < t_min:
            continue
        eps = FD_STEP[kind]
        fd, fd2 = fd_derivatives(inst, eps), fd_derivatives(inst, 2 * eps)
        if fd is None or fd2 is None:
            continue
        got = [np.array(inst.fmu.getRealOutputDerivatives(vrs, [k] * len(vrs))) for k in (1, 2)]
        found[kind] = (inst.t, got, fd, fd2)
    return found


@pytest.fixture(scope="module")
def mode_points(built_native_fmu):
    inst = open_hammer(built_native_fmu)
    try:
        return points_by_mode(inst)
    finally:
        inst.close()


def test_description_declares_order_2(built_native_fmu, built_fmu):
    from fmpy import read_model_description
    assert read_model_description(str(built_native_fmu)).coSimulation.maxOutputDerivativeOrder == 2
    # the pythonfmu flavour declares none
    assert not read_model_description(str(built_fmu)).coSimulation.maxOutputDerivativeOrder


@pytest.mark.parametrize("kind", ["slip", "stick", "contact"])
@pytest.mark.parametrize("order", [1, 2])
def test_derivatives_equal_finite_differences(mode_points, kind, order):
    assert kind in mode_points, f"the run reached no {kind} point: {sorted(mode_points)}"
    t, got, fd, fd2 = mode_points[kind]
    g, d = got[order - 1], fd[order - 1]
    # the finite differences' own error: their change from the spacing eps to 2 eps
    fd_err = np.abs(fd[order - 1] - fd2[order - 1])
    # and their rounding: the run's tolerance 1e-12 over eps^order
    tol = (1e-8, 1e-6)[order - 1] * np.abs(d) + 4.0 * fd_err + 1e-12
    bad = [f"{n}: {a!r} vs {b!r} (tolerance {e:.2g})" for n, a, b, e in zip(OUTPUTS, g, d, tol)
           if not abs(a - b) <= e]
    assert not bad, f"{kind} at t = {t} s, order {order}: " + "; ".join(bad)
    # the oracle resolves the derivatives it checks: the kinematic ones to 1e-6 (order 1) and
    # 1e-3 (order 2) or better
    kin = np.abs(d[:4])
    assert np.all(fd_err[:4] <= (1e-6, 1e-3)[order - 1] * kin + 1e-12), (kind, order, fd_err[:4], kin)


def test_stick_has_no_bit_motion_and_friction_is_the_reaction(mode_points):
    t, got, _, _ = mode_points["stick"]
    i = {n: k for k, n in enumerate(OUTPUTS)}
    for order in (0, 1):
        assert got[order][i["bit_position"]] == 0.0 and got[order][i["bit_velocity"]] == 0.0
        assert got[order][i["friction_force"]] == got[order][i["rock_force"]]


def _refused(inst, vrs, orders, text):
    with pytest.raises(FMICallException):
        inst.fmu.getRealOutputDerivatives(vrs, orders)
    assert any(text in m for m in inst.errors()), inst.errors()


@pytest.mark.parametrize("case", ["order 3", "order 0", "parameter", "integer output"])
def test_refusals_are_errors_with_a_message(built_native_fmu, case):
    inst = open_hammer(built_native_fmu)
    try:
        inst.step(1e-3)
        if case == "order 3":
            _refused(inst, [inst.vr["hammer_position"]], [3], "order[0] = 3 is out of range: allowed 1, 2")
        elif case == "order 0":
            _refused(inst, [inst.vr["hammer_velocity"]], [0], "order[0] = 0 is out of range")
        elif case == "parameter":
            _refused(inst, [inst.vr["stiffness"]], [1], "is not a Real output")
        else:
            _refused(inst, [inst.vr["impact_count"]], [1], "not a Real")
    finally:
        inst.close()


def test_asking_changes_nothing(built_native_fmu):
    """Two runs, one asked for every derivative after every step, end bit-identical."""
    a, b = open_hammer(built_native_fmu), open_hammer(built_native_fmu)
    vrs = [a.vr[n] for n in OUTPUTS]
    try:
        for _ in range(300):
            for inst in (a, b):
                inst.step(1e-3)
            a.fmu.getRealOutputDerivatives(vrs + vrs, [1] * len(vrs) + [2] * len(vrs))
        assert a.get(*OUTPUTS) == b.get(*OUTPUTS)
    finally:
        a.close()
        b.close()


def test_a_refused_call_loses_no_state(built_native_fmu):
    """After a refused derivative call (fmi2Error), the saved state recovers the instance, which then
    goes on bit-identical to one never refused."""
    a, b = open_hammer(built_native_fmu), open_hammer(built_native_fmu)
    try:
        for inst in (a, b):
            inst.step(2e-3)
        saved = a.fmu.getFMUState()
        with pytest.raises(FMICallException):
            a.fmu.getRealOutputDerivatives([a.vr["bit_velocity"], a.vr["stiffness"]], [1, 1])
        a.fmu.setFMUState(saved)
        a.fmu.freeFMUState(saved)
        for _ in range(100):
            for inst in (a, b):
                inst.step(1e-3)
        assert a.get(*OUTPUTS) == b.get(*OUTPUTS)
    finally:
        a.close()
        b.close()


def test_pythonfmu_flavour_refuses(built_fmu):
    inst = FMUInstance(built_fmu, "hammer")
    try:
        inst.step(1e-3)
        _refused(inst, [inst.vr["hammer_position"]], [1], "maxOutputDerivativeOrder = 0")
    finally:
        inst.close()


# ---------------------------------------------------------------------------------------------
# FMI 3.0: fmi3GetOutputDerivatives
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fmu3_dir(built_native_fmu3, tmp_path_factory):
    import zipfile
    d = tmp_path_factory.mktemp("fmi3_unzipped")
    with zipfile.ZipFile(built_native_fmu3) as zf:
        zf.extractall(d)
    return d


def test_fmi3_derivatives_are_fmi2s(fmu3_dir, built_native_fmu):
    """The FMI 3.0 front gives the FMI 2.0 front's derivatives (one model layer), after a run
    through impacts; it declares order 2 and refuses order 3 and a non-output."""
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Slave
    md = read_model_description(str(fmu3_dir / "modelDescription.xml"))
    assert md.coSimulation.maxOutputDerivativeOrder == 2
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(fmu3_dir), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="d3")
    s.instantiate()
    s.enterInitializationMode(startTime=0.0)
    for name, v in impact_values().items():
        s.setFloat64([vr[name]], [float(v)])
    s.setBoolean([vr["impact_enabled"]], [True])
    s.exitInitializationMode()
    two = open_hammer(built_native_fmu)
    vrs3, vrs2 = [vr[n] for n in OUTPUTS], [two.vr[n] for n in OUTPUTS]
    try:
        t = 0.0
        for _ in range(240):
            s.doStep(t, 1e-3)
            two.step(1e-3)
            t += 1e-3
        for order in (1, 2):
            got3 = s.getOutputDerivatives(vrs3, [order] * len(vrs3))
            got2 = two.fmu.getRealOutputDerivatives(vrs2, [order] * len(vrs2))
            assert got3 == got2
        with pytest.raises(FMICallException):
            s.getOutputDerivatives([vr["hammer_position"]], [3])
    finally:
        s.freeInstance()              # the refusal left it in the Error state: no fmi3Terminate
        two.close()


# ---------------------------------------------------------------------------------------------
# Drillstring.fmu: fmi2SetRealInputDerivatives (canInterpolateInputs)
# ---------------------------------------------------------------------------------------------
STRING_OUTPUTS = ("interface_force", "hook_load", "top_position", "top_velocity")
#: the hammer's acceleration of the polynomial motion [m/s^2]
ACCEL = 0.3


def string_run(fmu, h: float, stop: float, derivatives: bool) -> np.ndarray:
    """The string's outputs every 1 ms to ``stop`` with the hammer moving as
    x = x_rest + ACCEL t^2 / 2 from rest, stepped by ``h``; with ``derivatives`` its input derivatives
    are set before every step (else the string's own extrapolation)."""
    inst = FMUInstance(fmu, "string")
    rows = []
    try:
        x_rest = inst.get("hammer_position_at_rest")[0]
        vx, vv = inst.vr["hammer_position"], inst.vr["hammer_velocity"]
        n_out, per = int(round(stop / 1e-3)), int(round(1e-3 / h))
        for k in range(n_out * per):
            t = k * h
            inst.set(hammer_position=x_rest + 0.5 * ACCEL * t * t, hammer_velocity=ACCEL * t)
            if derivatives:
                inst.fmu.setRealInputDerivatives([vx, vv, vx, vv], [1, 1, 2, 2], [ACCEL * t, ACCEL, ACCEL, 0.0])
            inst.step(h)
            if (k + 1) % per == 0:
                rows.append(inst.get(*STRING_OUTPUTS))
    finally:
        inst.close()
    return np.array(rows)


def test_string_declares_interpolation(built_native_string_fmu):
    from fmpy import read_model_description
    assert read_model_description(str(built_native_string_fmu)).coSimulation.canInterpolateInputs


def test_string_is_exact_for_a_polynomial_motion(built_native_string_fmu):
    """A hammer motion that is its own Taylor polynomial: with its input derivatives the string's
    step is exact, so 1 ms and 0.1 ms steps give one answer; held inputs do not."""
    stop = 0.05
    coarse = string_run(built_native_string_fmu, 1e-3, stop, True)
    fine = string_run(built_native_string_fmu, 1e-4, stop, True)
    held = string_run(built_native_string_fmu, 1e-3, stop, False)
    scale = np.max(np.abs(fine), axis=0) + 1e-300
    assert np.max(np.abs(coarse - fine) / scale) < 1e-9
    # the string's own extrapolation through the past inputs is not exact over the first steps
    assert np.max(np.abs(held - fine) / scale) > 1e-6


@pytest.mark.parametrize("case", ["order 3", "a parameter"])
def test_string_refuses_bad_input_derivatives(built_native_string_fmu, case):
    inst = FMUInstance(built_native_string_fmu, "string")
    try:
        vr = inst.vr["hammer_position"] if case == "order 3" else inst.vr["wob"]
        with pytest.raises(FMICallException):
            inst.fmu.setRealInputDerivatives([vr], [3 if case == "order 3" else 1], [1.0])
        said = "order[0] = 3 is out of range: allowed 1, 2" if case == "order 3" else "wob"
        assert any(said in m for m in inst.errors()), inst.errors()
    finally:
        inst.close()


# ---------------------------------------------------------------------------------------------
# the fixed-step Jacobi masters: the hammer's output derivatives into the string
# ---------------------------------------------------------------------------------------------
#: the runs of the masters [s] and their step
MASTER_STOP, MASTER_STEP = 0.2, 1e-3


@pytest.fixture(scope="module")
def master_runs(built_native_ssp):
    """Penetrations of the user loop (through both FMUs) and of ``cosim --ssp`` (the string side in
    process), with and without output derivatives."""
    from hammerbit.ssp.run import cosimulate_ssp
    from hammerbit.ssp.runners import run_user_loop
    out = {}
    for given in (False, True):
        out["loop", given] = run_user_loop(built_native_ssp, MASTER_STOP, MASTER_STEP,
                                           output_derivatives=given).penetration_m
        out["cosim", given] = cosimulate_ssp(built_native_ssp, stop=MASTER_STOP, step=MASTER_STEP, adaptive=False,
                                             estimate=False, output_derivatives=given).penetration_m
    return out


def test_both_masters_pass_the_same_derivatives(master_runs):
    """The Drillstring FMU's input derivatives and the in-process string side's given polynomial are
    two implementations of one exchange: the same run to rounding; without derivatives another."""
    on_loop, on_cosim = master_runs["loop", True], master_runs["cosim", True]
    off = master_runs["loop", False]
    assert off > 1e-4                                     # the bit moved
    assert abs(on_loop - on_cosim) <= 1e-9 * on_cosim, (on_loop, on_cosim)
    assert abs(on_loop - off) > 1e-6 * off, (on_loop, off)


def test_cli_output_derivatives(built_native_ssp, built_ssp, capsys):
    from cli_run import run_cli
    base = ["cosim", "--ssp", str(built_native_ssp), "--step", "1e-3", "--stop", "0.05", "--json"]
    code, out, err = run_cli(base + ["--output-derivatives"], capsys)
    assert code in (0, 5), err
    assert '"output_derivatives": true' in out
    # the pythonfmu package has none: refused before the run, naming the option
    code, out, err = run_cli(["cosim", "--ssp", str(built_ssp), "--step", "1e-3", "--stop", "0.05",
                              "--output-derivatives"], capsys)
    assert code == 2 and "--output-derivatives" in err and "maxOutputDerivativeOrder = 0" in err
    assert "Traceback" not in err
    # without --step (the adaptive run) it is refused
    code, out, err = run_cli(["cosim", "--ssp", str(built_native_ssp), "--output-derivatives"], capsys)
    assert code == 2 and "--output-derivatives" in err and "Traceback" not in err

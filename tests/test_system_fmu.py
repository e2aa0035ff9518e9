"""DrillingSystem.fmu (``hammerbit fmu build-system``) against the monolithic reference.

The oracle is the library's monolithic reference (:func:`hammerbit.cosim.reference.monolithic`,
or a Stepper run of the same subsystem with the same input schedule) at a tolerance a hundred
times tighter than the FMU's: penetration at each whole second and the mean WOB over each second
(from the reference's dense output) must agree to the FMU's ``tolerance`` (1e-3), for any master
step.
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

from hammerbit.cosim.config import CosimConfig, default_hammer  # noqa: E402
from hammerbit.drillstring import load_string  # noqa: E402
from hammerbit.drillstring.top import TopCondition  # noqa: E402

TOL = 1e-3
STOP = 2.0
REF_RTOL = 1e-6


def _config(string, top, stop=STOP, rtol=REF_RTOL):
    return CosimConfig(stop=stop, step=0.01, rig=default_hammer(string), top=TopCondition.parse(top), rtol=rtol)


@pytest.fixture(scope="module")
def field():
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def field_auto_fmu(built_field_system_fmu):
    """field-2200m under the auto-driller, STOP at H = 10 ms (the session's shared build: the
    reference's rtol is not the FMU's)."""
    return built_field_system_fmu


class Slave:
    """The FMU in fmpy's FMU2Slave, started at t = 0 (``logger``: a list that collects its log
    messages, else fmpy's default logger)."""

    def __init__(self, path, logger=None):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName="system")
        callbacks = None
        if logger is not None:
            from fmpy.fmi2 import defaultCallbacks
            callbacks = fmi2CallbackFunctions()
            callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg: logger.append(msg.decode()))
            callbacks.allocateMemory = defaultCallbacks.allocateMemory
            callbacks.freeMemory = defaultCallbacks.freeMemory
            self._callbacks = callbacks     # kept alive as long as the instance
        self.fmu.instantiate(callbacks=callbacks, loggingOn=logger is not None)
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def real(self, *names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def set(self, **values):
        self.fmu.setReal([self.vr[n] for n in values], list(values.values()))

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def run_seconds(path, stop, next_step, schedule=None):
    """``[(bit position [m], WOB impulse [N s]) at each whole second]`` of a run whose master steps
    are ``next_step(k)`` (cut at the whole seconds); ``schedule``: ``{time: inputs}`` set there."""
    s = Slave(path)
    out, impulse, sec, k = [], 0.0, 1, 0
    schedule = dict(schedule or {})
    try:
        while s.t < stop - 1e-12:
            for when in [w for w in schedule if w <= s.t + 1e-12]:
                s.set(**schedule.pop(when))
            h = min(next_step(k), sec - s.t)
            nxt = min([w for w in schedule] + [math.inf])
            h = min(h, nxt - s.t) if nxt > s.t + 1e-12 else h
            s.step(h)
            k += 1
            impulse += s.real("mean_wob")[0] * h
            if abs(s.t - sec) < 1e-9:
                s.t = float(sec)          # the master's clock on the second (steps were cut there)
                out.append((s.real("bit_position")[0], impulse))
                impulse, sec = 0.0, sec + 1
    finally:
        s.close()
    return np.array(out)


def per_second(time, bit, dense, stop):
    """The reference's bit position at each whole second and the WOB impulse over each second."""
    rows = []
    for sec in range(1, int(stop) + 1):
        m = (dense["time"] >= sec - 1 - 1e-12) & (dense["time"] <= sec + 1e-12)
        rows.append((np.interp(sec, time, bit), np.trapezoid(dense["wob"][m], dense["time"][m])))
    return np.array(rows)


@pytest.fixture(scope="module")
def field_auto_ref(field):
    from hammerbit.cosim.reference import monolithic
    r = monolithic(field, _config(field, "auto-driller"))
    return per_second(r.data["time"], r.data["bit_position"], r.dense, STOP)


def assert_agrees(got, ref, tol=TOL, drills=True):
    wob = np.abs(got[:, 1] / ref[:, 1] - 1.0)
    if drills:
        pen = np.abs(got[:, 0] - ref[:, 0]) / np.abs(ref[:, 0]).max()
        assert ref[-1, 0] > 0.0, "the reference does not drill: the penetration check would be vacuous"
        assert pen.max() <= tol, f"penetration off by {pen.max():.3g} (relative)"
    else:                                 # a string whose rig does not drill: the bit stays put
        assert np.abs(got[:, 0] - ref[:, 0]).max() <= 1e-12
    assert wob.max() <= tol, f"mean WOB off by {wob.max():.3g} (relative)"


def test_validates(field_auto_fmu):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(field_auto_fmu)) == []


@pytest.mark.parametrize("h", [0.01, pytest.param(0.05, marks=pytest.mark.slow)])
def test_fixed_steps_agree_with_reference(field_auto_fmu, field_auto_ref, h):
    assert_agrees(run_seconds(field_auto_fmu, STOP, lambda k: h), field_auto_ref)


def test_uneven_steps_agree_with_reference(field_auto_fmu, field_auto_ref):
    # log-uniform steps from 1e-13 s to 0.3 s: a leftover sliver must not spoil what follows
    rng = np.random.default_rng(31)
    steps = 10.0 ** rng.uniform(-13, math.log10(0.3), 400)
    assert_agrees(run_seconds(field_auto_fmu, STOP, lambda k: steps[k % len(steps)]), field_auto_ref)


def test_whole_run_in_one_step(field_auto_fmu, field_auto_ref):
    assert_agrees(run_seconds(field_auto_fmu, STOP, lambda k: 1.0), field_auto_ref)


def schedule_reference(string, cfg, schedule, stop):
    """A Stepper run of the monolithic subsystem with the inputs of ``schedule`` ({time: {amplitude,
    wob_set_point}}) changed there: one Stepper per set point, the state carried over.  Each set
    point's subsystem is built whole (its constant column from the set point, not from the FMU's
    affine column) and stepped, as :func:`~hammerbit.cosim.reference.monolithic` steps it, in the
    string's modal form where that is well conditioned."""
    from hammerbit.cosim.modal_form import in_modal_form
    from hammerbit.cosim.reference import monolithic_subsystem
    from hammerbit.cosim.string_side import StringSide
    from hammerbit.model import kernel_layouts as L
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.model.stepping import Stepper
    side = StringSide(string, cfg)
    sc = cfg.rig.scales
    F0, Om = sc.friction_force, sc.omega
    grp = cfg.rig.to_groups().replace(b=0.0)
    t_d = np.linspace(0.0, stop, int(stop * cfg.rig.frequency * 4096) + 1)
    samples = np.zeros((len(t_d), L.N_SAMPLE_COLS))
    st, snap, amp = None, None, grp.a
    times = sorted(schedule) + [stop]
    dW = 0.0
    for i, t_next in enumerate(times[1:]):
        inputs = schedule[times[i]]
        dW = inputs.get("wob_set_point", side.wob + dW) - side.wob
        lin, x1eq = monolithic_subsystem(string, side, cfg, set_point_offset=dW)
        lin, _ = in_modal_form(lin, side.n, REF_RTOL)   # as the monolithic reference steps it
        new = Stepper(grp, solver=SolverOptions(rtol=REF_RTOL, atol=REF_RTOL * 1e-2), linear=lin,
                      y0=[x1eq, 0.0, 0.0, 0.0])
        if snap is not None:
            new.restore(snap)
        amp = inputs.get("amplitude", amp * F0) / F0
        new.p[L.P_A] = amp
        st = new
        # the sample cursor is part of the carried state: the same buffers throughout
        st.advance(Om * t_next, sample_times=Om * t_d, samples=samples)
        snap = st.snapshot()
    fk = (samples[:, L.X_HAMMER] - samples[:, L.X_BIT]) + 2.0 * st.p[L.P_XI] * (
        samples[:, L.V_HAMMER] - samples[:, L.V_BIT])
    dense = {"time": t_d, "wob": (fk + samples[:, 4]) * F0}
    return per_second(t_d, samples[:, L.X_BIT] * sc.length, dense, stop)


def test_input_schedule_agrees_with_reference(field, field_auto_fmu):
    cfg = _config(field, "auto-driller")
    W, A = cfg.weight_on_bit, cfg.rig.amplitude
    schedule = {0.0: {"wob_set_point": W, "amplitude": A}, 0.5: {"wob_set_point": W + 5000.0},
                1.25: {"amplitude": 0.8 * A}}
    ref = schedule_reference(field, cfg, schedule, STOP)
    got = run_seconds(field_auto_fmu, STOP, lambda k: 0.01, schedule={k: v for k, v in schedule.items() if k > 0})
    assert_agrees(got, ref)


def test_unused_input_refused_and_unchanged(field_auto_fmu):
    s = Slave(field_auto_fmu)
    try:
        st = s.fmu.getFMUstate()
        before = s.real("feed_velocity")[0]
        with pytest.raises(Exception):
            s.set(feed_velocity=before + 0.001)
        assert s.real("feed_velocity")[0] == before
        s.fmu.setFMUstate(st)             # FMI: after fmi2Error, a state or a reset recovers
        with pytest.raises(Exception):
            s.set(wob_set_point=float("nan"))
        s.fmu.setFMUstate(st)
        s.step(0.01)                      # the instance still runs
        s.fmu.freeFMUstate(st)
    finally:
        s.close()


def test_every_input_takes_its_declared_range_and_nothing_beyond(field_auto_fmu):
    """The bounds the modelDescription declares for each input are the FMU's own: each bound is
    accepted, the next double beyond it refused (fmi2Error, the input unchanged), with a message
    that names the input, its value and the unit the modelDescription declares."""
    import zipfile
    import xml.etree.ElementTree as ET
    from test_fmu_audit import _declared
    inputs = {name: (lo, hi) for name, (causality, lo, hi) in _declared(field_auto_fmu).items()
              if causality == "input"}
    assert set(inputs) == {"amplitude", "frequency", "wob_set_point", "feed_velocity"}
    with zipfile.ZipFile(field_auto_fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    units = {sv.get("name"): sv.find("Real").get("unit") for sv in root.iter("ScalarVariable")
             if sv.get("name") in inputs}
    log = []
    s = Slave(field_auto_fmu, logger=log)
    try:
        st = s.fmu.getFMUstate()
        for name, (lo, hi) in inputs.items():
            start = s.real(name)[0]
            for bound, beyond in ((lo, -math.inf), (hi, math.inf)):
                s.set(**{name: bound})
                assert s.real(name)[0] == bound, (name, bound)
                s.fmu.setFMUstate(st)
                del log[:]
                with pytest.raises(Exception):
                    s.set(**{name: math.nextafter(bound, beyond)})
                assert s.real(name)[0] == start, (name, bound)
                said = " ".join(log)
                assert f"input '{name}' = {math.nextafter(bound, beyond)!r}" in said, said
                assert re.search(rf"allowed (\[\S+, \S+\]|\S+) {re.escape(units[name])}\b", said), (said, units)
                s.fmu.setFMUstate(st)
        s.step(0.01)                      # the instance still runs
        s.fmu.freeFMUstate(st)
    finally:
        s.close()


def test_state_restores_exactly_and_corrupt_bytes_are_refused(field_auto_fmu):
    s = Slave(field_auto_fmu)
    try:
        s.step(0.05)
        st = s.fmu.getFMUstate()
        s.step(0.05)
        first = s.real("bit_position", "mean_wob", "hook_load")
        s.fmu.setFMUstate(st)
        s.t = 0.05
        s.step(0.05)
        assert s.real("bit_position", "mean_wob", "hook_load") == first
        data = bytes(s.fmu.serializeFMUstate(st))
        rng = np.random.default_rng(7)
        refused = 0
        for _ in range(100):
            b = bytearray(data)
            for i in rng.integers(0, len(b), 4):
                b[i] = int(rng.integers(0, 256))
            try:
                other = s.fmu.deSerializeFMUstate(bytes(b))
            except Exception:
                refused += 1
                s.fmu.setFMUstate(st)
                continue
            s.fmu.setFMUstate(other)        # accepted: it must run and stay finite
            s.t = 0.05
            try:
                s.step(0.01)
                assert all(np.isfinite(s.real("bit_position", "mean_wob", "hook_load")))
            except Exception:
                pass
            s.fmu.freeFMUstate(other)
            s.fmu.setFMUstate(st)
        # the subsystem's values, parameters and options are compared with the build's, the rest
        # range-checked: nearly every flip is refused
        assert refused >= 90
        b = bytearray(data)
        b[8:16] = np.array([np.nan]).tobytes()    # the tolerance
        with pytest.raises(Exception):
            s.fmu.deSerializeFMUstate(bytes(b))
        s.fmu.setFMUstate(st)
        s.fmu.freeFMUstate(st)
    finally:
        s.close()


def _build_and_reference(string_name, top, stop, tmp_path):
    from hammerbit.cosim.reference import monolithic
    from hammerbit.fmu.build_system import build_system_fmu
    string = load_string(string_name)
    cfg = _config(string, top, stop)
    fmu = build_system_fmu(string, cfg, tmp_path / "DS.fmu", log=lambda m: None)
    r = monolithic(string, cfg)
    return fmu, per_second(r.data["time"], r.data["bit_position"], r.dense, stop)


@pytest.mark.slow
def test_feed_agrees_with_reference(tmp_path):
    fmu, ref = _build_and_reference("field-2200m", "feed:20", STOP, tmp_path)
    assert_agrees(run_seconds(fmu, STOP, lambda k: 0.01), ref)


def test_cli_refuses_bad_tolerance():
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "hammerbit", "fmu", "build-system", "--string", "lab",
                        "--tolerance", "5"], capture_output=True, text=True)
    assert r.returncode == 2 and "--tolerance 5.0 is out of range" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.soak
@pytest.mark.slow
@pytest.mark.parametrize("string_name,top,drills", [("field-2200m", "auto-driller", True),
                                                    ("field-2200m", "fixed", True), ("lab", "fixed", False)])
def test_twenty_seconds_agree_with_reference(string_name, top, drills, tmp_path):
    stop = 20.0
    fmu, ref = _build_and_reference(string_name, top, stop, tmp_path)
    rng = np.random.default_rng(20)
    uneven = 10.0 ** rng.uniform(-13, 0, 500)
    for steps in (lambda k: 0.001, lambda k: 0.01, lambda k: 0.05, lambda k: uneven[k % len(uneven)]):
        assert_agrees(run_seconds(fmu, stop, steps), ref, drills=drills)


def _host_values(cmd, env):
    import subprocess
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return [float(ln.split()[1]) for ln in proc.stdout.splitlines() if ln.startswith("value ")]


def test_c_host_under_empty_environment(field_auto_fmu, field_auto_ref, tmp_path):
    # a plain C host (no Python anywhere in the process) under env -i: 2 s at 10 ms
    import zipfile

    from fmpy import read_model_description
    from native_hosts import linux_host
    d = tmp_path / "x"
    zipfile.ZipFile(field_auto_fmu).extractall(d)
    md = read_model_description(str(field_auto_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    got = _host_values([str(linux_host(tmp_path)), str(d / "binaries/linux64/DrillingSystem.so"),
                        (d / "resources").as_uri(), md.guid, "steps=200", "h=0.01",
                        f"out={vr['bit_position']}"], env={})
    assert len(got) == 1
    assert abs(got[0] / field_auto_ref[-1, 0] - 1.0) <= TOL


@pytest.mark.slow
def test_windows_binary_under_wine(field_auto_fmu, field_auto_ref, tmp_path):
    import os
    import zipfile
    from urllib.parse import quote

    from fmpy import read_model_description
    from native_hosts import windows_host_or_skip
    d = tmp_path / "x"
    zipfile.ZipFile(field_auto_fmu).extractall(d)
    dll = d / "binaries/win64/DrillingSystem.dll"
    wine, exe = windows_host_or_skip(dll, tmp_path)
    md = read_model_description(str(field_auto_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "WINEDEBUG": "-all",
           "WINEPREFIX": os.environ.get("WINEPREFIX", os.path.expanduser("~/.wine"))}
    got = _host_values([wine, str(exe), "Z:" + str(dll).replace("/", "\\"),
                        "file:///Z:" + quote((d / "resources").as_posix()), md.guid, "steps=200", "h=0.01",
                        f"out={vr['bit_position']}"], env)
    assert len(got) == 1
    assert abs(got[0] / field_auto_ref[-1, 0] - 1.0) <= TOL


def run_libcosim_seconds(path, stop, h):
    """:func:`run_seconds` in libcosim (libcosimpy) at the fixed step ``h``."""
    cosim = pytest.importorskip("libcosimpy.CosimExecution")
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    log_output_level(CosimLogLevel.ERROR)
    ns = 1_000_000_000
    ex = cosim.CosimExecution.from_step_size(step_size=int(round(h * ns)))
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name="system"))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    refs = [vr["bit_position"], vr["mean_wob"]]
    out, impulse, sec, last = [], 0.0, 1, 0
    while True:
        assert ex.step(), "libcosim: a step failed"
        t_ns = ex.status().current_time
        x, mw = obs.last_real_values(idx, refs)
        impulse += mw * (t_ns - last) / ns
        last = t_ns
        if t_ns >= sec * ns:
            out.append((x, impulse))
            impulse, sec = 0.0, sec + 1
            if sec > stop:
                break
    return np.array(out)


@pytest.mark.parametrize("h", [0.01, pytest.param(0.001, marks=pytest.mark.slow)])
def test_libcosim_agrees_with_reference(field_auto_fmu, field_auto_ref, h):
    assert_agrees(run_libcosim_seconds(field_auto_fmu, STOP, h), field_auto_ref)


@pytest.mark.soak
@pytest.mark.slow
@pytest.mark.parametrize("string_name,top,drills", [("field-2200m", "auto-driller", True), ("lab", "fixed", False)])
def test_twenty_seconds_in_other_hosts_agree_with_reference(string_name, top, drills, tmp_path):
    """The same 20 s in libcosim at 1 and 10 ms (each second), and in the C host under env -i and
    the win64 binary under wine at 10 ms (the penetration at 20 s: those hosts print the end)."""
    import os
    import zipfile
    from urllib.parse import quote

    from fmpy import read_model_description
    from native_hosts import linux_host, windows_host_or_skip
    stop = 20.0
    fmu, ref = _build_and_reference(string_name, top, stop, tmp_path)
    for h in (0.01, 0.001):
        assert_agrees(run_libcosim_seconds(fmu, stop, h), ref, drills=drills)
    d = tmp_path / "x"
    zipfile.ZipFile(fmu).extractall(d)
    md = read_model_description(str(fmu))
    args = [md.guid, f"steps={int(round(stop / 0.01))}", "h=0.01",
            f"out={next(v.valueReference for v in md.modelVariables if v.name == 'bit_position')}"]
    ends = [_host_values([str(linux_host(tmp_path)), str(d / "binaries/linux64/DrillingSystem.so"),
                          (d / "resources").as_uri(), *args], env={})]
    dll = d / "binaries/win64/DrillingSystem.dll"
    if dll.exists():
        wine, exe = windows_host_or_skip(dll, tmp_path)
        env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "WINEDEBUG": "-all",
               "WINEPREFIX": os.environ.get("WINEPREFIX", os.path.expanduser("~/.wine"))}
        ends.append(_host_values([wine, str(exe), "Z:" + str(dll).replace("/", "\\"),
                                  "file:///Z:" + quote((d / "resources").as_posix()), *args], env))
    for got in ends:
        assert len(got) == 1
        if drills:
            assert abs(got[0] / ref[-1, 0] - 1.0) <= TOL
        else:
            assert abs(got[0] - ref[-1, 0]) <= 1e-12

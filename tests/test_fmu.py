"""HammerBitRock.fmu: model description, importers (fmpy, libcosim), agreement with the library,
state rollback and serialisation, statuses of bad calls, independent instances, warm start.

The FMU is built once per session (``built_fmu`` in conftest.py, ``hammerbit fmu build``) and
loaded into this process through the project's loader (:class:`hammerbit.fmu.host.FMUInstance`,
fmpy's ``FMU2Slave``) and by libcosim (libcosimpy), like any FMI host would.

Statuses: the slave records the status of every call in its ``last_status`` variable; when the
FMU carries the native front (``hammerbit.fmu.native``), the FMI call itself returns it too
(fmpy raises ``FMICallException`` for Discard and Error).  Both are checked.
"""
from __future__ import annotations

import atexit
import json
import math
import shutil
import subprocess
import sys
import textwrap
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import fmi2LastSuccessfulTime  # noqa: E402

from hammerbit.fmu.host import FMI_DISCARD, FMI_ERROR, FMI_OK, FMI_WARNING, FMUInstance  # noqa: E402
from hammerbit.model import kernel_layouts  # noqa: E402
from hammerbit.model.kernel_layouts import P_B, P_FEXT  # noqa: E402
from hammerbit.model.params import RigParameters
from hammerbit.model.solver_options import SolverOptions  # noqa: E402
from hammerbit.model.stepping import Stepper
from hammerbit.model.validation import RANGES  # noqa: E402

RIG = RigParameters()                    # the FMU's start values (lab preset)
SCALES = RIG.scales
TOL = 1e-8                               # the FMU's default solver tolerance

OUTPUT_NAMES = ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity", "spring_force",
                "contact_force", "friction_force", "rock_force", "rate_of_penetration")


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
_EXTRACTED = {}                          # FMU path -> its one extraction directory in this process


def _extracted(path) -> str:
    """The FMU extracted once per process and shared by its instances, as FMI hosts do (one
    binary, several instances).  New extraction directories: the fresh processes below."""
    key = str(path)
    if key not in _EXTRACTED:
        from fmpy import extract
        d = extract(key)
        atexit.register(shutil.rmtree, d, True)
        _EXTRACTED[key] = d
    return _EXTRACTED[key]


class Instance(FMUInstance):
    """The project's loader plus the outputs as one tuple and the recorded status; the
    instances of one FMU share its extraction directory."""

    def __init__(self, path, *args, unzipdir=None, **kw):
        super().__init__(path, *args, unzipdir=unzipdir if unzipdir is not None else _extracted(path), **kw)

    def outputs(self):
        reals = self.get(*OUTPUT_NAMES)
        ints = self.get_int("stick_slip", "impact_count", "slip_count", "bounce_count")
        flag = self.get_bool("in_contact")
        return tuple(reals) + tuple(ints) + tuple(flag)

    def last_status(self) -> int:
        return self.get_int("last_status")[0]

    def call(self, fn, *args, **kw) -> int:
        """Status of an FMI call as the master sees it: from the exception, or OK."""
        try:
            fn(*args, **kw)
        except FMICallException as e:
            return e.status
        return FMI_OK

    def expect(self, status, fn, *args, **kw) -> None:
        """The call records ``status``; with the native front the call returns it too."""
        got = self.call(fn, *args, **kw)
        assert self.last_status() == status, self.messages[-3:]
        if self.has_front:
            assert got == status, (got, self.messages[-3:])
        else:
            assert got in (FMI_OK, FMI_DISCARD) and got <= status


def library_stepper(rig=RIG, *, y0=None):
    return Stepper(rig.to_groups(), solver=SolverOptions(rtol=TOL, atol=1e-2 * TOL), y0=y0)


def tau(t, rig=RIG):
    return t * rig.scales.omega


# ---------------------------------------------------------------------------
# build and model description
# ---------------------------------------------------------------------------
def _runtime_package(names):
    pkgs = {n.split("/")[1] for n in names if n.startswith("resources/hammerbit_fmu_runtime_")}
    assert len(pkgs) == 1, pkgs
    return pkgs.pop()


def test_build_carries_the_runtime_and_its_compiled_kernels(built_fmu):
    from hammerbit.fmu.build import build_hash
    with zipfile.ZipFile(built_fmu) as zf:
        names = zf.namelist()
        md = zf.read("modelDescription.xml").decode()
        manifest = json.loads(zf.read(f"resources/{_runtime_package(names)}/_compiled/manifest.json"))
    pkg = _runtime_package(names)
    assert pkg == f"hammerbit_fmu_runtime_{build_hash()}"
    assert f"resources/{pkg}/slave.py" in names and f"resources/{pkg}/kernel_driver.py" in names
    assert f"resources/hammerbit_fmu_slave_{build_hash()}.py" in names
    assert any(n.startswith(f"resources/{pkg}/_compiled/") and n.endswith(".nbc") for n in names)
    assert manifest["cpu_name"] == "generic" and manifest["python"] == "%d.%d" % sys.version_info[:2]
    assert "binaries/linux64/HammerBitRock.so" in names
    assert not [n for n in names if "coupling" in n or "tests/" in n or n.endswith(".pyc")]
    assert 'canGetAndSetFMUstate="true"' in md and 'canSerializeFMUstate="true"' in md
    assert 'canHandleVariableCommunicationStepSize="true"' in md


def test_the_host_reads_a_rebuilt_fmu_at_the_same_path_anew(built_fmu, built_native_fmu, tmp_path):
    """The host parses each FMU's description once, but an FMU rebuilt at the same path (another
    flavour here) is read again: the description is that of the file as it is now."""
    from hammerbit.fmu.host import model_description
    path = tmp_path / "HammerBitRock.fmu"
    seen = []
    for source in (built_fmu, built_native_fmu, built_fmu):
        shutil.copyfile(source, path)
        md = model_description(path)
        assert md.guid == read_model_description(str(source)).guid
        seen.append(md.generationTool)
    assert seen[0] == seen[2] != seen[1]
    assert model_description(path) is model_description(str(path))


def test_validate_reports_nothing(built_fmu):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(built_fmu)) == []
    r = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(built_fmu)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "No problems found" in r.stdout


def test_model_description_variables(built_fmu):
    md = read_model_description(str(built_fmu))
    by = {v.name: v for v in md.modelVariables}
    for v in md.modelVariables:
        assert v.description, v.name
        if v.type == "Real":
            assert v.unit, v.name
    assert {by["preload"].causality, by["harmonic_force"].causality} == {"input"}
    assert float(by["preload"].start) == pytest.approx(29.7)
    for name in ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
                 "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
                 "contact_damping", "amplitude", "frequency", "phase"):
        assert by[name].causality == "parameter" and by[name].variability == "fixed"
        assert float(by[name].start) == pytest.approx(getattr(RIG, name), rel=1e-15), name
    assert by["tolerance"].variability == "tunable"
    assert by["impact_enabled"].type == "Boolean"
    assert float(by["frequency"].start) == pytest.approx(1.474, abs=1e-3)
    for name in OUTPUT_NAMES + ("stick_slip", "in_contact", "impact_count", "slip_count", "bounce_count"):
        assert by[name].causality == "output" and by[name].initial == "calculated"
    status = by["last_status"]
    assert (status.type, status.causality, status.variability, status.initial) == \
        ("Integer", "local", "discrete", "calculated")
    assert md.defaultExperiment.stopTime and md.defaultExperiment.stepSize


def test_model_description_ranges_nominals_and_no_feedthrough(built_fmu):
    """Parameters declare min/max inside validation.RANGES (exactly what is accepted:
    tests/test_fmu_audit.py), the inputs +-1000 F0; outputs depend on no input."""
    from hammerbit.model.fmu_variables import range_key
    with zipfile.ZipFile(built_fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    variables = root.find("ModelVariables").findall("ScalarVariable")
    checked = 0
    for sv in variables:
        real = sv.find("Real")
        if real is None or sv.get("causality") not in ("parameter", "input"):
            continue
        lo, hi = float(real.get("min")), float(real.get("max"))
        if sv.get("causality") == "input":
            assert (lo, hi) == (-1000.0 * SCALES.friction_force, 1000.0 * SCALES.friction_force)
        else:
            rng = RANGES[range_key(sv.get("name"))]
            assert rng.lo <= lo and hi <= rng.hi, sv.get("name")
        assert lo <= float(real.get("start")) <= hi
        checked += 1
    assert checked == 20
    nominal = {sv.get("name"): sv.find("Real").get("nominal") for sv in variables if sv.find("Real") is not None}
    assert float(nominal["stiffness"]) == RIG.stiffness
    assert float(nominal["bit_position"]) == pytest.approx(SCALES.length, rel=1e-5)
    assert float(nominal["rock_force"]) == pytest.approx(SCALES.friction_force, rel=1e-5)
    outputs = root.find("ModelStructure/Outputs").findall("Unknown")
    assert len(outputs) == 15                                 # docs/fmu.md: 15 outputs, regime the last
    assert all(u.get("dependencies") == "" for u in outputs)   # no direct feedthrough


# ---------------------------------------------------------------------------
# importers and agreement with the library
# ---------------------------------------------------------------------------
def test_simulate_fmu_default_scene_drills_like_the_library(built_fmu):
    """fmpy simulate of the bare FMU (start values, no input file) drills; = library to tolerance."""
    res = fmpy.simulate_fmu(str(built_fmu), stop_time=20.0, output_interval=0.01,
                            output=["bit_position", "slip_count", "stick_slip", "rate_of_penetration"])
    x_fmu = res["bit_position"][-1]
    st = library_stepper()
    st.advance(tau(20.0))
    x_lib = st.y[2] * SCALES.length
    assert x_fmu > 0.1                      # 20 s of the lab scene: about 0.21 m
    assert res["slip_count"][-1] == st.counts["slip_start"] >= 25
    assert abs(x_fmu - x_lib) <= 1e-6 * x_lib
    assert res["rate_of_penetration"][-1] == pytest.approx(x_fmu / 20.0, rel=1e-12)


def test_fmu2slave_variable_steps_match_the_library(built_fmu):
    """Variable communication steps; at every communication point the state equals the library's."""
    inst = Instance(built_fmu)
    st = library_stepper()
    rng = np.random.default_rng(7)
    worst = 0.0
    try:
        for k in range(400):
            h = float(rng.choice([1e-4, 1e-3, 7e-3, 0.02, 0.05]))
            inst.step(h)
            if k % 40 != 39:
                continue
            st.advance(tau(inst.t))
            got = np.array(inst.get("hammer_position", "hammer_velocity", "bit_position", "bit_velocity"))
            ref = st.y[:4] * np.array([SCALES.length, SCALES.velocity, SCALES.length, SCALES.velocity])
            scale = np.array([SCALES.length, SCALES.velocity, SCALES.length, SCALES.velocity])
            worst = max(worst, float(np.max(np.abs(got - ref) / (scale * (1.0 + np.abs(st.y[:4]))))))
        assert inst.get_int("slip_count")[0] == st.counts["slip_start"] > 5
        assert worst < 1e-6, worst
        assert not inst.errors()
    finally:
        inst.close()


def test_zero_order_hold_of_the_inputs(built_fmu):
    """preload and harmonic_force are held over each step: the library with the same held values agrees."""
    inst = Instance(built_fmu, reals={"amplitude": 0.0})
    rig = RIG.replace(amplitude=0.0)
    st = library_stepper(rig)
    F0 = rig.scales.friction_force
    h = 2e-3
    try:
        for k in range(1500):
            t = inst.t
            B = 29.7 + 3.0 * math.sin(2.0 * t)
            Fh = 8.1 * math.sin(2.0 * math.pi * RIG.frequency * t + math.pi / 2)   # sampled at step start
            inst.set(preload=B, harmonic_force=Fh)
            inst.step(h)
            st.p[P_B] = B / F0
            st.p[P_FEXT] = Fh / F0
            st.advance((t + h) * rig.scales.omega)
        got = inst.get("bit_position", "hammer_position")
        assert got[0] == pytest.approx(st.y[2] * rig.scales.length, rel=1e-12, abs=1e-15)
        assert got[1] == pytest.approx(st.y[0] * rig.scales.length, rel=1e-12)
        assert got[0] > 0.0 and inst.get_int("slip_count")[0] > 0
    finally:
        inst.close()


def test_si_parameters_map_onto_the_rig(built_fmu):
    """Setting SI parameters by their RigParameters names gives the library's scene with the same rig."""
    rig = RIG.replace(hammer_mass=30.0, bit_mass=8.0, stiffness=2500.0, damping=40.0, mu_static=0.6,
                      mu_kinetic=0.5, friction_decay=300.0, normal_force=95.0, amplitude=10.0,
                      frequency=1.4, phase=0.3, preload=31.0)
    names = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
             "friction_decay", "normal_force", "amplitude", "frequency", "phase")
    inst = Instance(built_fmu, reals={n: getattr(rig, n) for n in names} | {"preload": rig.preload})
    st = library_stepper(rig)
    try:
        for _ in range(200):
            inst.step(0.05)
        st.advance(tau(inst.t, rig))
        x = inst.get("bit_position")[0]
        assert x == pytest.approx(st.y[2] * rig.scales.length, rel=1e-6)
        assert inst.get_int("slip_count")[0] == st.counts["slip_start"] > 0
    finally:
        inst.close()


def test_impact_scene_matches_the_library(built_fmu):
    gap = 0.84 * SCALES.length
    rig = RIG.replace(gap=gap, amplitude=0.06 * SCALES.friction_force)
    inst = Instance(built_fmu, reals={"gap": gap, "amplitude": rig.amplitude},
                    booleans={"impact_enabled": True})
    st = library_stepper(rig)
    saw_contact = False
    try:
        for _ in range(2000):
            inst.step(5e-3)
            saw_contact |= bool(inst.fmu.getBoolean([inst.vr["in_contact"]])[0])
        st.advance(tau(inst.t))
        assert saw_contact
        assert inst.get_int("impact_count")[0] == st.counts["impact"] > 0
        assert inst.get("bit_position")[0] == pytest.approx(st.y[2] * SCALES.length, rel=1e-6)
    finally:
        inst.close()


def test_output_forces_are_consistent(built_fmu):
    with Instance(built_fmu) as inst:
        for _ in range(300):
            inst.step(1e-3)
            (xb, vb, xs, vs, fk, fc, ff, frock, rop) = inst.get(*OUTPUT_NAMES)
            slip = inst.get_int("stick_slip")[0]
            assert fk == pytest.approx(RIG.stiffness * (xb - xs) + RIG.damping * (vb - vs), rel=1e-9, abs=1e-9)
            assert frock == pytest.approx(fk + fc, rel=1e-12, abs=1e-12)
            if slip:
                v = vs
                expect = RIG.normal_force * (RIG.mu_kinetic + (RIG.mu_static - RIG.mu_kinetic)
                                             * math.exp(-RIG.friction_decay * v))
                assert ff == pytest.approx(expect, rel=1e-12)
            else:
                assert ff == pytest.approx(frock, rel=1e-12, abs=1e-12)
                assert vs == 0.0


def test_libcosim_runs_the_fmu_like_fmpy_and_the_library(any_fmu):
    """Each runtime flavour in libcosim: the library's penetration, and fmpy's on the same FMU."""
    libcosim = pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    log_output_level(CosimLogLevel.ERROR)
    stop = 3.0
    ex = CosimExecution.from_step_size(step_size=int(1e6))            # 1 ms, in ns
    slave = CosimLocalSlave(fmu_path=str(any_fmu), instance_name="hammer")
    idx = ex.add_local_slave(slave)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    assert ex.simulate_until(target_time=int(stop * 1e9))
    x_cosim = obs.last_real_values(idx, [vr["bit_position"]])[0]
    slips = obs.last_integer_values(idx, [vr["slip_count"]])[0]
    ex.stop()

    st = library_stepper()
    st.advance(tau(stop))
    x_lib = st.y[2] * SCALES.length
    with Instance(any_fmu) as inst:
        for _ in range(3000):
            inst.step(1e-3)
        x_fmpy = inst.get("bit_position")[0]
    assert slips == st.counts["slip_start"] > 0
    assert x_cosim == pytest.approx(x_lib, rel=1e-6)
    assert x_cosim == pytest.approx(x_fmpy, rel=1e-9)


# ---------------------------------------------------------------------------
# FMU state: rollback and serialisation
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("impact", [False, True], ids=["no-impact", "impact"])
def test_rollback_is_bit_identical(built_fmu, impact):
    kw = {}
    if impact:
        kw = dict(reals={"gap": 0.84 * SCALES.length, "amplitude": 0.06 * SCALES.friction_force},
                  booleans={"impact_enabled": True})
    with Instance(built_fmu, **kw) as inst:
        for _ in range(517):                       # somewhere in the cycle, modes set
            inst.step(2e-3)
        t0 = inst.t
        state = inst.fmu.getFMUstate()
        first = []
        for k in range(400):
            inst.set(preload=29.7 + 0.01 * k)
            inst.step(3e-3)
            first.append(inst.outputs())
        inst.fmu.setFMUstate(state)
        inst.t = t0
        second = []
        for k in range(400):
            inst.set(preload=29.7 + 0.01 * k)
            inst.step(3e-3)
            second.append(inst.outputs())
        assert first == second                      # bit-identical, every output, every step
        # the replayed window holds events: slips (and impacts in the impact scene)
        assert first[-1][11] > first[0][11]                 # slip_count
        if impact:
            assert first[-1][10] > first[0][10]             # impact_count
        inst.fmu.freeFMUstate(state)
        assert not inst.errors()


def test_serialized_state_restores_in_another_instance(built_fmu):
    a = Instance(built_fmu, "a")
    b = Instance(built_fmu, "b", reals={"hammer_mass": 40.0})      # different parameters on purpose
    try:
        for _ in range(333):
            a.step(2e-3)
        blob = a.fmu.serializeFMUstate(a.fmu.getFMUstate())
        assert b'"format": "hammerbit-fmu-state/' in blob         # (after the front's header, if any)
        t0 = a.t
        ref = []
        for _ in range(250):
            a.step(2e-3)
            ref.append(a.outputs())
        state = b.fmu.deSerializeFMUstate(blob)
        b.fmu.setFMUstate(state)
        b.t = t0
        got = []
        for _ in range(250):
            b.step(2e-3)
            got.append(b.outputs())
        assert got == ref
        assert b.get("hammer_mass")[0] == RIG.hammer_mass   # the parameters came with the state
        assert not a.errors() and not b.errors()
    finally:
        a.close()
        b.close()


def test_corrupt_serialized_state_is_an_error(built_fmu):
    with Instance(built_fmu) as inst:
        inst.step(0.1)
        before = inst.outputs()
        saved = inst.fmu.getFMUstate()
        state = None

        def deserialize():
            nonlocal state
            state = inst.fmu.deSerializeFMUstate(b"\x00not a state")

        inst.expect(FMI_ERROR, deserialize)
        if state is not None:                        # without the front the invalid state exists
            inst.expect(FMI_ERROR, inst.fmu.setFMUstate, state)
            assert any("state unchanged" in m for m in inst.errors())
        assert inst.errors()
        assert inst.has_front or any("cannot deserialise" in m for m in inst.errors())
        assert inst.outputs() == before
        inst.fmu.setFMUstate(saved)                  # the recovery from fmi2Error
        inst.step(0.1)
        assert inst.last_status() == FMI_OK


# ---------------------------------------------------------------------------
# bad input: every refused call records fmi2Error (with the front: returns it) and changes nothing
# ---------------------------------------------------------------------------
def _reference_outputs(path, n_before, n_after, h=2e-3):
    with Instance(path, "ref") as ref:
        for _ in range(n_before + n_after):
            ref.step(h)
        return ref.outputs()


def _set(name, value):
    return lambda i: i.fmu.setReal([i.vr[name]], [value])


def _step(dt=0.0, h=2e-3):
    return lambda i: i.fmu.doStep(currentCommunicationPoint=i.t + dt, communicationStepSize=h)


_INPUT_RANGE = f"[{-1000 * SCALES.friction_force:g}, {1000 * SCALES.friction_force:g}] N"   # +-1000 F0
BAD_CALLS = {   # refused call, words its message must contain
    "nan-preload": (_set("preload", math.nan), ("preload", "nan", _INPUT_RANGE)),
    "inf-harmonic-force": (_set("harmonic_force", math.inf), ("harmonic_force", "inf")),
    "absurd-preload": (_set("preload", 1e12), ("preload", "1000000000000.0", _INPUT_RANGE)),
    "absurd-harmonic-force": (_set("harmonic_force", -1e308), ("harmonic_force", "-1e+308")),
    "fixed-parameter-after-init": (_set("hammer_mass", 50.0), ("hammer_mass", "50.0", "fixed")),
    "invalid-tolerance-after-init": (_set("tolerance", -1.0), ("tolerance", "-1.0", "[1e-14, 0.01]")),
    "zero-step": (_step(h=0.0), ("step size", "0.0")),
    "negative-step": (_step(h=-1e-3), ("step size", "-0.001")),
    "nan-step": (_step(h=math.nan), ("step size", "nan")),
    "wrong-communication-point": (_step(dt=0.5), ("currentCommunicationPoint", "0.9000")),
    "unknown-value-reference": (lambda i: i.fmu.setReal([9999], [1.0]), ("9999", "no such variable")),
    "output-is-not-settable": (_set("bit_position", 1.0), ("bit_position", "not settable")),
}


@pytest.fixture(scope="module")
def bad_call_expected(built_fmu):
    """Outputs of the clean run that every bad-call case must reproduce (computed once)."""
    return _reference_outputs(built_fmu, 200, 150, 2e-3)


@pytest.mark.parametrize("case", sorted(BAD_CALLS))
def test_bad_call_is_an_error_and_changes_nothing(built_fmu, bad_call_expected, case):
    call, words = BAD_CALLS[case]
    h = 2e-3
    with Instance(built_fmu) as inst:
        for _ in range(200):
            inst.step(h)
        before = inst.outputs()
        saved = inst.fmu.getFMUstate()
        inst.expect(FMI_ERROR, call, inst)
        errs = inst.errors()
        assert errs, "no error logged"
        assert words[0] in errs[-1], errs[-1]
        if not inst.has_front or "value reference" not in errs[-1]:   # the slave's message
            assert all(w in errs[-1] for w in words), errs[-1]
        assert inst.outputs() == before                          # nothing changed
        assert inst.get("preload", "harmonic_force", "hammer_mass", "tolerance") == \
            [RIG.preload, 0.0, RIG.hammer_mass, TOL]              # refused values were not stored
        # after fmi2Error the master restores a saved state (FMI 2.0.4, 2.1.3) and goes on:
        # the same result as a run without the bad call
        inst.fmu.setFMUstate(saved)
        inst.fmu.freeFMUstate(saved)
        for _ in range(150):
            inst.step(h)
        assert inst.last_status() == FMI_OK
        assert inst.outputs() == bad_call_expected


BAD_PARAMETERS = {
    "negative-mass": ({"hammer_mass": -1.0}, ("hammer_mass", "-1.0", "[1e-06, 1e+09] kg")),
    "zero-bit-mass": ({"bit_mass": 0.0}, ("bit_mass", "0.0", "[1e-06, 1e+09] kg")),
    "mu_d-above-mu_e": ({"mu_kinetic": 0.7}, ("mu_kinetic", "0.7", "mu_static")),
    "n-zero": ({"contact_exponent": 0.0}, ("contact_exponent", "0.0", "(0, 5]")),
    "nan-normal-force": ({"normal_force": math.nan}, ("normal_force", "nan")),
    "inf-stiffness": ({"stiffness": math.inf}, ("stiffness", "inf")),
    "zero-frequency": ({"frequency": 0.0}, ("frequency", "0.0", "(0, 1e+09] Hz")),
    "zero-tolerance": ({"tolerance": 0.0}, ("tolerance", "0.0", "[1e-14, 0.01]")),
    "huge-initial-position": ({"initial_bit_position": 1e7}, ("initial_bit_position", "10000000.0", "[-1e+06, 1e+06] m")),
}


@pytest.mark.parametrize("case", sorted(BAD_PARAMETERS))
def test_bad_parameter_fails_initialisation(built_fmu, case):
    """An invalid parameter: fmi2ExitInitializationMode is an error naming it, value and range;
    every later step is refused; the host can still free the instance."""
    reals, words = BAD_PARAMETERS[case]
    with Instance(built_fmu, init=False) as inst:
        inst.set(**reals)                       # a warning at most: initialisation decides
        assert inst.last_status() in (FMI_OK, FMI_WARNING)
        inst.expect(FMI_ERROR, inst.fmu.exitInitializationMode)
        errs = inst.errors()
        assert errs and all(w in errs[-1] for w in words), errs
        assert "initialisation failed" in errs[-1]
        if not inst.has_front:     # the front refuses doStep after a failed initialisation itself
            inst.expect(FMI_ERROR, inst.fmu.doStep, 0.0, 1e-3)
            assert words[0] in inst.errors()[-1]
        assert inst.get("bit_position", "hammer_position") == [0.0, 0.0]


def test_outputs_are_valid_in_initialization_mode(built_fmu):
    """spring_force = K (x_b0 - x_s0) and rock_force follow the parameters set so far."""
    with Instance(built_fmu, init=False) as inst:
        inst.set(initial_hammer_position=0.012, initial_bit_position=0.002, stiffness=3000.0)
        fk, frock, xb, xs, ff = inst.get("spring_force", "rock_force", "hammer_position", "bit_position",
                                          "friction_force")
        assert fk == pytest.approx(3000.0 * (0.012 - 0.002), rel=1e-14)
        assert frock == pytest.approx(fk, rel=1e-14) and ff == pytest.approx(fk, rel=1e-14)
        assert (xb, xs) == (0.012, 0.002)
        inst.set(stiffness=2000.0)
        assert inst.get("spring_force")[0] == pytest.approx(2000.0 * 0.01, rel=1e-14)
        inst.fmu.exitInitializationMode()
        assert inst.get("spring_force")[0] == pytest.approx(2000.0 * 0.01, rel=1e-14)


def test_terminated_fmu_refuses_steps(built_fmu):
    inst = Instance(built_fmu)
    try:
        inst.step(1e-3)
        inst.fmu.terminate()
        inst.expect(FMI_ERROR, inst.fmu.doStep, inst.t, 1e-3)
        assert "terminate" in inst.errors()[-1].lower()
    finally:
        inst.fmu.freeInstance()


def test_setup_experiment_with_a_non_finite_start_time_is_an_error(built_fmu):
    inst = Instance(built_fmu, setup=False)
    try:
        inst.expect(FMI_ERROR, inst.fmu.setupExperiment, startTime=math.nan)
        assert "startTime" in inst.errors()[-1] and "nan" in inst.errors()[-1]
    finally:
        inst.fmu.freeInstance()


@pytest.mark.parametrize("kind", ["unknown-real", "wrong-type-integer", "wrong-type-boolean"])
def test_wrong_type_and_unknown_references_in_get(built_fmu, kind):
    with Instance(built_fmu) as inst:
        inst.step(1e-3)
        saved = inst.fmu.getFMUstate()
        call = {"unknown-real": (inst.fmu.getReal, [9999]),
                "wrong-type-integer": (inst.fmu.getInteger, [inst.vr["bit_position"]]),
                "wrong-type-boolean": (inst.fmu.getBoolean, [inst.vr["slip_count"]])}[kind]
        inst.expect(FMI_ERROR, *call)
        assert inst.errors() and ("9999" in inst.errors()[-1] or "not" in inst.errors()[-1])
        inst.fmu.setFMUstate(saved)
        inst.step(1e-3)                                                         # alive again
        assert inst.last_status() == FMI_OK


def test_tolerance_is_tunable(built_fmu):
    with Instance(built_fmu) as inst:
        for _ in range(100):
            inst.step(5e-3)
        inst.set(tolerance=1e-6)
        for _ in range(100):
            inst.step(5e-3)
        assert not inst.errors()
        assert inst.get("tolerance")[0] == 1e-6


def test_start_time_other_than_zero(built_fmu):
    """The internal source is A sin(2 pi f t + phase) in absolute time; the clock starts at t_start."""
    t0 = 5.0
    inst = Instance(built_fmu, start_time=t0)
    omega_f = 2.0 * math.pi * RIG.frequency
    g = RIG.to_groups().replace(phi=math.fmod(RIG.phase + omega_f * t0, 2.0 * math.pi))
    st = Stepper(g, solver=SolverOptions(rtol=TOL, atol=1e-2 * TOL))
    try:
        saved = inst.fmu.getFMUstate()
        with pytest.raises(FMICallException):
            inst.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        inst.fmu.setFMUstate(saved)
        for _ in range(500):
            inst.step(4e-3)
        st.advance(tau(inst.t - t0))
        assert inst.get("bit_position")[0] == pytest.approx(st.y[2] * SCALES.length, rel=1e-6)
    finally:
        inst.close()


# ---------------------------------------------------------------------------
# several instances
# ---------------------------------------------------------------------------
def test_two_instances_with_different_parameters_are_independent(built_fmu):
    rig_b = RIG.replace(hammer_mass=30.0, amplitude=9.0, preload=25.0)
    a = Instance(built_fmu, "a")
    b = Instance(built_fmu, "b", reals={"hammer_mass": 30.0, "amplitude": 9.0, "preload": 25.0})
    sa, sb = library_stepper(), library_stepper(rig_b)
    sb.p[P_B] = 25.0 / rig_b.scales.friction_force
    try:
        for k in range(600):                       # interleaved
            a.step(3e-3)
            b.step(3e-3)
        sa.advance(tau(a.t))
        sb.advance(tau(b.t, rig_b))
        xa, xb = a.get("bit_position")[0], b.get("bit_position")[0]
        assert xa == pytest.approx(sa.y[2] * SCALES.length, rel=1e-6)
        assert xb == pytest.approx(sb.y[2] * rig_b.scales.length, rel=1e-6)
        assert xa != pytest.approx(xb, rel=1e-3)
        alone = _reference_outputs(built_fmu, 600, 0, 3e-3)
        assert a.outputs() == alone
    finally:
        a.close()
        b.close()


# ---------------------------------------------------------------------------
# fresh processes: repeated loading, exit, warm start from the numba cache
# ---------------------------------------------------------------------------
_PROBE = textwrap.dedent("""
    import json, sys, time
    from hammerbit.fmu.host import FMUInstance
    path, n = sys.argv[1], int(sys.argv[2])
    out = {}
    for i in range(n):
        t1 = time.perf_counter()
        inst = FMUInstance(path, "probe%d" % i)
        t2 = time.perf_counter()
        inst.step(1e-3)
        out.setdefault("load_s", t2 - t1)
        out.setdefault("messages", inst.messages)
        inst.close()
    pkg = [m for m in sys.modules if m.startswith("hammerbit_fmu_runtime_") and "." not in m][0]
    nc = sys.modules[pkg + ".numba_cache"]
    out["cache_hits"], out["cache_misses"] = nc.kernel_cache_counts()
    out["decision"] = nc.DECISION
    out["exit_guard"] = len(sys.modules["hammerbit.model.pythonfmu_exit"]._PINNED_WRAPPERS)
    print(json.dumps(out), flush=True)
""")


def _probe(path, n, env=None):
    r = subprocess.run([sys.executable, "-c", _PROBE, str(path), str(n)], capture_output=True,
                       text=True, timeout=600, env=env)
    assert r.returncode == 0, f"exit status {r.returncode}\n{r.stdout}\n{r.stderr}"
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_repeated_instantiation_and_exit_in_a_fresh_process(built_fmu):
    """20 load/instantiate/free cycles from new extraction directories, then a clean exit."""
    out = _probe(built_fmu, 20)
    assert out["exit_guard"] >= 1
    assert out["cache_misses"] == 0, out


def test_a_new_process_loads_the_shipped_kernels(built_fmu):
    """A new process and a new extraction directory load the kernels the build compiled (the
    first of two cycles; nothing compiled in either), and the process exits cleanly."""
    out = _probe(built_fmu, 2)
    assert out["exit_guard"] >= 1
    assert out["decision"]["shipped"], out["decision"]
    assert out["cache_misses"] == 0 and out["cache_hits"] >= 3, out         # advance + two force formulas
    # nothing compiled is the fast set's check; the load time is a goal of benchmarks/bench_fmu.py


@pytest.mark.parametrize("failure, status, words", [
    (kernel_layouts.ST_NONFINITE, FMI_DISCARD, "retry with a shorter step"),      # the master may retry
    (kernel_layouts.ST_EVENT_STORM, FMI_ERROR, "cannot get past"),                 # counted per forcing period
])
def test_solver_failure_inside_a_step_restores_the_state(monkeypatch, failure, status, words):
    """A failure of the integrator in the middle of a step leaves the state of the step start; a
    storm no shorter step can clear is an error, any other failure a Discard."""
    from hammerbit.model.slave import HammerBitRock
    s = HammerBitRock(instance_name="unit")
    s.setup_experiment(0.0)
    s.exit_initialization_mode()
    h = 2e-3
    for k in range(300):
        assert s.do_step(k * h, h)
    before = (s._st.get_state(), s._t)
    s.preload = 31.0                                      # a new input value that fails mid-step
    real = s._kernel

    def failing(y, ist, fst, t_end, *rest):
        real(y, ist, fst, 0.5 * (fst[kernel_layouts.F_T] + t_end), *rest)   # half-way, then fail
        ist[kernel_layouts.I_COUNT0] += 5
        return failure

    monkeypatch.setattr(s, "_kernel", failing)
    s._slow = True                  # do_step takes the kernel from the tuple its slow path rebuilds
    assert s.do_step(300 * h, h) is False
    assert s.last_status == status
    assert words in s.log_queue[-1].msg
    after = (s._st.get_state(), s._t)
    assert np.array_equal(after[0], before[0]) and after[1] == before[1]
    monkeypatch.setattr(s, "_kernel", real)
    s._slow = True
    s.preload = RIG.preload
    assert s.do_step(300 * h, h)


def test_stepper_snapshot_restores_the_integration_state_in_place():
    """Stepper.snapshot/restore (do_step's rollback): y, istate and fstate come back bit for bit, in
    the same arrays, and the stepper then continues exactly as it did the first time."""
    st = Stepper(RIG.to_groups(), solver=SolverOptions(rtol=TOL, atol=1e-2 * TOL))
    st.advance(3.0)
    arrays = (st.y, st.istate, st.fstate)
    before, snap = st.get_state(), st.snapshot()
    st.advance(9.0)                                  # moves y, the event counts and the clock
    first = st.get_state()
    assert not np.array_equal(first, before) and st.istate[kernel_layouts.I_COUNT0:].sum() > 0
    st.restore(snap)
    assert np.array_equal(st.get_state(), before)
    assert all(a is b for a, b in zip((st.y, st.istate, st.fstate), arrays))
    st.advance(9.0)
    assert np.array_equal(st.get_state(), first)


def test_tolerance_set_after_initialisation_applies_from_the_next_step():
    """The slave's step equals the library's Stepper stepped on the same grid, with its tolerance
    switched at the same communication point (and differs from not switching it)."""
    from hammerbit.model.slave import HammerBitRock
    s = HammerBitRock(instance_name="unit")
    s.setup_experiment(0.0)
    s.exit_initialization_mode()
    vr_tol = next(vr for vr, v in s.vars.items() if v.name == "tolerance")
    h, om = 5e-3, SCALES.omega
    lib = Stepper(RIG.to_groups(), solver=SolverOptions(rtol=TOL, atol=1e-2 * TOL))
    same = Stepper(RIG.to_groups(), solver=SolverOptions(rtol=TOL, atol=1e-2 * TOL))
    t = 0.0
    for k in range(200):
        if k == 100:
            s.set_real([vr_tol], [1e-6])
            assert s.last_status == 0
            state = lib.get_state()
            lib = Stepper(RIG.to_groups(), solver=SolverOptions(rtol=1e-6, atol=1e-8))
            lib.set_state(state)
        assert s.do_step(t, h)
        t += h
        lib.advance(t * om)
        same.advance(t * om)
    assert np.array_equal(s._st.get_state(), lib.get_state())
    assert not np.array_equal(lib.y, same.y)


@pytest.mark.parametrize("t, h", [(1e-3, -1e-3), (1e-3, math.nan), (0.5, 1e-3)],
                         ids=["negative step", "NaN step", "wrong communication point"])
def test_bad_do_step_in_process_is_an_error_and_changes_nothing(t, h):
    """The slave itself (no FMU archive): a bad fmi2DoStep returns False with fmi2Error and a log
    message naming the bad value, and the state and clock stay where they were."""
    from hammerbit.model.slave import HammerBitRock
    s = HammerBitRock(instance_name="unit")
    s.setup_experiment(0.0)
    s.exit_initialization_mode()
    assert s.do_step(0.0, 1e-3) and s.last_status == FMI_OK
    before = (s._st.get_state(), s._t)
    assert s.do_step(t, h) is False                     # the clock is at 1 ms
    assert s.last_status == FMI_ERROR
    assert "step" in s.log_queue[-1].msg or "Communication" in s.log_queue[-1].msg
    assert np.array_equal(s._st.get_state(), before[0]) and s._t == before[1]

"""The native runtime flavour of HammerBitRock.fmu (``hammerbit fmu build --runtime native``).

The FMU is built once for the module.  Its binaries hold the library's own kernels compiled to
machine code: a C host with an empty environment and no Python, the same host cross-built for
Windows under wine, fmpy (co-simulation and Model Exchange), libcosim and ecos run it.  The
oracle is the library itself (``Stepper``, ``simulate``), run here in the test process.
"""
from __future__ import annotations

import csv
import math
import os
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import (FMU2Model, fmi2CallbackAllocateMemoryTYPE,  # noqa: E402
                       fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE,
                       fmi2Real)

from hammerbit.fmu.native_build import MINGW_CC, select_platforms  # noqa: E402
from fmu_slave import FMI_ERROR, FMI_WARNING, Slave  # noqa: E402
from native_hosts import ecos_or_skip, linux_host as build_linux_host, windows_host_or_skip  # noqa: E402
from hammerbit.model.kernel_layouts import P_B, P_FEXT  # noqa: E402
from hammerbit.model.params import RigParameters  # noqa: E402
from hammerbit.model.presets import preset  # noqa: E402
from hammerbit.model.solver_options import SolverOptions  # noqa: E402
from hammerbit.model.stepping import Stepper  # noqa: E402
from cached_compile import compile_c  # noqa: E402

ID = "HammerBitRock"
RIG = RigParameters()
SC = RIG.scales
H = 1e-3
#: the outputs the hosts print, in this order
COMPARED = ("bit_position", "hammer_position", "hammer_velocity", "rock_force", "friction_force")
#: relative agreement asked of two builds of the same kernels (Linux/Windows, FMU/library)
REL = 1e-13


# ---------------------------------------------------------------------------
# fixtures
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def native_fmu(built_native_fmu):
    return built_native_fmu


@pytest.fixture(scope="module")
def native_dir(native_fmu, tmp_path_factory):
    d = tmp_path_factory.mktemp("native_x")
    with zipfile.ZipFile(native_fmu) as zf:
        zf.extractall(d)
    return d


@pytest.fixture(scope="module")
def md(native_dir):
    return read_model_description(str(native_dir / "modelDescription.xml"))


@pytest.fixture(scope="module")
def vrs(md):
    return {v.name: v.valueReference for v in md.modelVariables}


@pytest.fixture(scope="module")
def linux_host(tmp_path_factory):
    return build_linux_host(tmp_path_factory.mktemp("host"))


def run_linux_host(host, native_dir, md, vrs, **opts):
    """The host with an empty environment (``env -i``): no PATH, so no python3 to find."""
    so = native_dir / "binaries" / "linux64" / f"{ID}.so"
    args = ["env", "-i", str(host), str(so), (native_dir / "resources").as_uri(), md.guid,
            "out=" + ",".join(str(vrs[n]) for n in COMPARED), *(f"{k}={v}" for k, v in opts.items())]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=120)
    values = [float(line.split()[1]) for line in proc.stdout.splitlines() if line.startswith("value ")]
    return proc, values


def library_outputs(seconds: float, h: float = H) -> list:
    """The oracle: the library's Stepper on the lab rig, stepped like a master steps the FMU."""
    g = RIG.to_groups()
    st = Stepper(g.replace(b=0.0), solver=SolverOptions(rtol=1e-8, atol=1e-10))
    st.p[P_B] = RIG.preload / SC.friction_force
    n = round(seconds / h)
    for k in range(n):
        st.advance((k * h + h) * SC.omega)
    y, p = st.y, st.p
    x1, x2, x3, x4 = y
    spring = (x1 - x3) + 2.0 * p[1] * (x2 - x4)
    return [x3 * SC.length, x1 * SC.length, x2 * SC.velocity, spring * SC.friction_force,
            spring * SC.friction_force]


def assert_close(got, want, *, label):
    """Each compared output equal to REL relative (velocities against their scale x0 Omega)."""
    scales = [SC.length, SC.length, SC.velocity, SC.friction_force, SC.friction_force]
    for name, a, b, s in zip(COMPARED, got, want, scales):
        assert abs(a - b) <= REL * max(abs(b), s), f"{label}: {name} {a!r} vs {b!r}"


# ---------------------------------------------------------------------------
# what the FMU holds
# ---------------------------------------------------------------------------
def test_native_fmu_holds_both_interfaces_and_no_python(native_fmu, md):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(native_fmu)) == []
    assert md.coSimulation is not None and md.modelExchange is not None
    assert md.coSimulation.modelIdentifier == md.modelExchange.modelIdentifier == ID
    assert md.numberOfEventIndicators == 9 and md.numberOfContinuousStates == 4
    states = [d.variable.name for d in md.derivatives]
    assert states == ["der(hammer_position)", "der(hammer_velocity)", "der(bit_position)",
                      "der(bit_velocity)"]
    names = zipfile.ZipFile(native_fmu).namelist()
    assert f"binaries/linux64/{ID}.so" in names
    assert not [n for n in names if n.endswith(".py") or "_python" in n or "_compiled" in n]
    if shutil.which(MINGW_CC):
        assert f"binaries/win64/{ID}.dll" in names


def test_native_binaries_link_no_python_numba_or_nrt(native_dir):
    so = native_dir / "binaries" / "linux64" / f"{ID}.so"
    ldd = subprocess.run(["ldd", str(so)], capture_output=True, text=True, check=True).stdout
    libs = {line.split()[0] for line in ldd.splitlines() if line.strip()}
    assert all(re.match(r"(linux-vdso|libm\.|libc\.|/lib.*ld-linux|libpthread\.)", lib) for lib in libs), libs
    dyn = subprocess.run(["nm", "-D", str(so)], capture_output=True, text=True, check=True).stdout
    defined = [ln.split()[-1] for ln in dyn.splitlines() if ln.split()[-2:-1] == ["T"]]
    assert defined and all(n.startswith("fmi2") for n in defined), defined
    text = dyn.lower()
    for bad in ("python", "py_", "numba", "nrt_", "numpy"):
        assert bad not in text, bad
    dll = native_dir / "binaries" / "win64" / f"{ID}.dll"
    objdump = shutil.which("x86_64-w64-mingw32-objdump") or shutil.which("objdump")
    if dll.exists() and objdump:
        p = subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True, check=True).stdout
        dlls = {ln.split(":", 1)[1].strip().lower() for ln in p.splitlines() if "DLL Name:" in ln}
        assert dlls <= {"kernel32.dll", "msvcrt.dll"}, dlls
        assert "python" not in p.lower() and "numba" not in p.lower() and "NRT_" not in p


def test_build_without_mingw_skips_win64_and_says_so(monkeypatch):
    import hammerbit.fmu.native_build as nb
    real_which = shutil.which
    monkeypatch.setattr(nb.shutil, "which", lambda name, *a, **k: None if name == MINGW_CC
                        else real_which(name, *a, **k))
    said = []
    assert select_platforms(said.append) == ["linux64"]
    assert len(said) == 1 and MINGW_CC in said[0] and "gcc-mingw-w64-x86-64" in said[0]


# ---------------------------------------------------------------------------
# native hosts
# ---------------------------------------------------------------------------
def test_c_host_without_python_equals_the_library(linux_host, native_dir, md, vrs):
    proc, values = run_linux_host(linux_host, native_dir, md, vrs, steps=10000, h=H)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert len(values) == len(COMPARED)
    assert values[0] > 0.05          # the lab rig drills: ~0.1 m in 10 s
    assert_close(values, library_outputs(10.0), label="C host (Linux) vs Stepper")


def test_windows_host_under_wine_equals_the_linux_run(linux_host, native_dir, md, vrs, tmp_path):
    dll = native_dir / "binaries" / "win64" / f"{ID}.dll"
    wine, exe = windows_host_or_skip(dll, tmp_path)
    uri = "file:///Z:" + urllib_quote((native_dir / "resources").as_posix())
    outs = "out=" + ",".join(str(vrs[n]) for n in COMPARED)
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "WINEDEBUG": "-all",
           "WINEPREFIX": os.environ.get("WINEPREFIX", str(Path.home() / ".wine"))}
    proc = subprocess.run([wine, str(exe), "Z:" + str(dll).replace("/", "\\"), uri, md.guid, outs,
                           "steps=10000"], capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    win = [float(ln.split()[1]) for ln in proc.stdout.splitlines() if ln.startswith("value ")]
    lproc, lin = run_linux_host(linux_host, native_dir, md, vrs, steps=10000)
    assert lproc.returncode == 0 and len(win) == len(lin) == len(COMPARED)
    assert_close(win, lin, label="Windows (wine) vs Linux")


def urllib_quote(path: str) -> str:
    import urllib.parse
    return urllib.parse.quote(path)


# ---------------------------------------------------------------------------
# fmpy, co-simulation
# ---------------------------------------------------------------------------
def test_fmpy_cs_with_changing_inputs_and_start_time_equals_the_library(native_dir):
    """Inputs held over each step, changed every 0.25 s; a start time of 7 s shifts the phase."""
    t0 = 7.0
    s = Slave(native_dir, start_time=t0)
    g = RIG.to_groups()
    phi = math.fmod(RIG.phase + 2.0 * math.pi * RIG.frequency * t0, 2.0 * math.pi)
    st = Stepper(g.replace(b=0.0, phi=phi), solver=SolverOptions(rtol=1e-8, atol=1e-10))
    F0 = SC.friction_force
    for k in range(2000):
        if k % 250 == 0:
            preload, force = 25.0 + 0.01 * k, 3.0 * math.sin(k)
            s.fmu.setReal([s.vr["preload"], s.vr["harmonic_force"]], [preload, force])
            st.p[P_B], st.p[P_FEXT] = preload / F0, force / F0
        s.step()
        st.advance((s.t - t0) * SC.omega)
    x_fmu, v_fmu = s.get("bit_position", "hammer_velocity")
    assert x_fmu == pytest.approx(st.y[2] * SC.length, rel=REL) and x_fmu > 1e-3
    assert v_fmu == pytest.approx(st.y[1] * SC.velocity, rel=0, abs=REL * SC.velocity)
    slips = s.fmu.getInteger([s.vr["slip_count"]])[0]
    assert slips == st.counts["slip_start"] > 0
    s.close()


def test_state_rollback_and_serialisation_are_bit_identical(native_dir):
    reals = {"gap": 0.84 * SC.length, "amplitude": 0.06 * SC.friction_force}
    s = Slave(native_dir, reals=reals, booleans={"impact_enabled": True})
    for _ in range(500):
        s.step()
    state = s.fmu.getFMUstate()
    blob = s.fmu.serializeFMUstate(state)
    t_saved = s.t
    outs = []
    for _ in range(3):
        for _ in range(700):
            s.step()
        outs.append(s.get("bit_position", "hammer_velocity", "contact_force"))
        s.fmu.setFMUstate(state)
        s.t = t_saved
    assert outs[0] == outs[1] and s.fmu.getInteger([s.vr["impact_count"]])[0] >= 0
    other = Slave(native_dir)                       # other parameters: the state carries them
    other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(blob))
    other.t = t_saved
    for _ in range(700):
        other.step()
    assert other.get("bit_position", "hammer_velocity", "contact_force") == outs[0]
    assert s.fmu.getInteger([s.vr["impact_count"]])[0] > 0
    s.close()
    other.close()


# ---------------------------------------------------------------------------
# bad input: fmi2Error with a message, nothing changed
# ---------------------------------------------------------------------------
def test_invalid_input_is_an_error_with_a_message_and_changes_nothing(native_dir):
    s = Slave(native_dir, logging=False)
    for _ in range(10):
        s.step()
    before = s.get("preload", "harmonic_force", "bit_position")
    # a vector set with one bad value applies none of them
    st = s.status_of(s.fmu.setReal, [s.vr["harmonic_force"], s.vr["preload"]], [5.0, 1e12])
    assert st == FMI_ERROR
    msg = s.errors()[-1]
    limit = 1000.0 * SC.friction_force          # the range follows F0 = mu_static normal_force
    assert "'preload'" in msg and "1000000000000.0" in msg and f"[-{limit:g}, {limit:g}] N" in msg
    assert s.get("preload", "harmonic_force", "bit_position") == before
    assert s.fmu.getInteger([s.vr["last_status"]])[0] == FMI_ERROR
    s.fmu.freeInstance()
    # a fixed parameter after initialisation
    s = Slave(native_dir, logging=False)
    assert s.status_of(s.fmu.setReal, [s.vr["hammer_mass"]], [30.0]) == FMI_ERROR
    assert "hammer_mass" in s.errors()[-1] and "fixed" in s.errors()[-1]
    assert s.get("hammer_mass") == [RIG.hammer_mass]
    s.fmu.freeInstance()


def test_invalid_parameter_fails_initialisation_naming_it(native_dir):
    s = Slave(native_dir, reals={"hammer_mass": -1.0}, init=False)
    assert s.messages and s.messages[-1][0] == FMI_WARNING           # out of range when set
    assert s.status_of(s.fmu.exitInitializationMode) == FMI_ERROR
    assert "parameter 'hammer_mass' = -1.0 is out of range: allowed [1e-06, 1e+09] kg" in s.errors()[-1]
    s2 = Slave(native_dir, reals={"mu_kinetic": 0.7}, init=False)    # above mu_static = 0.62
    assert s2.status_of(s2.fmu.exitInitializationMode) == FMI_ERROR
    assert "'mu_kinetic' = 0.7" in s2.errors()[-1] and "mu_static" in s2.errors()[-1]


def test_bad_step_and_corrupt_state_are_errors(native_dir):
    s = Slave(native_dir)
    s.step()
    x = s.get("bit_position")
    assert s.status_of(s.fmu.doStep, s.t + 0.5, H) == FMI_ERROR
    assert "not the current time" in s.errors()[-1]
    s2 = Slave(native_dir)
    state = s2.fmu.getFMUstate()
    blob = bytearray(s2.fmu.serializeFMUstate(state))
    blob[-600] ^= 0xFF                       # inside the model state (its flags and numbers)
    blob[100:108] = np.array([np.nan]).tobytes()
    assert s2.status_of(s2.fmu.deSerializeFMUstate, bytes(blob)) == FMI_ERROR
    assert "fmi2DeSerializeFMUstate" in s2.errors()[-1]
    assert s.get("bit_position") == x


# ---------------------------------------------------------------------------
# other masters
# ---------------------------------------------------------------------------
def test_libcosim_runs_the_native_fmu_like_the_library(native_fmu):
    pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    log_output_level(CosimLogLevel.ERROR)
    ex = CosimExecution.from_step_size(step_size=int(1e6))            # 1 ms, in ns
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(native_fmu), instance_name="hammer"))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    assert ex.simulate_until(target_time=int(3e9))
    x = obs.last_real_values(idx, [vr["bit_position"]])[0]
    ex.stop()
    assert x == pytest.approx(library_outputs(3.0)[0], rel=1e-9) and x > 1e-3


def _ecos_or_skip(tmp: Path) -> tuple[Path, dict]:
    ecos, tbb = ecos_or_skip(tmp)
    # nothing that points at a Python (no HAMMERBIT_PYTHON, no PYTHONPATH); PATH for ecos's unzip
    return ecos, {"PATH": "/usr/bin:/bin", "HOME": str(tmp), "LD_LIBRARY_PATH": f"{tbb}:{tmp}"}


def test_ecos_runs_the_native_fmu(native_fmu, tmp_path):
    ecos, env = _ecos_or_skip(tmp_path)
    fmu = shutil.copy(native_fmu, tmp_path / f"{ID}.fmu")
    proc = subprocess.run([str(ecos), "simulate", "--path", str(fmu), "--stopTime", "0.5",
                           "--stepSize", "0.001", "--noParallel"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    rows = list(csv.reader((tmp_path / f"{ID}.csv").open(), skipinitialspace=True))
    col = next(i for i, h in enumerate(rows[0]) if h.endswith("::hammer_position[REAL]"))
    last = rows[-1]
    n = int(last[0])                 # iterations done: the row holds the outputs at n h
    assert n >= 490
    assert float(last[col]) == pytest.approx(library_outputs(n * H)[1], abs=1e-6)   # CSV: 6 decimals


# ---------------------------------------------------------------------------
# Model Exchange
# ---------------------------------------------------------------------------
def _scene_start_values(groups) -> dict:
    rig = groups.to_rig()
    names = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
             "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
             "contact_damping", "amplitude", "frequency", "phase", "preload")
    sv = {n: getattr(rig, n) for n in names}
    if math.isfinite(rig.gap):
        sv.update(gap=rig.gap, impact_enabled=True)
    return sv


@pytest.mark.parametrize("scene,a", [("paper-fig9", 0.083), ("paper-fig12", 0.06)])
def test_model_exchange_reproduces_the_library(native_fmu, scene, a):
    from hammerbit.scene.analysis import detect_period
    from hammerbit.scene.simulate import Record, simulate
    g = preset(scene).replace(a=a)
    sc, periods = g.scales, 100
    res = fmpy.simulate_fmu(str(native_fmu), fmi_type="ModelExchange", start_values=_scene_start_values(g),
                            stop_time=periods * g.period_s, relative_tolerance=1e-10,
                            output_interval=g.period_s, record_events=False,
                            output=["hammer_position", "hammer_velocity", "bit_position", "bit_velocity"])
    lib = simulate(g, periods, record=Record(poincare=True), solver=SolverOptions(rtol=1e-10, atol=1e-12))
    x_me, x_lib = res["bit_position"][-1], lib.final[2] * sc.length
    assert x_lib > 0.0 and abs(x_me - x_lib) <= 1e-6 * abs(x_lib)
    poin = np.column_stack([res["time"], res["hammer_position"] / sc.length,
                            res["hammer_velocity"] / sc.velocity, res["bit_position"] / sc.length,
                            res["bit_velocity"] / sc.velocity])
    n_lib = detect_period(lib.poincare)
    assert n_lib is not None and detect_period(poin) == n_lib


def test_model_exchange_bad_sizes_are_errors(native_dir):
    md = read_model_description(str(native_dir / "modelDescription.xml"))
    m = FMU2Model(guid=md.guid, unzipDirectory=str(native_dir),
                  modelIdentifier=md.modelExchange.modelIdentifier, instanceName="me")
    messages = []

    def logger(env, instance, status, category, message):
        messages.append((status, message.decode()))

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    m.instantiate(callbacks=cb, loggingOn=False)
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    m.exitInitializationMode()
    m.newDiscreteStates()
    m.enterContinuousTimeMode()
    x4 = (fmi2Real * 4)()
    m.getContinuousStates(x4, 4)
    m.enterEventMode()
    with pytest.raises(FMICallException):          # states are set in Continuous-Time Mode only
        m.setContinuousStates(x4, 4)
    assert "illegal call sequence" in messages[-1][1] and "Event Mode" in messages[-1][1]
    m.reset()                                      # recovers from the Error state
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    m.exitInitializationMode()
    x = (fmi2Real * 3)()
    with pytest.raises(FMICallException) as e:
        m.getContinuousStates(x, 3)
    assert e.value.status == FMI_ERROR
    assert "3 values given, the model has 4" in messages[-1][1]
    m.freeInstance()


def test_start_values_of_the_build_are_the_binaries_own(tmp_path):
    """``--set`` values reach the model description and the compiled-in defaults alike."""
    from hammerbit.fmu.build import build_fmu
    fmu = build_fmu(tmp_path / f"{ID}.fmu", runtime="native",
                    start_values={"hammer_mass": 30.0, "preload": 35.0})
    d = tmp_path / "x"
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(d)
    md = read_model_description(str(d / "modelDescription.xml"))
    starts = {v.name: v.start for v in md.modelVariables}
    assert float(starts["hammer_mass"]) == 30.0 and float(starts["preload"]) == 35.0
    s = Slave(d)                                      # nothing set: the binary's own defaults
    assert s.get("hammer_mass", "preload") == [30.0, 35.0]
    s.close()


def test_a_step_storm_is_an_error_at_the_librarys_time_and_changes_nothing(native_dir):
    """Too stiff for the solver's step budget per forcing period: fmi2Error naming the time the
    library's own Stepper stops at (no shorter step gets past it), the state as before the step."""
    import re as _re
    from hammerbit.model.solver_errors import StepStormError
    stiff = {"stiffness": 1e15, "hammer_mass": 1e-6, "bit_mass": 1e-6}   # Omega = 3.2e10 rad/s
    s = Slave(native_dir, reals=stiff)
    before = s.get("hammer_position", "hammer_velocity")
    assert s.status_of(s.fmu.doStep, 0.0, 1e-3) == FMI_ERROR
    msg = s.errors()[-1]
    assert "step storm" in msg and "retry" not in msg, msg
    t_fail = float(_re.search(r"cannot get past t = ([-+0-9.e]+) s", msg).group(1))
    rig = RIG.replace(**stiff)
    st = Stepper(rig.to_groups().replace(b=0.0), solver=SolverOptions(rtol=1e-8, atol=1e-10))
    st.p[P_B] = RIG.preload / rig.scales.friction_force
    with pytest.raises(StepStormError) as e:
        st.advance(1e-3 * rig.scales.omega)
    assert t_fail == pytest.approx(e.value.time / rig.scales.omega, rel=1e-12)
    assert s.get("hammer_position", "hammer_velocity") == before
    s.fmu.freeInstance()


def test_a_kernel_object_needing_more_than_the_shim_is_refused_naming_the_symbols(tmp_path):
    """``link_binary`` checks the object's undefined symbols against what the shim provides before
    it links (both native FMUs link through it)."""
    from hammerbit.fmu.native import FrontBuildError, find_compiler
    from hammerbit.fmu.native_build import NativeBuildError, link_binary
    try:
        cc = find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))
    src = tmp_path / "k.c"
    src.write_text("double PyNumber_Float(double);\ndouble hb_k(double x) { return PyNumber_Float(x) + exp(x); }\n"
                   "double exp(double);\n")
    obj = tmp_path / "kernels_linux64.o"
    compile_c([cc, "-c", "-fPIC", "-o", str(obj), str(src)], obj, tmp_path)
    with pytest.raises(NativeBuildError, match=r"kernels_linux64\.o needs symbols no shim provides: "
                                               r"\['PyNumber_Float'\]"):
        link_binary("linux64", cc, obj, tmp_path, tmp_path / "out.so")
    assert not (tmp_path / "out.so").exists()

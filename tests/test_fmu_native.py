"""The FMU's native front (hammerbit.fmu.native) in native and Python hosts.

A C host compiled here against the standard FMI 2.0 headers loads the FMU with no LD_PRELOAD
and no PYTHONPATH and must reproduce fmpy's result on the plain pythonfmu FMU; resource URIs,
GUID, FMU type, the state machine, value-reference checks, the slave's status protocol
(``last_status``, through a stub slave), serialized states, process exit, and ecos as a second
native master.  Skipped (with the reason) when no C compiler is installed.
"""
from __future__ import annotations

import csv
import ctypes
import os
import re
import shutil
import subprocess
import sys
import textwrap
import urllib.parse
import zipfile
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi2 import fmi2LastSuccessfulTime, fmi2Terminated  # noqa: E402

from hammerbit.fmu.native import (FrontBuildError, build_front, find_compiler,  # noqa: E402
                                  generate_header, read_model_description as read_spec)
from fmu_slave import FMI_DISCARD, FMI_ERROR, FMI_OK, Slave  # noqa: E402
from native_hosts import ecos_or_skip, host_env  # noqa: E402
from cached_compile import compile_c  # noqa: E402

HERE = Path(__file__).resolve().parent
HOST_SOURCE = HERE / "fmu_native_host.c"
ID = "HammerBitRock"


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def _compiler_or_skip() -> str:
    try:
        return find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))


def _shared_libpython_or_skip() -> None:
    """A native host embeds this Python through its shared library; skip if it has none."""
    import sysconfig
    v = sysconfig.get_config_var
    names = [n for n in (v("INSTSONAME"), v("LDLIBRARY")) if n and ".so" in n]
    dirs = [v("LIBDIR") or "", os.path.join(v("LIBDIR") or "", v("MULTIARCH") or "")]
    if not any(os.path.isfile(os.path.join(d, n)) for d in dirs for n in names):
        pytest.skip(f"{sys.executable} has no shared libpython, which a native host needs")


def add_front(fmu: Path, dest: Path) -> Path:
    """Extract ``fmu`` into ``dest`` with the native front as ``binaries/linux64/<id>.so`` and
    pythonfmu's library next to it as ``<id>_python.so``; return ``dest``.  An FMU from
    ``hammerbit fmu build`` carries both already; a plain pythonfmu FMU gets the front here."""
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(dest)
    md = (dest / "modelDescription.xml").read_text()
    ident = read_spec(md).model_identifier
    bindir = dest / "binaries" / "linux64"
    if not (bindir / f"{ident}_python.so").exists():
        (bindir / f"{ident}.so").rename(bindir / f"{ident}_python.so")
        build_front(md, bindir, wrapper_name=f"{ident}_python")
    return dest


def zip_dir(src: Path, fmu: Path) -> Path:
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(src.rglob("*")):
            if p.is_file():
                zf.write(p, p.relative_to(src).as_posix())
    return fmu


def run_host(host: Path, fmu_dir: Path, *, uri=None, guid=None, env=None, **opts):
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    uri = uri or (fmu_dir / "resources").as_uri()
    args = [str(host), str(fmu_dir / "binaries" / "linux64" / f"{ID}.so"), uri, guid or md.guid]
    args += [f"{k}={v}" for k, v in opts.items()]
    env = env if env is not None else host_env(HAMMERBIT_PYTHON=sys.executable)
    proc = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300)
    value = next((float(line.split()[1]) for line in proc.stdout.splitlines()
                  if line.startswith("value ")), None)
    return proc, value


def vr_of(fmu_dir: Path, name: str) -> int:
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    return next(v.valueReference for v in md.modelVariables if v.name == name)


def fmpy_positions(fmu_dir: Path, n: int, h: float) -> list[float]:
    """bit_position after each of n steps t_i = i h, by fmpy (the oracle when fmu_dir has no front)."""
    s = Slave(fmu_dir)
    out = []
    for i in range(n):
        s.fmu.doStep(i * h, h)
        out.append(s.fmu.getReal([s.vr["bit_position"]])[0])
    s.fmu.terminate()
    s.fmu.freeInstance()
    return out


# ---------------------------------------------------------------------------
# fixtures
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def plain_dir(built_fmu, tmp_path_factory):
    """The built FMU with pythonfmu's library only (the front taken out), extracted."""
    d = tmp_path_factory.mktemp("plain")
    with zipfile.ZipFile(built_fmu) as zf:
        zf.extractall(d)
    bindir = d / "binaries" / "linux64"
    for wrapper in bindir.glob("*_python.so"):
        wrapper.replace(bindir / wrapper.name.replace("_python.so", ".so"))
    return d


@pytest.fixture(scope="module")
def front_dir(built_fmu, tmp_path_factory):
    _compiler_or_skip()
    return add_front(built_fmu, tmp_path_factory.mktemp("front"))


@pytest.fixture(scope="module")
def c_host(tmp_path_factory):
    cc = _compiler_or_skip()
    _shared_libpython_or_skip()
    include = Path(fmpy.__file__).parent / "c-code"
    exe = tmp_path_factory.mktemp("host") / "fmu_native_host"
    return compile_c([cc, "-O1", "-I", str(include), "-o", str(exe), str(HOST_SOURCE), "-ldl", "-lpthread"],
                     exe, exe.parent)


@pytest.fixture(scope="module")
def oracle_10s(plain_dir):
    return fmpy_positions(plain_dir, 10000, 1e-3)[-1]


# ---------------------------------------------------------------------------
# build API (no compiler needed)
# ---------------------------------------------------------------------------
def test_model_description_tables(built_fmu):
    with zipfile.ZipFile(built_fmu) as zf:
        spec = read_spec(zf.read("modelDescription.xml"))
    by_name = {v.name: v for v in spec.variables}
    # states bits: 1 Instantiated, 2 Initialization Mode, 4 Step Mode
    assert by_name["preload"].set_mask == 7                      # input
    assert by_name["tolerance"].set_mask == 7                    # tunable parameter
    assert by_name["hammer_mass"].set_mask == 3                  # fixed parameter
    assert by_name["bit_position"].set_mask == 0                 # output
    assert spec.model_identifier == ID and spec.guid
    header = generate_header(spec, wrapper_file="x_python.so")
    assert f'#define HB_GUID "{spec.guid}"' in header
    assert f"#define HB_NVARS {len(spec.variables)}u" in header
    expected_flag = 0 if spec.status_vr is None else 1
    assert f"#define HB_HAS_STATUS_VR {expected_flag}" in header


def test_missing_compiler_is_a_clear_error(built_fmu, tmp_path, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with zipfile.ZipFile(built_fmu) as zf:
        md = zf.read("modelDescription.xml").decode()
    with pytest.raises(FrontBuildError, match="C compiler.*CC="):
        build_front(md, tmp_path)


def test_non_fmi2_description_is_refused(tmp_path):
    with pytest.raises(FrontBuildError, match="FMI 2.0"):
        build_front('<fmiModelDescription fmiVersion="3.0"/>', tmp_path)


def test_front_exports_fmi_only_and_needs_an_old_glibc(front_dir):
    """Only the FMI functions (and pythonfmu's finalizePythonInterpreter) are exported; the
    glibc symbol versions stay at 2.17 or older, whatever glibc built the front."""
    objdump = shutil.which("objdump")
    if objdump is None:
        pytest.skip("objdump (binutils) is not installed")

    def dynamic_symbols(name):
        out = subprocess.run([objdump, "-T", str(front_dir / "binaries" / "linux64" / name)],
                             capture_output=True, text=True, check=True).stdout
        return out, {line.split()[-1] for line in out.splitlines() if " .text" in line}

    out, defined = dynamic_symbols(f"{ID}.so")
    _, wrapped = dynamic_symbols(f"{ID}_python.so")
    assert all(n.startswith("fmi2") or n == "finalizePythonInterpreter" for n in defined)
    assert {n for n in wrapped if n.startswith("fmi2")} <= defined     # all that pythonfmu offers
    versions = {tuple(int(x) for x in m.split(".")) for m in re.findall(r"GLIBC_([0-9.]+)", out)}
    assert versions and max(versions) <= (2, 17), sorted(versions)


# ---------------------------------------------------------------------------
# the C host
# ---------------------------------------------------------------------------
def test_c_host_steps_10_s_like_fmpy_and_exits_0(front_dir, c_host, oracle_10s):
    proc, value = run_host(c_host, front_dir, steps=10000, h=1e-3,
                           out=vr_of(front_dir, "bit_position"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert value is not None and value > 0.0
    assert abs(value - oracle_10s) <= 1e-12 * max(1.0, abs(oracle_10s)), (value, oracle_10s)


def test_c_host_threads_start_python_once_and_agree(front_dir, c_host):
    """Three instances created and stepped at once, each in its own host thread."""
    proc, _ = run_host(c_host, front_dir, threads=3, steps=300, out=vr_of(front_dir, "bit_position"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    values = [float(line.split()[1]) for line in proc.stdout.splitlines() if line.startswith("value ")]
    assert len(values) == 3 and len(set(values)) == 1 and values[0] > 0.0, values


def test_python3_on_path_is_found(front_dir, c_host):
    bindir = Path(sys.executable).parent
    if not (bindir / "python3").exists():
        pytest.skip(f"no python3 next to {sys.executable}")
    env = host_env(PATH=f"{bindir}:/usr/bin:/bin")
    proc, value = run_host(c_host, front_dir, env=env, steps=100, out=vr_of(front_dir, "bit_position"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert value is not None


@pytest.fixture(scope="module")
def odd_dir(front_dir, tmp_path_factory):
    """The front FMU in a directory whose name needs percent-encoding (space, non-ASCII, '#')."""
    d = tmp_path_factory.mktemp("uri") / "Bohrkopf ü #1" / ID
    shutil.copytree(front_dir, d)
    return d


URI_FORMS = ["file:/", "file://localhost/", "file:///", "unencoded"]


@pytest.fixture(scope="module")
def uri_runs(odd_dir, c_host):
    """One host process, one instance per form of :data:`URI_FORMS` after the other (``uri1=``...):
    ``{form: (exit code of that instance, its value or None, the host's output)}``."""
    path = str(odd_dir / "resources")
    quoted = urllib.parse.quote(path.lstrip("/"), safe="/")
    assert "%C3%BC" in quoted and "%23" in quoted and "%20" in quoted
    uris = [f"file:///{path.lstrip('/')}" if form == "unencoded" else form + quoted for form in URI_FORMS]
    extra = {f"uri{i}": u for i, u in enumerate(uris) if i}
    proc, _ = run_host(c_host, odd_dir, uri=uris[0], steps=20, out=vr_of(odd_dir, "bit_position"), **extra)
    runs, value = {}, None
    for line in proc.stdout.splitlines():
        if line.startswith("value "):
            value = float(line.split()[1])
        elif line.startswith("result "):
            i, rc = map(int, line.split()[1:3])
            runs[URI_FORMS[i]] = (rc, value, proc.stdout + proc.stderr)
            value = None
    assert len(runs) == len(URI_FORMS), proc.stdout + proc.stderr
    assert proc.returncode == next((rc for rc, _, _ in runs.values() if rc), 0)
    return runs


@pytest.mark.parametrize("form", URI_FORMS)
def test_resource_uri_forms(uri_runs, form):
    rc, value, output = uri_runs[form]
    assert rc == 0, output
    assert value is not None


def test_wrong_guid_native(front_dir, c_host):
    proc, _ = run_host(c_host, front_dir, guid="{not-this-fmu}")
    assert proc.returncode == 10, proc.stdout
    assert "log 3" in proc.stdout and "GUID '{not-this-fmu}' does not match" in proc.stdout


def test_model_exchange_refused_native(front_dir, c_host):
    proc, _ = run_host(c_host, front_dir, type=0)
    assert proc.returncode == 10, proc.stdout
    assert "supports only fmi2CoSimulation" in proc.stdout


def test_missing_python_is_reported(front_dir, c_host, tmp_path):
    missing = tmp_path / "no" / "python3"
    proc, _ = run_host(c_host, front_dir, env=host_env(HAMMERBIT_PYTHON=str(missing)))
    assert proc.returncode == 10, proc.stdout
    assert f"HAMMERBIT_PYTHON={missing}" in proc.stdout and "numpy and numba" in proc.stdout
    proc, _ = run_host(c_host, front_dir, env=host_env(PATH=str(tmp_path)))
    assert proc.returncode == 10, proc.stdout
    assert "python3 on PATH" in proc.stdout


def test_python_without_numba_is_reported(front_dir, c_host, tmp_path):
    venv = tmp_path / "bare"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    proc, _ = run_host(c_host, front_dir, env=host_env(HAMMERBIT_PYTHON=str(venv / "bin" / "python")))
    assert proc.returncode == 10, proc.stdout
    line = next(l for l in proc.stdout.splitlines() if l.startswith("log 3"))
    assert "lacks the modules: numpy numba" in line and "HAMMERBIT_PYTHON" in line


# ---------------------------------------------------------------------------
# a Python host (fmpy) with the front
# ---------------------------------------------------------------------------
def test_python_host_with_front_matches_and_exits_0(front_dir, oracle_10s):
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(HERE)!r})
        from test_fmu_native import fmpy_positions
        from pathlib import Path
        print(repr(fmpy_positions(Path({str(front_dir)!r}), 10000, 1e-3)[-1]))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert float(proc.stdout.split()[-1]) == pytest.approx(oracle_10s, rel=0, abs=1e-12)


def test_python_host_without_numba_logs_the_reason(front_dir):
    script = textwrap.dedent(f"""
        import sys
        sys.modules["numba"] = None
        sys.path.insert(0, {str(HERE)!r})
        from pathlib import Path
        from fmu_slave import Slave
        s = Slave.__new__(Slave)
        try:
            Slave.__init__(s, Path({str(front_dir)!r}), setup=False)
        except Exception as e:
            print("refused:", e)
        print("\\n".join(m for _, m in s.messages))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "refused: Failed to instantiate model" in proc.stdout
    assert "lacks what the FMU needs: numba (not installed)" in proc.stdout
    assert "install them into the Python that runs this host" in proc.stdout


def test_wrong_guid_and_model_exchange_are_refused_with_logging_off(front_dir):
    s = Slave(front_dir, setup=False)
    uri = (front_dir / "resources").as_uri()
    assert s.raw_instantiate(1, "{wrong}", uri) is None
    assert any("GUID '{wrong}' does not match" in m for m in s.errors())
    assert s.raw_instantiate(0, s.md.guid, uri) is None
    assert any("supports only fmi2CoSimulation" in m for m in s.errors())
    assert s.raw_instantiate(1, s.md.guid, "file://otherhost" + uri[7:]) is None
    assert any("names the host 'otherhost'" in m for m in s.errors())
    assert s.raw_instantiate(1, s.md.guid, uri + "/nowhere") is None
    assert any("no such directory" in m for m in s.errors())
    assert s.raw_instantiate(1, s.md.guid, uri + "/%zz") is None
    assert any("invalid percent-escape" in m for m in s.errors())
    s.fmu.freeInstance()


def test_unknown_and_mistyped_value_references(front_dir):
    s = Slave(front_dir)
    assert s.status_of(s.fmu.getReal, [9999]) == FMI_ERROR
    assert any("unknown value reference 9999" in m for m in s.errors())
    s = Slave(front_dir)
    assert s.status_of(s.fmu.getReal, [s.vr["stick_slip"]]) == FMI_ERROR
    assert any("stick_slip, a Integer variable, not a Real" in m for m in s.errors())
    s = Slave(front_dir)
    assert s.status_of(s.fmu.setReal, [s.vr["bit_position"]], [1.0]) == FMI_ERROR
    assert any("bit_position" in m and "cannot be set" in m for m in s.errors())
    s = Slave(front_dir)
    assert s.status_of(s.fmu.setReal, [s.vr["hammer_mass"]], [30.0]) == FMI_ERROR
    assert any("hammer_mass" in m and "parameter, fixed" in m for m in s.errors())
    # an error leaves the instance in the Error state: no more steps
    assert s.status_of(s.fmu.doStep, 0.0, 1e-3) == FMI_ERROR
    assert any("illegal call sequence" in m for m in s.errors())


def test_error_state_recovers_by_restoring_a_state(front_dir):
    """After fmi2Error a state saved before brings the instance back to Step Mode; the run then
    equals a run without the error."""
    clean = Slave(front_dir)
    for _ in range(40):
        clean.step()
    s = Slave(front_dir)
    for _ in range(20):
        s.step()
    saved = s.fmu.getFMUstate()
    assert s.status_of(s.fmu.setReal, [s.vr["bit_velocity"]], [1.0]) == FMI_ERROR
    assert s.status_of(s.fmu.doStep, s.t, 1e-3) == FMI_ERROR
    s.fmu.setFMUstate(saved)
    for _ in range(20):
        s.step()
    names = [s.vr["bit_position"], s.vr["hammer_velocity"], s.vr["spring_force"]]
    assert s.fmu.getReal(names) == clean.fmu.getReal(names)
    s.fmu.freeFMUstate(saved)
    for inst in (s, clean):
        inst.fmu.terminate()
        inst.fmu.freeInstance()


def test_terminated_status_and_calls_after_terminate(front_dir):
    s = Slave(front_dir)
    s.step()
    assert s.fmu.getBooleanStatus(fmi2Terminated) is False
    # a refused step (negative step size: an error, as in the Reference-FMUs): nothing changes;
    # the FMU goes on from a saved state, not terminated
    saved = s.fmu.getFMUstate()
    assert s.status_of(s.fmu.doStep, s.t, -1.0) == FMI_ERROR
    s.fmu.setFMUstate(saved)
    assert s.fmu.getBooleanStatus(fmi2Terminated) is False
    s.fmu.freeFMUstate(saved)
    s.step()
    s.fmu.terminate()
    assert s.fmu.getBooleanStatus(fmi2Terminated) is True
    assert s.status_of(s.fmu.doStep, s.t, 1e-3) == FMI_ERROR
    assert any("fmi2DoStep: illegal call sequence" in m for m in s.errors())
    assert s.fmu.getReal([s.vr["bit_position"]])[0] >= 0.0     # outputs stay readable
    # fmi2Reset leaves the Error state: a new run from Instantiated
    s.fmu.reset()
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    s.fmu.exitInitializationMode()
    s.t = 0.0
    s.step()
    assert s.fmu.getBooleanStatus(fmi2Terminated) is False
    s.fmu.terminate()
    s.fmu.freeInstance()


def test_serialized_state_round_trip_and_corrupt_bytes(front_dir):
    s = Slave(front_dir)
    for _ in range(50):
        s.step()
    state = s.fmu.getFMUstate()
    data = s.fmu.serializeFMUstate(state)
    t0 = s.t
    for _ in range(50):
        s.step()
    after = s.fmu.getReal([s.vr["bit_position"], s.vr["hammer_velocity"]])
    restored = s.fmu.deSerializeFMUstate(data)
    s.fmu.setFMUstate(restored)
    s.t = t0
    for _ in range(50):
        s.step()
    assert s.fmu.getReal([s.vr["bit_position"], s.vr["hammer_velocity"]]) == after
    # a state handed back to fmi2GetFMUstate is overwritten with the current one
    s.fmu.fmi2GetFMUstate(s.fmu.component, ctypes.byref(state))
    s.step()
    s.fmu.setFMUstate(state)
    s.t -= 1e-3
    s.step()
    again = s.fmu.getReal([s.vr["bit_position"], s.vr["hammer_velocity"]])
    s.fmu.setFMUstate(state)
    s.t -= 1e-3
    s.step()
    assert s.fmu.getReal([s.vr["bit_position"], s.vr["hammer_velocity"]]) == again
    s.fmu.freeFMUstate(state)
    s.fmu.freeFMUstate(restored)
    bad = bytearray(data)
    bad[10] ^= 0xFF                                   # inside the GUID of the header
    assert s.status_of(s.fmu.deSerializeFMUstate, bytes(bad)) == FMI_ERROR
    assert any("not a serialized state of this FMU" in m for m in s.errors())


def test_real_fmu_bad_parameter_fails_initialisation(front_dir):
    spec = read_spec((front_dir / "modelDescription.xml").read_bytes())
    if spec.status_vr is None:
        pytest.skip("this build's slave has no last_status variable (the stub test covers the mapping)")
    s = Slave(front_dir, setup=False)
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    s.fmu.setReal([s.vr["hammer_mass"]], [-1.0])
    assert s.status_of(s.fmu.exitInitializationMode) == FMI_ERROR
    assert any("hammer_mass" in m for m in s.errors())


# ---------------------------------------------------------------------------
# the status protocol, through a stub slave with last_status
# ---------------------------------------------------------------------------
STUB_SOURCE = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status


class StatusStub(Fmi2Slave):
    """x < 0: the step is discarded; x > 1e6: the step is an error; x == 42: the step raises
    (pythonfmu: fmi2Fatal); fail_init: init fails; every good step logs an OK message."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.fail_init = 0
        self.x = 0.0
        self.y = 0.0
        self.last_status = 0
        self.register_variable(Integer("fail_init", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed))
        self.register_variable(Real("x", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output))
        self.register_variable(Integer("last_status", causality=Fmi2Causality.local,
                                       variability=Fmi2Variability.discrete))

    def exit_initialization_mode(self):
        self.last_status = 3 if self.fail_init else 0
        if self.fail_init:
            self.log("fail_init = 1: initialisation refused", Fmi2Status.error)

    def do_step(self, t, h):
        if self.x < 0:
            self.last_status = 2
            self.log("x < 0: step discarded", Fmi2Status.error)
            return False
        if self.x > 1e6:
            self.last_status = 3
            self.log("x > 1e6: step failed", Fmi2Status.error)
            return False
        if self.x == 42:
            raise RuntimeError("the stub raises")
        self.last_status = 0
        self.y += self.x * h
        self.log("stepped")
        return True
'''


@pytest.fixture(scope="module")
def stub_dir(tmp_path_factory):
    _compiler_or_skip()
    from hammerbit.fmu.build import pythonfmu_builder
    FmuBuilder = pythonfmu_builder()       # the installed pythonfmu, not an FMU's copy
    src = tmp_path_factory.mktemp("stub_src")
    script = src / "hb_status_stub.py"
    script.write_text(STUB_SOURCE)
    fmu = FmuBuilder.build_FMU(script, dest=src)
    sys.modules.pop("hb_status_stub", None)
    return add_front(Path(fmu), tmp_path_factory.mktemp("stub"))


def _stub(stub_dir, *, fail_init=0):
    s = Slave(stub_dir, setup=False)
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    s.fmu.setInteger([s.vr["fail_init"]], [fail_init])
    return s


def test_stub_exit_initialisation_error_is_returned(stub_dir):
    assert read_spec((stub_dir / "modelDescription.xml").read_bytes()).status_vr is not None
    s = _stub(stub_dir, fail_init=1)
    assert s.status_of(s.fmu.exitInitializationMode) == FMI_ERROR
    assert any("initialisation refused" in m for m in s.errors())
    assert s.status_of(s.fmu.doStep, 0.0, 0.1) == FMI_ERROR       # Error state: no steps


def test_stub_discard_and_error_from_do_step(stub_dir):
    s = _stub(stub_dir)
    s.fmu.exitInitializationMode()
    s.fmu.setReal([s.vr["x"]], [1.0])
    s.step(0.5)
    s.fmu.setReal([s.vr["x"]], [-1.0])
    assert s.status_of(s.fmu.doStep, s.t, 0.5) == FMI_DISCARD
    assert s.fmu.getBooleanStatus(fmi2Terminated) is False
    assert s.fmu.getRealStatus(fmi2LastSuccessfulTime) == 0.5
    s.fmu.setReal([s.vr["x"]], [2.0])                 # after a Discard the master may go on
    s.step(0.5)
    assert s.fmu.getReal([s.vr["y"]]) == [0.5 + 1.0]
    assert s.fmu.getInteger([s.vr["last_status"]]) == [FMI_OK]
    s.fmu.setReal([s.vr["x"]], [1e7])
    assert s.status_of(s.fmu.doStep, s.t, 0.5) == FMI_ERROR
    assert s.fmu.getInteger([s.vr["last_status"]]) == [FMI_ERROR]
    assert s.status_of(s.fmu.terminate) == FMI_ERROR                # Error state
    assert s.fmu.getReal([s.vr["y"]]) == [1.5]                       # still readable


def test_stub_last_status_reports_errors_found_by_the_front(stub_dir):
    s = _stub(stub_dir)
    s.fmu.exitInitializationMode()
    s.step(0.5)
    assert s.fmu.getInteger([s.vr["last_status"]]) == [FMI_OK]
    assert s.status_of(s.fmu.getReal, [999]) == FMI_ERROR          # refused before the slave
    assert s.fmu.getInteger([s.vr["last_status"], s.vr["fail_init"]]) == [FMI_ERROR, 0]
    s.fmu.reset()                                                    # a new run starts clean
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    assert s.fmu.getInteger([s.vr["last_status"]]) == [FMI_OK]


def test_stub_ok_messages_follow_the_debug_logging_settings(stub_dir):
    s = _stub(stub_dir)                              # loggingOn = false
    s.fmu.exitInitializationMode()
    s.step(0.5)
    assert not any("stepped" in m for _, m in s.messages)
    s.fmu.setDebugLogging(True, [])
    s.step(0.5)
    assert sum("stepped" in m for _, m in s.messages) == 1
    s.fmu.setDebugLogging(True, ["logStatusError"])
    s.step(0.5)
    assert sum("stepped" in m for _, m in s.messages) == 1
    assert s.status_of(s.fmu.setDebugLogging, True, ["noSuchCategory"]) == FMI_ERROR
    assert any("unknown log category 'noSuchCategory'" in m for m in s.errors())


def test_stub_fatal_step_does_not_crash_the_host(stub_dir):
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(HERE)!r})
        from pathlib import Path
        from test_fmu_native import FMI_ERROR, _stub
        s = _stub(Path({str(stub_dir)!r}))
        s.fmu.exitInitializationMode()
        s.fmu.setReal([s.vr["x"]], [42.0])
        print("doStep", s.status_of(s.fmu.doStep, 0.0, 0.5))
        print("getReal", s.status_of(s.fmu.getReal, [s.vr["y"]]))
        s.fmu.freeInstance()                         # must not touch the released slave
        for _ in range(3):                           # the process goes on with new instances
            t = _stub(Path({str(stub_dir)!r}))
            t.fmu.exitInitializationMode()
            t.step(0.5)
            t.fmu.terminate()
            t.fmu.freeInstance()
        print("messages", " | ".join(m for _, m in s.messages))
        print("survived")
    """)
    # the debug allocator overwrites freed objects: a second release of the slave would crash
    env = dict(os.environ, PYTHONMALLOC="debug")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout
    assert "doStep 4" in out and "getReal 3" in out and "survived" in out, out
    assert "the stub raises" in out and "illegal call sequence" in out


# ---------------------------------------------------------------------------
# another native master: ecos (from the ecospy wheel)
# ---------------------------------------------------------------------------
def _ecos_or_skip(tmp: Path) -> tuple[Path, dict]:
    ecos, tbb = ecos_or_skip(tmp)
    return ecos, host_env(HAMMERBIT_PYTHON=sys.executable, LD_LIBRARY_PATH=f"{tbb}:{tmp}")


def test_ecos_runs_the_fmu_natively(any_fmu, plain_dir, tmp_path, request):
    """Each runtime flavour in ecos (a native C++ master): fmpy's positions on the plain
    pythonfmu FMU, to the 6 decimals of ecos's CSV."""
    if "pythonfmu" in request.node.callspec.id:
        _shared_libpython_or_skip()
    ecos, env = _ecos_or_skip(tmp_path)
    fmu = shutil.copy(any_fmu, tmp_path / f"{ID}.fmu")
    proc = subprocess.run([str(ecos), "simulate", "--path", str(fmu), "--stopTime", "0.5",
                           "--stepSize", "0.001", "--noParallel"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    rows = list(csv.reader((tmp_path / f"{ID}.csv").open(), skipinitialspace=True))
    col = next(i for i, h in enumerate(rows[0]) if h.endswith("::bit_position[REAL]"))
    ref = fmpy_positions(plain_dir, 500, 1e-3)
    checked = 0
    for row in rows[1:]:
        n = int(row[0])              # iterations done: the row holds the outputs at n * h
        if 1 <= n <= len(ref):
            assert float(row[col]) == pytest.approx(ref[n - 1], abs=1e-6)   # CSV keeps 6 decimals
            checked += 1
    assert checked >= 400 and ref[-1] > 1e-3

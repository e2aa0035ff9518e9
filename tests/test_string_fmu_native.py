"""The native Drillstring FMU: the Python flavour's step, bit for bit, without Python on the target.

The oracle is the Python (pythonfmu) flavour built from the same string: it runs
:mod:`hammerbit.model.string_step` under numba in the host, the native flavour
runs the same kernels compiled ahead of time behind the C front.  The lab
string covers both forms of the exact step: its fixed hook (and feed) steps in
the modal form, its auto-driller in the dense form.
"""
import json
import os
import re
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

from native_hosts import linux_host as build_linux_host, windows_host_or_skip  # noqa: E402

STRING = "lab"
H = 1e-3
STEPS = 300
#: the outputs compared, in the order the hosts print them
OUT = ("interface_force", "held_force", "held_force_change", "hook_load", "top_position", "top_velocity")
#: the top conditions as the FMU's parameters: (top_condition, feed_velocity [m/s])
TOPS = {"fixed": (0, 0.0), "feed": (1, 60.0 / 3600.0), "auto-driller": (2, 0.0)}
#: the hammer's motion about its rest position: a periodic parabola (amplitude [m], frequency [Hz])
AMP, FREQ = 5e-5, 25.0
REL = 1e-12


@pytest.fixture(scope="module")
def fmus(built_string_fmu, built_native_string_fmu):
    """The lab string's Drillstring.fmu in both flavours (the session's shared builds)."""
    return built_string_fmu, built_native_string_fmu


@pytest.fixture(scope="module")
def native_dir(fmus, tmp_path_factory):
    d = tmp_path_factory.mktemp("string_native_x")
    with zipfile.ZipFile(fmus[1]) as zf:
        zf.extractall(d)
    return d


def drive(t: float, rest: float) -> tuple:
    """The hammer's (position, velocity) at t, computed as the C host computes it."""
    u = FREQ * t
    s = u - float(int(u))
    return rest + 4.0 * AMP * s * (1.0 - s), 4.0 * AMP * FREQ * (1.0 - 2.0 * s)


def _instance(path, top, **reals):
    from hammerbit.fmu.host import FMUInstance
    kind, V = TOPS[top]
    fmu = FMUInstance(path, "string", reals={"feed_velocity": V, **reals}, init=False)
    fmu.fmu.setInteger([fmu.vr["top_condition"]], [kind])
    return fmu


def run(path, top, steps=STEPS) -> np.ndarray:
    """Outputs at every communication point of a run driven by :func:`drive`."""
    fmu = _instance(path, top)
    try:
        fmu.fmu.exitInitializationMode()
        rest = fmu.get("hammer_position_at_rest")[0]
        rows = [fmu.get(*OUT)]
        for i in range(steps):
            x, v = drive(i * H, rest)
            fmu.set(hammer_position=x, hammer_velocity=v)
            fmu.step(H)
            rows.append(fmu.get(*OUT))
    finally:
        fmu.close()
    return np.array(rows)


#: the top's motion is compared on the scale of the hammer motion driving it (it barely moves in 0.1 s)
FLOORS = {"top_position": AMP, "top_velocity": 4.0 * AMP * FREQ}


def assert_equal_runs(got, want, label):
    scale = np.max(np.abs(want), axis=0)
    for j, name in enumerate(OUT):
        err = np.max(np.abs(got[:, j] - want[:, j]))
        s = max(scale[j], FLOORS.get(name, 0.0), 1e-300)
        assert err <= REL * s, f"{label}: {name} differs by {err:.3g} (scale {s:.3g})"


@pytest.mark.parametrize("top", list(TOPS))
def test_native_string_fmu_equals_the_python_flavour_step_for_step(fmus, top):
    py, nat = fmus
    want, got = run(py, top), run(nat, top)
    assert np.ptp(want[:, 0]) > 10.0             # the hammer drives the string: tens of N
    if top != "fixed":
        assert np.ptp(want[:, 4]) > 1e-6         # the top moves
    assert_equal_runs(got, want, f"native vs pythonfmu ({top})")


@pytest.mark.slow
def test_field_string_native_equals_the_python_flavour(tmp_path):
    """The 2200 m field string (441 states, modal fixed hook, dense auto-driller): the same."""
    from hammerbit.fmu.build_string import build_string_fmu, string_build
    from hammerbit.fmu.native_string import build_native_string_fmu
    build = string_build("field-2200m")
    py = build_string_fmu("field-2200m", tmp_path / "py" / "Drillstring.fmu", build=build)
    nat = build_native_string_fmu("field-2200m", tmp_path / "nat" / "Drillstring.fmu", build=build,
                                  log=lambda m: None)
    for top in TOPS:
        want, got = run(py, top, steps=100), run(nat, top, steps=100)
        assert np.ptp(want[:, 0]) > 100.0
        assert_equal_runs(got, want, f"field-2200m native vs pythonfmu ({top})")


def _errors(fmu):
    return [m for s, m in fmu.messages if s >= 3]


@pytest.mark.parametrize("name,value,top", [("damping_ratio", 0.07, "fixed"),
                                            ("proportional_gain", 1e-3, "auto-driller"),
                                            ("integral_gain", 1e-3, "auto-driller")])
def test_a_parameter_that_changes_the_matrices_is_refused_naming_it(fmus, name, value, top):
    """The Python flavour takes it (its oracle: a rebuild); the native one refuses with fmi2Error."""
    from fmpy.fmi1 import FMICallException
    py, nat = fmus
    ok = _instance(py, top, **{name: value})
    ok.fmu.exitInitializationMode()
    ok.close()
    fmu = _instance(nat, top, **{name: value})
    with pytest.raises(FMICallException):
        fmu.fmu.exitInitializationMode()
    msgs = _errors(fmu)
    assert msgs and f"parameter '{name}' = {value!r}" in msgs[-1], msgs
    assert "build value" in msgs[-1] or "build gains" in msgs[-1], msgs


def test_gains_are_free_without_the_auto_driller(fmus):
    fmu = _instance(fmus[1], "fixed", proportional_gain=1e-3)
    fmu.fmu.exitInitializationMode()
    fmu.step(H)
    fmu.close()


def test_a_bad_parameter_gives_the_python_flavours_message(fmus):
    """The same message; the native flavour's status is fmi2Error (pythonfmu's exit of
    initialisation can only return OK: the Python flavour refuses the steps instead)."""
    from fmpy.fmi1 import FMICallException
    msgs = []
    for path in fmus:
        fmu = _instance(path, "fixed", wob=-1.0)
        if path == fmus[1]:
            with pytest.raises(FMICallException):
                fmu.fmu.exitInitializationMode()
        else:
            fmu.fmu.exitInitializationMode()
        msgs.append(_errors(fmu)[-1])
    assert "parameter 'wob' = -1.0 is out of range" in msgs[0]
    assert msgs[1] == msgs[0]


#: a step schedule a master may send: libcosim's clock after 4 s, a leftover, others (lengths [s])
ODD_STEPS = (1e-3, 0.0009999999999994458, 1e-13, 1e-3 - 1e-13, 1e-13, 2e-3, 3.7e-4, 1e-3 * (1 + 5e-10), 1e-3)


def run_schedule(path, top, schedule, repeats=20) -> np.ndarray:
    """Outputs after each step of ``schedule`` (repeated), the hammer driven by :func:`drive`."""
    fmu = _instance(path, top)
    try:
        fmu.fmu.exitInitializationMode()
        rest = fmu.get("hammer_position_at_rest")[0]
        rows = []
        for h in schedule * repeats:
            fmu.set(**dict(zip(("hammer_position", "hammer_velocity"), drive(fmu.t, rest))))
            fmu.step(h)
            rows.append(fmu.get(*OUT))
    finally:
        fmu.close()
    return np.array(rows)


@pytest.mark.parametrize("top", list(TOPS))
def test_any_step_length_is_taken_and_equals_the_python_flavour(fmus, top):
    """Steps the FMU was not built for (1e-13 s, libcosim's 0.0009999999999994458 s, 2 ms, 0.37
    ms): the modal form (fixed, feed) and the dense one (the lab's auto-driller) equal the Python
    flavour, which computes them with the same kernels, to 1e-12."""
    py, nat = fmus
    md = zipfile.ZipFile(nat).read("modelDescription.xml").decode()
    assert 'canHandleVariableCommunicationStepSize="true"' in md
    want, got = run_schedule(py, top, ODD_STEPS), run_schedule(nat, top, ODD_STEPS)
    assert np.ptp(want[:, 0]) > 10.0
    assert_equal_runs(got, want, f"native vs pythonfmu at odd steps ({top})")


def test_a_bad_input_is_an_error_naming_it_and_changes_nothing(fmus):
    from fmpy.fmi1 import FMICallException
    fmu = _instance(fmus[1], "auto-driller")
    try:
        fmu.fmu.exitInitializationMode()
        rest = fmu.get("hammer_position_at_rest")[0]
        for i in range(5):
            fmu.set(**dict(zip(("hammer_position", "hammer_velocity"), drive(i * H, rest))))
            fmu.step(H)
        before = fmu.get(*OUT)
        saved = fmu.fmu.getFMUstate()
        fmu.set(hammer_velocity=float("nan"))
        with pytest.raises(FMICallException):
            fmu.fmu.doStep(currentCommunicationPoint=fmu.t, communicationStepSize=H)
        assert "input 'hammer_velocity' = nan is out of range" in _errors(fmu)[-1]
        assert fmu.get(*OUT) == before
        fmu.fmu.setFMUstate(saved)              # the way out of the Error state
        fmu.set(hammer_velocity=0.0)
        fmu.step(H)
        assert fmu.get(*OUT) != before
    finally:
        fmu.close()


def test_state_rollback_and_serialisation_repeat_the_run_exactly(fmus):
    """What the Python flavour cannot do: get, serialize, restore; the rerun gives the same bits."""
    fmu = _instance(fmus[1], "auto-driller")
    try:
        fmu.fmu.exitInitializationMode()
        rest = fmu.get("hammer_position_at_rest")[0]

        def steps(i0, n):
            out = []
            for i in range(i0, i0 + n):
                fmu.set(**dict(zip(("hammer_position", "hammer_velocity"), drive(i * H, rest))))
                fmu.step(H)
                out.append(fmu.get(*OUT))
            return np.array(out)
        steps(0, 40)
        t_saved = fmu.t
        blob = fmu.fmu.serializeFMUstate(fmu.fmu.getFMUstate())
        first = steps(40, 40)
        state = fmu.fmu.deSerializeFMUstate(blob)
        fmu.fmu.setFMUstate(state)
        fmu.t = t_saved
        again = steps(40, 40)
        assert np.ptp(first[:, 0]) > 1.0
        assert np.array_equal(first, again)
        corrupt = bytearray(blob)
        corrupt[-8:] = np.array([np.nan]).tobytes()
        from fmpy.fmi1 import FMICallException
        with pytest.raises(FMICallException):
            fmu.fmu.deSerializeFMUstate(bytes(corrupt))
    finally:
        fmu.close()


# ---------------------------------------------------------------------------
# no Python on the target
# ---------------------------------------------------------------------------
def test_native_string_binaries_link_no_python(native_dir):
    so = native_dir / "binaries" / "linux64" / "Drillstring.so"
    ldd = subprocess.run(["ldd", str(so)], capture_output=True, text=True, check=True).stdout
    libs = {line.split()[0] for line in ldd.splitlines() if line.strip()}
    assert all(re.match(r"(linux-vdso|libm\.|libc\.|/lib.*ld-linux|libpthread\.)", lib) for lib in libs), libs
    dyn = subprocess.run(["nm", "-D", str(so)], capture_output=True, text=True, check=True).stdout
    defined = [ln.split()[-1] for ln in dyn.splitlines() if ln.split()[-2:-1] == ["T"]]
    assert defined and all(n.startswith("fmi2") for n in defined), defined
    for bad in ("python", "py_", "numba", "nrt_", "numpy"):
        assert bad not in dyn.lower(), bad
    md = (native_dir / "modelDescription.xml").read_text()
    assert "needsExecutionTool" not in md and 'canGetAndSetFMUstate="true"' in md


@pytest.fixture(scope="module")
def linux_host(tmp_path_factory):
    return build_linux_host(tmp_path_factory.mktemp("host"))


def _host_args(native_dir, top, binary, uri):
    from fmpy import read_model_description
    md = read_model_description(str(native_dir / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    # the start value in full (the model description's has 16 digits)
    rest = json.loads((native_dir / "resources" / "string_info.json").read_text())["hammer_position_at_rest"]
    return [binary, uri, md.guid, "out=" + ",".join(str(vr[n]) for n in OUT), f"steps={STEPS}", f"h={H!r}",
            f"int={vr['top_condition']}:{TOPS[top][0]}",
            f"drive={vr['hammer_position']}:{vr['hammer_velocity']}:{rest!r}:{AMP!r}:{FREQ!r}"]


def _values(proc):
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return np.array([float(ln.split()[1]) for ln in proc.stdout.splitlines() if ln.startswith("value ")])


@pytest.mark.parametrize("top", ["fixed", "auto-driller"])
def test_c_host_without_python_equals_the_python_flavour(fmus, native_dir, linux_host, top):
    """``env -i``: no PATH, no python3; the last outputs equal the pythonfmu run in fmpy."""
    so = str(native_dir / "binaries" / "linux64" / "Drillstring.so")
    proc = subprocess.run(["env", "-i", str(linux_host), *_host_args(native_dir, top, so,
                                                                     (native_dir / "resources").as_uri())],
                          capture_output=True, text=True, timeout=120)
    got = _values(proc)
    want = run(fmus[0], top)
    assert len(got) == len(OUT)
    assert_equal_runs(got[None, :], want[-1:], f"C host vs pythonfmu ({top})")


def test_windows_host_under_wine_equals_the_linux_run(native_dir, linux_host, tmp_path):
    import urllib.parse
    dll = native_dir / "binaries" / "win64" / "Drillstring.dll"
    wine, exe = windows_host_or_skip(dll, tmp_path)
    uri = "file:///Z:" + urllib.parse.quote((native_dir / "resources").as_posix())
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "WINEDEBUG": "-all",
           "WINEPREFIX": os.environ.get("WINEPREFIX", str(Path.home() / ".wine"))}
    win = _values(subprocess.run([wine, str(exe), *_host_args(native_dir, "auto-driller",
                                                               "Z:" + str(dll).replace("/", "\\"), uri)],
                                 capture_output=True, text=True, timeout=600, env=env))
    so = str(native_dir / "binaries" / "linux64" / "Drillstring.so")
    lin = _values(subprocess.run(["env", "-i", str(linux_host),
                                  *_host_args(native_dir, "auto-driller", so, (native_dir / "resources").as_uri())],
                                 capture_output=True, text=True, timeout=120))
    assert len(win) == len(lin) == len(OUT)
    assert np.all(np.abs(win - lin) <= 1e-13 * np.maximum(np.abs(lin), 1e-300)), (win, lin)

"""No crash at process exit with two pythonfmu FMUs in one Python process.

pythonfmu 0.7.0's binary releases its static ``std::shared_ptr<PyState>`` twice at exit (its
C++ static destructor, then its ``__attribute__((destructor))`` function).  With only
HammerBitRock's binary guarded, FMPy's ``simulate_ssp`` on the pythonfmu ``drilling.ssp`` (the
Drillstring's pythonfmu binary unguarded) ended in ``corrupted double-linked list`` (exit 134)
after printing its result in most runs.  Both FMUs are now guarded: by the native front's exit
handler (the FMUs as built) and by the slaves' Python exit hook
(:mod:`hammerbit.model.pythonfmu_exit`, pythonfmu's binaries alone).  Each run is a process of
its own; it must exit 0 after printing its result.
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("fmpy")

SSP_RUN = """
import sys
from fmpy.ssp.simulation import simulate_ssp
r = simulate_ssp(sys.argv[1], stop_time=0.05, step_size=1e-3)
print("result", r["hammer.bit_position"][-1], flush=True)
"""

#: a user's own loop over the two FMUs of the package: Jacobi, as docs/cosim.md wires them
USER_LOOP = """
import sys, zipfile, tempfile
from fmpy import read_model_description, extract
from fmpy.fmi2 import FMU2Slave
with zipfile.ZipFile(sys.argv[1]) as zf:
    d = tempfile.mkdtemp()
    zf.extractall(d)
fmus = {}
for name in ("HammerBitRock", "Drillstring"):
    path = f"{d}/resources/{name}.fmu"
    md = read_model_description(path)
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=name, instanceName=name)
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    fmus[name] = (s, {v.name: v.valueReference for v in md.modelVariables})
(h, hv), (g, gv) = fmus["HammerBitRock"], fmus["Drillstring"]
t = 0.0
for _ in range(50):
    x, v = h.getReal([hv["hammer_position"], hv["hammer_velocity"]])
    f, = g.getReal([gv["held_force_change"]])
    g.setReal([gv["hammer_position"], gv["hammer_velocity"]], [x, v])
    h.setReal([hv["harmonic_force"]], [f])
    h.doStep(t, 1e-3)
    g.doStep(t, 1e-3)
    t += 1e-3
print("result", h.getReal([hv["bit_position"]])[0], flush=True)
for s, _ in fmus.values():
    s.terminate()
    s.freeInstance()
"""


def _without_front(ssp: Path, out: Path) -> Path:
    """The package with each FMU's pythonfmu binary alone (no native front): the Python guard's case."""
    with zipfile.ZipFile(ssp) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename.endswith(".fmu"):
                inner = out.parent / Path(item.filename).name
                inner.write_bytes(data)
                plain = out.parent / ("plain_" + inner.name)
                with zipfile.ZipFile(inner) as fi, zipfile.ZipFile(plain, "w", zipfile.ZIP_DEFLATED) as fo:
                    names = fi.namelist()
                    for n in names:
                        if n.endswith("_python.so"):
                            fo.writestr(n.replace("_python.so", ".so"), fi.read(n))
                        elif not (n.startswith("binaries/linux64/") and n.replace(".so", "_python.so") in names):
                            fo.writestr(n, fi.read(n))
                data = plain.read_bytes()
            dst.writestr(item, data)
    return out


@pytest.fixture(scope="module")
def packages(built_ssp, tmp_path_factory):
    """``{"front": the package as built, "plain": its FMUs with pythonfmu's binaries alone}``."""
    return {"front": built_ssp,
            "plain": _without_front(built_ssp, tmp_path_factory.mktemp("plain") / "drilling.ssp")}


def _runs(code: str, ssp: Path, n: int) -> list:
    """The exit codes (and last output) of ``n`` processes running ``code`` on ``ssp``."""
    out = []
    for _ in range(n):
        proc = subprocess.run([sys.executable, "-c", code, str(ssp)], capture_output=True, text=True,
                              timeout=600)
        printed = any(line.startswith("result ") for line in proc.stdout.splitlines())
        out.append((proc.returncode, printed, proc.stderr[-300:]))
    return out


def _assert_clean(runs: list) -> None:
    crashes = [r for r in runs if r[0] != 0 or not r[1]]
    assert not crashes, f"{len(crashes)} of {len(runs)} runs crashed or printed no result: {crashes[:3]}"


@pytest.mark.parametrize("flavour", ["front", "plain"])
@pytest.mark.parametrize("code, n", [(SSP_RUN, 1), (USER_LOOP, 1)], ids=["simulate_ssp", "user_loop"])
def test_a_few_process_runs_exit_0(packages, flavour, code, n):
    _assert_clean(_runs(code, packages[flavour], n))


@pytest.mark.soak
@pytest.mark.slow
@pytest.mark.parametrize("flavour", ["front", "plain"])
def test_a_hundred_simulate_ssp_runs_exit_0(packages, flavour):
    _assert_clean(_runs(SSP_RUN, packages[flavour], 100))


@pytest.mark.soak
@pytest.mark.slow
def test_a_hundred_user_loops_exit_0(packages):
    _assert_clean(_runs(USER_LOOP, packages["plain"], 50) + _runs(USER_LOOP, packages["front"], 50))

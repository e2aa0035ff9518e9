"""Building HammerBitRock.fmu: the command, start values of a build, two builds in one process,
the shipped compiled kernels in a new process (cold start), the fallback when they cannot be used,
a plain wheel install, and fmpy's command line on a bad start value.
"""
from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("fmpy")

from cli_run import run_cli  # noqa: E402
from cold_env import cold_env  # noqa: E402
from hammerbit.fmu.build import build_fmu, build_hash, runtime_files  # noqa: E402
from hammerbit.fmu.host import FMUInstance  # noqa: E402
from hammerbit.model.params import RigParameters  # noqa: E402
from hammerbit.model.solver_options import SolverOptions  # noqa: E402
from hammerbit.model.stepping import Stepper

REPO = Path(__file__).resolve().parents[1]
RIG = RigParameters()


# ---------------------------------------------------------------------------
# the command
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("setting, words", [
    ("nonsense=1", ["'nonsense'", "not a parameter or input", "hammer_mass"]),
    ("hammer_mass=-1", ["hammer_mass", "-1.0", "[1e-06, 1e+09] kg"]),
    ("preload=1e12", ["preload", "1000000000000.0", "[-54000, 54000] N"]),
    ("mu_kinetic=0.9", ["mu_kinetic", "0.9"]),
])
@pytest.mark.parametrize("runtime", ["pythonfmu", "native"])
def test_build_command_refuses_bad_start_values(tmp_path, setting, words, runtime, capsys):
    """``hammerbit fmu build`` in this process (the console script's process boundary is tested in
    test_cli.py): exit 2, the name and value as typed, no traceback, no file; both flavours."""
    code, out, err = run_cli(["fmu", "build", "--runtime", runtime, "--out", str(tmp_path / "x.fmu"),
                              "--set", setting], capsys)
    assert code == 2, out + err
    assert all(w in err for w in words), err
    assert "Traceback" not in err
    assert not (tmp_path / "x.fmu").exists()


def test_build_hash_names_the_code(tmp_path):
    """Another runtime source (one byte) gives other module names; the same sources the same."""
    files = runtime_files()
    assert build_hash(files) == build_hash(list(reversed(files)))
    copies = []
    for f in files:
        shutil.copy2(f, tmp_path / f.name)
        copies.append(tmp_path / f.name)
    assert build_hash(copies) == build_hash(files)
    slave = tmp_path / "slave.py"
    slave.write_bytes(slave.read_bytes() + b"\n")
    assert build_hash(copies) != build_hash(files)


# ---------------------------------------------------------------------------
# two builds with different start values in one process
# ---------------------------------------------------------------------------
def _library_run(rig: RigParameters, t_end: float):
    st = Stepper(rig.to_groups(), solver=SolverOptions(rtol=1e-8, atol=1e-10))
    st.advance(t_end * rig.scales.omega)
    return st.y[2] * rig.scales.length, st.counts["slip_start"]


def test_two_builds_with_different_start_values_in_one_process(built_fmu, tmp_path):
    other = build_fmu(tmp_path / "heavy" / "HammerBitRock.fmu",
                      start_values={"hammer_mass": 30.0, "amplitude": 9.0, "preload": 25.0})
    rig_b = RIG.replace(hammer_mass=30.0, amplitude=9.0, preload=25.0)
    a = FMUInstance(built_fmu, "a")
    b = FMUInstance(other, "b")
    try:
        assert b.get("hammer_mass", "amplitude", "preload") == [30.0, 9.0, 25.0]
        assert a.get("hammer_mass", "amplitude", "preload") == [RIG.hammer_mass, RIG.amplitude, RIG.preload]
        assert float(b.var["hammer_mass"].start) == 30.0 and float(a.var["hammer_mass"].start) == RIG.hammer_mass
        for _ in range(1000):                      # interleaved
            a.step(3e-3)
            b.step(3e-3)
        xa, na = _library_run(RIG, a.t)
        xb, nb = _library_run(rig_b, b.t)
        assert a.get("bit_position")[0] == pytest.approx(xa, rel=1e-6)
        assert b.get("bit_position")[0] == pytest.approx(xb, rel=1e-6)
        assert a.get_int("slip_count")[0] == na and b.get_int("slip_count")[0] == nb
        assert abs(xa - xb) > 1e-3 * abs(xa)
        assert not a.errors() and not b.errors()
    finally:
        a.close()
        b.close()


# ---------------------------------------------------------------------------
# cold start: a new process, an empty cache directory, a read-only HOME
# ---------------------------------------------------------------------------
_COLD = textwrap.dedent("""
    import json, sys, time
    t0 = time.perf_counter()
    from hammerbit.fmu.host import FMUInstance
    inst = FMUInstance(sys.argv[1], "cold")
    t1 = time.perf_counter()
    inst.step(1e-3)
    pkg = [m for m in sys.modules if m.startswith("hammerbit_fmu_runtime_") and "." not in m][0]
    nc = sys.modules[pkg + ".numba_cache"]
    hits, misses = nc.kernel_cache_counts()
    print(json.dumps({"load_init_s": t1 - t0, "hits": hits, "misses": misses, "decision": nc.DECISION,
                      "messages": inst.messages}))
    inst.close()
""")


def _cold_probe(fmu, env):
    r = subprocess.run([sys.executable, "-c", _COLD, str(fmu)], capture_output=True, text=True,
                       env=env, timeout=1800)
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_cold_start_loads_the_shipped_kernels_with_a_read_only_home(built_fmu, tmp_path):
    env = cold_env(tmp_path)
    out = _cold_probe(built_fmu, env)
    assert out["decision"]["shipped"], out["decision"]
    assert out["misses"] == 0 and out["hits"] >= 3, out        # advance + two force formulas
    msgs = [m for s, m in out["messages"]]
    assert any("shipped in the FMU" in m and "nothing compiled" in m for m in msgs), msgs
    assert not any(s >= 1 for s, m in out["messages"]), out["messages"]
    # the load time is a goal of benchmarks/bench_fmu.py; here: nothing compiled (hits, misses above)
    assert not (tmp_path / "tmp" / f"hammerbit-{os.getuid()}").exists()     # nothing compiled anywhere


@pytest.mark.slow
def test_cold_start_fallback_compiles_once_says_so_and_uses_a_writable_directory(built_fmu, tmp_path):
    """Shipped kernels unusable (another CPU target asked for) and HOME read-only: the first process
    compiles into <tmp>/hammerbit-<uid>/numba and says so; the next process loads from there."""
    env = cold_env(tmp_path, NUMBA_CPU_NAME="x86-64", NUMBA_CPU_FEATURES="")
    first = _cold_probe(built_fmu, env)
    fallback = str(tmp_path / "tmp" / f"hammerbit-{os.getuid()}" / "numba")
    assert not first["decision"]["shipped"] and first["decision"]["dir"] == fallback
    warn = [m for s, m in first["messages"] if s == 1]
    assert warn and "compiled" in warn[0] and "NUMBA_CPU_NAME" in warn[0] and fallback in warn[0], warn
    assert "cannot be written" in warn[0]
    second = _cold_probe(built_fmu, env)
    assert second["misses"] == 0 and second["hits"] >= 3
    assert any("loaded from the cache" in m and fallback in m for s, m in second["messages"])


# ---------------------------------------------------------------------------
# a plain (non-editable) install
# ---------------------------------------------------------------------------
@pytest.mark.slow
def test_fmu_build_from_a_wheel_install(tmp_path):
    wheels = tmp_path / "wheels"
    try:                                   # the build backend from this Python, else pip fetches it
        import wheel  # noqa: F401
        isolation = ["--no-build-isolation"]
    except ImportError:
        isolation = []
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", *isolation, "-q",
                        "-w", str(wheels), str(REPO)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    wheel = next(wheels.glob("hammerbit-*.whl"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True,
                   timeout=300)
    py = venv / "bin" / "python"
    if sys.prefix != sys.base_prefix:
        # the tests run in a virtual environment, whose packages the new one's system site lacks:
        # its site directories as plain paths (their .pth files, such as an editable install's, unread)
        site_dir = subprocess.run([str(py), "-c", "import site; print(site.getsitepackages()[0])"],
                                  capture_output=True, text=True, check=True, timeout=60).stdout.strip()
        Path(site_dir, "_tests_parent_environment.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    r = subprocess.run([str(py), "-m", "pip", "install", "--no-deps", "-q", str(wheel)], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    where = subprocess.run([str(py), "-c", "import hammerbit; print(hammerbit.__file__)"],
                           capture_output=True, text=True, cwd=tmp_path).stdout.strip()
    assert where.startswith(str(venv)), where
    out = tmp_path / "out" / "HammerBitRock.fmu"
    t0 = time.perf_counter()
    r = subprocess.run([str(venv / "bin" / "hammerbit"), "fmu", "build", "--out", str(out)],
                       capture_output=True, text=True, timeout=1800, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert Path(r.stdout.strip()) == out and out.is_file(), (time.perf_counter() - t0, r.stdout)
    with zipfile.ZipFile(out) as zf:
        names = zf.namelist()
    assert f"resources/hammerbit_fmu_runtime_{build_hash()}/slave.py" in names
    r = subprocess.run([str(py), "-m", "fmpy", "simulate", str(out), "--stop-time", "1"],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr


# ---------------------------------------------------------------------------
# fmpy's command line
# ---------------------------------------------------------------------------
def test_fmpy_simulate_with_a_bad_start_value_fails_naming_it(built_fmu, tmp_path):
    probe = FMUInstance(built_fmu, "probe")
    has_front = probe.has_front
    probe.close()
    if not has_front:
        pytest.skip("needs the native front (hammerbit.fmu.native): pythonfmu alone returns OK from "
                    "fmi2ExitInitializationMode")
    r = subprocess.run([sys.executable, "-m", "fmpy", "simulate", str(built_fmu), "--start-values",
                        "hammer_mass", "-1", "--output-file", str(tmp_path / "out.csv")],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode != 0, r.stdout + r.stderr
    assert "hammer_mass" in r.stdout + r.stderr

"""The C timing host of the native-FMU benchmark (benchmarks/fmu_step_host.c) builds, loads the
native FMU and a pythonfmu FMU into one process, and drives them as the benchmark does: a few
steps here, their results checked against fmpy driving the same FMU (no timings)."""
from __future__ import annotations

import subprocess
import zipfile

import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from benchmarks import build_trivial_fmu
from benchmarks.c_step_host import HostUnavailable, build_step_host, hosted_fmu, run_step_host, \
    shared_libpython

H = 1e-3
STEPS, PAIRS = 5, 2
PRELOAD_FACTOR = 1.1          # the input differs from its start value, so the set reaches the model


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    try:
        return build_step_host(tmp_path_factory.mktemp("step_host"))
    except HostUnavailable as e:
        pytest.skip(str(e))


def _extract(fmu, dest):
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(dest)
    return dest


def _fmpy_output(fmu_dir, n_steps, input_name, value, output_name):
    """``output_name`` after ``n_steps`` steps of h with ``input_name`` = value before each: fmpy."""
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(fmu_dir),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="oracle")
    s.instantiate()
    try:
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        for k in range(n_steps):
            s.setReal([vr[input_name]], [value])
            s.doStep(k * H, H)
        out = s.getReal([vr[output_name]])[0]
        s.terminate()
    finally:
        s.freeInstance()
    return out


def test_host_steps_the_native_and_a_pythonfmu_fmu_like_fmpy(host, built_native_fmu, tmp_path):
    if shared_libpython() is None:
        pytest.skip("this Python has no shared libpython, which a pythonfmu FMU needs in a C host")
    native = _extract(built_native_fmu, tmp_path / "native")
    trivial = _extract(build_trivial_fmu(tmp_path / "floor"), tmp_path / "trivial")
    md = read_model_description(str(native / "modelDescription.xml"))
    preload = PRELOAD_FACTOR * float(next(v.start for v in md.modelVariables if v.name == "preload"))
    fmus = [hosted_fmu(native, "native", "preload", preload, "hammer_position"),
            hosted_fmu(trivial, "trivial", "u", 1.5, "u")]
    out = run_step_host(host, fmus, steps=STEPS, pairs=PAIRS, h=H, python=True)
    assert [f["name"] for f in out["fmus"]] == ["native", "trivial"]
    n_steps = out["warmup_steps"] + PAIRS * STEPS
    assert out["warmup_steps"] == STEPS                      # warm-up: one block, at most 2000 steps
    for f in out["fmus"]:
        assert f["steps"] == n_steps
        assert len(f["cpu_s"]) == len(f["wall_s"]) == PAIRS
    # the same binary, the same calls on the same time grid: the same bits
    assert out["fmus"][0]["output"] == _fmpy_output(native, n_steps, "preload", preload, "hammer_position")
    assert out["fmus"][0]["output"] != _fmpy_output(native, n_steps, "preload", preload / PRELOAD_FACTOR,
                                                    "hammer_position")
    assert out["fmus"][1]["output"] == 1.5                  # the input read back through pythonfmu


def test_host_refuses_bad_arguments_with_usage(host):
    r = subprocess.run([str(host), "0", "1", "1e-3", "--", "x"], capture_output=True, text=True)
    assert r.returncode == 1
    assert "STEPS and PAIRS must be >= 1" in r.stderr
    r = subprocess.run([str(host), "5", "1", "1e-3", "--", "only-a-name"], capture_output=True, text=True)
    assert r.returncode == 1 and "usage:" in r.stderr


def test_no_compiler_is_a_clear_skip_reason(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(HostUnavailable, match="no C compiler for the C timing host.*CC="):
        build_step_host(tmp_path)

"""The FMI 3.0 DrillingSystem.fmu (``hammerbit fmu build-system --fmi-version 3``).

Oracles: the FMI 3.0 schema fmpy ships and ``fmpy validate``; the FMI 2.0 DrillingSystem.fmu of
the same build (the same model layer behind the FMI 2.0 front: each communication point's
outputs must agree to 1e-12, relative to the output's range); ``objdump`` for the symbol
versions of the Linux binaries.
"""
from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description, simulate_fmu  # noqa: E402

STRING, TOP = "field-2200m", "auto-driller"
STOP, H = 2.0, 0.01
#: agreement of the FMI 3.0 and FMI 2.0 runs, relative to each output's largest magnitude
AGREE = 1e-12


@pytest.fixture(scope="module")
def system_fmus(built_field_system_fmu, built_field_system_fmu3):
    """field-2200m under the auto-driller (STOP, H) in FMI 2.0 and 3.0 (the session's shared builds)."""
    return built_field_system_fmu, built_field_system_fmu3


def test_system_fmi3_description_is_valid(system_fmus):
    from fmpy.validation import validate_fmu
    two, three = system_fmus
    assert validate_fmu(str(three)) == []
    etree = pytest.importorskip("lxml.etree")
    xsd = Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3ModelDescription.xsd"
    schema = etree.XMLSchema(etree.parse(str(xsd)))
    with zipfile.ZipFile(three) as zf:
        doc = etree.fromstring(zf.read("modelDescription.xml"))
        names = set(zf.namelist())
    assert schema.validate(doc), str(schema.error_log)
    assert "binaries/x86_64-linux/DrillingSystem.so" in names
    md3, md2 = read_model_description(str(three)), read_model_description(str(two))
    cs = md3.coSimulation
    assert md3.fmiVersion == "3.0" and md3.modelExchange is None
    # the solver's events stay inside the step: no early return, no Event Mode declared
    assert cs.canHandleVariableCommunicationStepSize and not cs.mightReturnEarlyFromDoStep and not cs.hasEventMode
    v2 = {v.name: v for v in md2.modelVariables}
    v3 = {v.name: v for v in md3.modelVariables}
    assert set(v3) - {"time"} == set(v2)
    for name, v in v2.items():
        assert (v3[name].valueReference, v3[name].causality, v3[name].unit) == \
            (v.valueReference, v.causality, v.unit), name
    assert v3["impact_count"].type == "UInt64" and v3["stick_slip"].type == "Int32"


def _outputs(fmu) -> list:
    return [v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"]


@pytest.mark.parametrize("early_return", [False, True])
def test_system_fmi3_run_equals_fmi2(system_fmus, early_return):
    """The FMI 3.0 front over the same model layer: the same outputs at every communication point;
    with early return allowed too (the FMU declares none, so the steps are the same)."""
    two, three = system_fmus
    outs = _outputs(two)
    r2 = simulate_fmu(str(two), stop_time=STOP, output_interval=H, output=outs)
    r3 = simulate_fmu(str(three), stop_time=STOP, output_interval=H, output=outs,
                      early_return_allowed=early_return)
    assert r2["bit_position"][-1] > 0.0 and r2["slip_count"][-1] > 0   # it drills: stick-slip
    assert np.array_equal(r2["time"], r3["time"])
    for n in outs:
        a, b = r2[n].astype(float), r3[n].astype(float)
        scale = max(float(np.abs(a).max()), 1e-300)
        assert float(np.abs(a - b).max()) <= AGREE * scale, n


def test_system_fmi3_linux_binaries_need_no_newer_glibc_than_2_17(system_fmus, tmp_path):
    """The glibc shim links into the FMI 3.0 binaries as into the FMI 2.0 one."""
    readers = {"x86_64-linux": shutil.which("objdump"), "aarch64-linux": shutil.which("aarch64-linux-gnu-objdump")}
    if readers["x86_64-linux"] is None:
        pytest.skip("no objdump")
    newest = {}
    with zipfile.ZipFile(system_fmus[1]) as zf:
        for plat, reader in readers.items():
            name = f"binaries/{plat}/DrillingSystem.so"
            if reader is None or name not in zf.namelist():
                continue
            zf.extract(name, tmp_path)
            out = subprocess.run([reader, "-T", str(tmp_path / name)], capture_output=True, text=True,
                                 check=True).stdout
            vers = {tuple(int(p) for p in v.split("_")[1].split(".")) for v in
                    (w.strip("()") for w in out.split()) if v.startswith("GLIBC_") and v[6:7].isdigit()}
            newest[plat] = max(vers)
    assert "x86_64-linux" in newest and all(v <= (2, 17) for v in newest.values()), newest


@pytest.mark.parametrize("version", [2, 3])
def test_system_reference_results_equal_its_run_in_fmpy(system_fmus, version):
    """The FMI-LS-REF results the build ships (the library's Stepper on the subsystem) against
    the FMU's default experiment in fmpy (tests/reference_check.py says how close and why)."""
    from reference_check import compare_with_fmpy, shipped
    fmu = system_fmus[version - 2]
    _, header, rows = shipped(fmu)
    assert header == ["time", "bit_position", "hammer_position", "hammer_velocity"]
    assert float(rows[-1][1]) > 0.0                                  # the reference drills
    compare_with_fmpy(fmu)


def test_build_system_refuses_an_unknown_fmi_version(capsys, tmp_path):
    from cli_run import run_cli
    code, _, err = run_cli(["fmu", "build-system", "--string", "lab", "--fmi-version", "4",
                            "--out", str(tmp_path / "x.fmu")], capsys)
    assert code == 2 and "Traceback" not in err and "--fmi-version" in err
    assert not (tmp_path / "x.fmu").exists()


def test_build_system_fmu_refuses_an_unknown_fmi_version_before_any_work(tmp_path):
    from hammerbit.fmu.build_system import build_system_fmu
    with pytest.raises(ValueError, match="fmi_version = 4 is out of range: allowed 2 or 3"):
        build_system_fmu(None, None, tmp_path / "x.fmu", fmi_version=4)
    assert not (tmp_path / "x.fmu").exists()


@pytest.mark.slow
def test_system_aarch64_under_qemu_equals_x86_64(system_fmus, tmp_path):
    """The aarch64-linux binary (cross-built, run by the plain C host under qemu-aarch64) against
    the x86_64-linux one: 1 s at 10 ms, the outputs to 1e-13 of their magnitude (the same
    C code and kernels, no fused multiply-add; only libm may round differently)."""
    from test_fmi3_platforms import QEMU_SYSROOT, _host, _run, _values
    from hammerbit.fmu.native import find_compiler
    from hammerbit.fmu.native_build import AARCH64_CC
    qemu = shutil.which("qemu-aarch64")
    d = tmp_path / "fmu"
    with zipfile.ZipFile(system_fmus[1]) as zf:
        zf.extractall(d)
    so = d / "binaries/aarch64-linux/DrillingSystem.so"
    if not (qemu and shutil.which(AARCH64_CC) and so.exists() and Path(QEMU_SYSROOT).is_dir()):
        pytest.skip(f"needs {AARCH64_CC}, qemu-aarch64 (Debian: qemu-user) and {QEMU_SYSROOT}")
    md = read_model_description(str(d / "modelDescription.xml"))
    names = ("bit_position", "hammer_position", "hammer_velocity", "mean_wob", "hook_load")
    vrs = ",".join(str(v.valueReference) for n in names for v in md.modelVariables if v.name == n)
    args = [str(d / "resources") + "/", md.guid, "100", "0.01", vrs, "early=1"]
    arm = _values(_run([qemu, "-L", QEMU_SYSROOT, str(_host(shutil.which(AARCH64_CC), tmp_path / "h_arm", "-ldl")),
                        str(so), *args]))
    x86 = _values(_run([str(_host(find_compiler(), tmp_path / "h_x86", "-ldl")),
                        str(d / "binaries/x86_64-linux/DrillingSystem.so"), *args]))
    assert len(arm) == len(x86) == len(names) and x86[0] > 0.0
    for name, a, b in zip(names, arm, x86):
        assert abs(a - b) <= 1e-13 * abs(b), (name, a, b)

"""drilling.ssp with both FMUs native (``hammerbit ssp build --runtime native``): the runners give
the pythonfmu package's run."""
import zipfile

import numpy as np
import pytest

from cli_run import run_cli

H = 1e-3
FAST_STOP = 0.2
#: the same FMU kernels stepped with the same inputs: equal to rounding
SAME_RUN_REL = 1e-9


@pytest.fixture(scope="module")
def native_ssp(built_native_ssp):
    """The package of ``conftest.built_ssp`` (field-2200m, 22.5 Hz, H = 1 ms), native flavour."""
    return built_native_ssp


def test_both_fmus_of_the_package_are_native(native_ssp, tmp_path):
    from fmpy import read_model_description
    tools = {}
    with zipfile.ZipFile(native_ssp) as z:
        for n in ("Drillstring", "HammerBitRock"):
            (tmp_path / f"{n}.fmu").write_bytes(z.read(f"resources/{n}.fmu"))
            tools[n] = read_model_description(str(tmp_path / f"{n}.fmu")).generationTool
    assert tools["Drillstring"].startswith("hammerbit fmu build-string --runtime native"), tools
    assert tools["HammerBitRock"].startswith("hammerbit fmu build --runtime native"), tools


@pytest.mark.parametrize("runner", ["libcosim", "fmpy"])
def test_runners_give_the_pythonfmu_packages_penetration(native_ssp, built_ssp, runner):
    from hammerbit.ssp.runners import run_fmpy, run_libcosim

    def go(path):
        return run_libcosim(path, FAST_STOP) if runner == "libcosim" else run_fmpy(path, FAST_STOP, H)
    nat, py = go(native_ssp), go(built_ssp)
    assert py.penetration_m > 1e-4                       # the bit moved: a run, not a rest state
    assert abs(nat.penetration_m - py.penetration_m) <= SAME_RUN_REL * py.penetration_m, (nat.penetration_m,
                                                                                          py.penetration_m)


def test_cosim_ssp_reads_the_native_package_as_the_pythonfmu_one(native_ssp, built_ssp):
    """``hammerbit cosim --ssp`` on the native package: its string arrays and the native hammer."""
    from hammerbit.ssp.run import cosimulate_ssp
    nat, py = (cosimulate_ssp(p, stop=FAST_STOP, step=H, adaptive=False, estimate=False)
               for p in (native_ssp, built_ssp))
    assert py.penetration_m > 1e-4
    assert abs(nat.penetration_m - py.penetration_m) <= SAME_RUN_REL * py.penetration_m


def test_cli_ssp_build_bad_runtime_exits_2(capsys, tmp_path):
    code, _out, err = run_cli(["ssp", "build", "--string", "lab", "--runtime", "cython", "--out",
                               str(tmp_path / "x.ssp")], capsys)
    assert code == 2 and "--runtime" in err and "Traceback" not in err


def _with_step(src, dst, step: float):
    """``src`` with libcosim's step annotation at ``step`` [s] (the FMUs take any step)."""
    import re
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.namelist():
            data = zin.read(item)
            if item == "SystemStructure.ssd":
                text = data.decode()
                new = re.sub(r'baseStepSize="[^"]*"', f'baseStepSize="{step!r}"', text)
                assert new != text
                data = new.encode()
            zout.writestr(item, data)
    return dst


def _past(native_ssp, stop):
    """libcosim to ``stop``: its clock sends h = 0.0009999999999994458 s after 4 s, which the native
    Drillstring takes (it refused it before, at t = 4.001 s)."""
    from hammerbit.ssp.runners import run_libcosim
    r = run_libcosim(native_ssp, stop)
    assert abs(r.data["time"][-1] - stop) < 1e-9, r.data["time"][-1]
    assert np.all(np.isfinite(r.data["bit_position"])) and r.penetration_m > 1e-4
    return r


def test_libcosim_runs_the_native_package_past_4_s(native_ssp):
    _past(native_ssp, 4.5)


@pytest.mark.slow
@pytest.mark.parametrize("step", [1e-3, 5e-4])
def test_libcosim_runs_the_native_package_60_s(native_ssp, tmp_path, step):
    path = native_ssp if step == H else _with_step(native_ssp, tmp_path / "drilling.ssp", step)
    r = _past(path, 60.0)
    assert np.allclose(np.diff(r.data["time"]), step, rtol=1e-6)

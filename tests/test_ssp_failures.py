"""A failed step stops every runner of ours at once, with the FMU's message: libcosim, FMPy's SSP
runner and the master of ``hammerbit cosim --ssp`` (its hammer FMU)."""
import io
import json
import re
import zipfile

import pytest

pytest.importorskip("fmpy")

#: the refusal the Drillstring FMU logs at every step when its WOB is out of range
REFUSAL = "parameter 'wob' = -1.0 is out of range"


def _with_bad_wob(src, dst):
    """``src`` with the string's WOB at -1 N: in the SSD (libcosim applies it) and as the FMU's
    own start value (FMPy's runner applies none), so every step of the string is refused."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.namelist():
            data = zin.read(item)
            if item == "SystemStructure.ssd":
                text = data.decode()
                bad = re.sub(r'(<ssv:Parameter name="wob">\s*<ssv:Real value=")[^"]*', r"\g<1>-1.0", text,
                             count=1)
                assert bad != text
                data = bad.encode()
            elif item == "resources/Drillstring.fmu":
                buf = io.BytesIO()
                with zipfile.ZipFile(io.BytesIO(data)) as fin, zipfile.ZipFile(buf, "w") as fout:
                    for name in fin.namelist():
                        raw = fin.read(name)
                        if name.endswith("string_info.json"):
                            info = json.loads(raw)
                            info["scalars"]["wob"] = -1.0
                            raw = json.dumps(info).encode()
                        fout.writestr(name, raw)
                data = buf.getvalue()
            zout.writestr(item, data)
    return dst


@pytest.fixture(scope="module")
def failing_ssp(built_ssp, tmp_path_factory):
    return _with_bad_wob(built_ssp, tmp_path_factory.mktemp("ssp_fail") / "failing.ssp")


def test_libcosim_stops_at_the_first_failed_step_with_the_fmus_message(failing_ssp, capfd):
    from hammerbit.ssp.runners import RunnerStepError, run_libcosim
    with pytest.raises(RunnerStepError) as info:
        run_libcosim(failing_ssp, 0.05)
    e = info.value
    assert e.time == 0.0 and e.runner == "libcosim"
    assert REFUSAL in str(e), str(e)
    out = capfd.readouterr().out                      # libcosim's log, passed on: one step's refusal
    assert out.count("fmi2DoStep refused") == 1, out


def test_fmpy_runner_stops_at_the_first_failed_step(failing_ssp):
    from hammerbit.ssp.runners import RunnerStepError, run_fmpy
    with pytest.raises(RunnerStepError) as info:
        run_fmpy(failing_ssp, 0.05, 1e-3)
    assert "fmi2DoStep" in str(info.value), str(info.value)


def test_cosim_master_stops_at_the_hammer_fmus_failed_step_with_its_message(built_ssp, tmp_path):
    """The master of ``hammerbit cosim --ssp`` steps the package's hammer FMU: a refused step (here
    at a time that is not the FMU's) raises at once with the FMU's own words."""
    from hammerbit.cosim.hammer_fmu import FMUHammer, FMUStepError
    from hammerbit.ssp.run import load_ssp
    system = load_ssp(built_ssp)
    try:
        c = system.config
        hammer = FMUHammer(system.hammer_fmu, c.rig, c.weight_on_bit, force_input="harmonic_force")
        hammer.step(0.0, 1e-3, c.weight_on_bit)
        with pytest.raises(FMUStepError, match="currentCommunicationPoint = 5 s is not the current time"):
            hammer.step(5.0, 1e-3, c.weight_on_bit)
    finally:
        system.close()

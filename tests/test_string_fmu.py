"""The Drillstring FMU: the library's string side, step for step, through fmpy."""
import math

import numpy as np
import pytest
import scipy.linalg as sla

from cli_run import run_cli

STOP, H = 0.2, 1e-3


@pytest.fixture(scope="module")
def string_fmu(tmp_path_factory):
    from hammerbit.fmu.build_string import build_string_fmu
    return build_string_fmu("field-2200m", tmp_path_factory.mktemp("string_fmu") / "Drillstring.fmu")


def _instance(path, *, integers=None, **reals):
    from hammerbit.fmu.host import FMUInstance
    fmu = FMUInstance(path, "string", reals=reals or None, init=False)
    if integers:
        fmu.fmu.setInteger([fmu.vr[k] for k in integers], list(integers.values()))
    fmu.fmu.exitInitializationMode()
    return fmu


#: the top conditions as the FMU's parameters: (top_condition, feed_velocity [m/s])
TOPS = {"fixed": (0, 0.0), "feed": (1, 60.0 / 3600.0), "auto-driller": (2, 0.0)}


@pytest.mark.parametrize("top", list(TOPS))
def test_string_fmu_equals_the_library_string_side_step_for_step(string_fmu, top):
    """The master's run (exchange='fmi', the same top condition) recorded; the FMU fed the same hammer
    motion gives the same interface force, held force and hook load at every communication point."""
    from hammerbit.cosim.config import CosimConfig
    from hammerbit.cosim.master import cosimulate
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    kind, V = TOPS[top]
    fmu = _instance(string_fmu, feed_velocity=V, integers={"top_condition": kind})
    kp, ki = fmu.get("proportional_gain", "integral_gain")     # the build's default tuning
    condition = {"fixed": TopCondition.fixed(), "feed": TopCondition.feed(V),
                 "auto-driller": TopCondition.auto_driller(kp, ki)}[top]
    cfg = CosimConfig(stop=STOP, step=H, exchange="fmi", estimate=False, top=condition,
                      record=("hammer_position", "hammer_velocity", "interface_force", "hammer_force",
                              "hook_load"))
    d = cosimulate(load_string("field-2200m"), cfg).data
    W = cfg.weight_on_bit
    assert np.ptp(d["interface_force"]) > 0.1 * W          # the hammer drives the string
    try:
        assert fmu.get("interface_force")[0] == d["interface_force"][0]
        worst = 0.0
        for n in range(len(d) - 1):
            fmu.set(hammer_position=d["hammer_position"][n], hammer_velocity=d["hammer_velocity"][n])
            fmu.step(H)
            F, held, hook = fmu.get("interface_force", "held_force", "hook_load")
            worst = max(worst, abs(F - d["interface_force"][n + 1]), abs(hook - d["hook_load"][n + 1]))
            if n + 2 < len(d):                                 # the force the hammer held next
                worst = max(worst, abs(held - d["hammer_force"][n + 2]))
        assert worst <= 1e-12 * W
        u_top, v_top = fmu.get("top_position", "top_velocity")
        if top == "feed":
            assert (u_top, v_top) == pytest.approx((V * STOP, V), rel=1e-12)
        elif top == "fixed":
            assert (u_top, v_top) == (0.0, 0.0)
        else:                     # the auto-driller lowers the block as the bit drills and unloads
            assert u_top > 0.0
    finally:
        fmu.close()


def test_one_step_of_any_length_is_the_closed_form(string_fmu, tmp_path):
    """A step of 12.3 ms with the hammer held still (extrapolation 0) against the matrix exponential
    of the string side's own matrices (dense, independent of the modal form the FMU steps with)."""
    import zipfile
    from hammerbit.model.string_model import INFO_FILE, MODEL_FILE, load_model
    with zipfile.ZipFile(string_fmu) as z:
        for name in (MODEL_FILE, INFO_FILE):
            z.extract(f"resources/{name}", tmp_path)
    arrays, info = load_model(str(tmp_path / "resources"))
    f = arrays["forms"]["fixed"]
    sc = info["scalars"]
    A1, E, frow, rows3 = f["A1"], f["E"], f["frow"], f["rows"]
    ki, W = sc["interface_stiffness"], sc["wob"]
    fmu = _instance(string_fmu, integers={"extrapolation": 0})
    try:
        x_rest = fmu.get("hammer_position")[0]
        fmu.set(hammer_position=0.0, hammer_velocity=0.0)   # connectors zeroed, as FMPy's runner does
        fmu.step(H)                                   # the first step: the hammer at rest
        assert fmu.get("interface_force")[0] == pytest.approx(W, rel=1e-14)
        dx, h = 1e-4, 0.0123
        fmu.set(hammer_position=x_rest + dx, hammer_velocity=0.0)
        fmu.step(h)
        F, hook = fmu.get("interface_force", "hook_load")
    finally:
        fmu.close()
    n = A1.shape[0]
    Z = np.zeros((n + 1, n + 1))
    Z[:n, :n] = A1
    Z[:n, n] = E[:, 0] * dx
    xi = sla.expm(Z * h)[:n, n]
    F_ref = W + frow @ xi - ki * dx
    assert abs(F - F_ref) <= 1e-8 * ki * dx
    assert abs(hook - (sc["hook_load"] + rows3[2] @ xi)) <= 1e-8 * ki * dx


def test_bad_parameter_and_bad_input_are_refused_naming_them(string_fmu):
    fmu = _instance(string_fmu, damping_ratio=1.5)
    try:
        assert any("damping_ratio" in m and "1.5" in m and "[0, 1)" in m for _s, m in fmu.messages)
        with pytest.raises(Exception):
            fmu.step(H)
    finally:
        fmu.close()
    fmu = _instance(string_fmu)
    try:
        fmu.step(H)
        before = fmu.get("interface_force", "held_force", "hook_load")
        fmu.set(hammer_position=math.nan)
        with pytest.raises(Exception):
            fmu.step(H)
        assert any("hammer_position" in m and "nan" in m for _s, m in fmu.messages)
        assert fmu.get("interface_force", "held_force", "hook_load") == before
    finally:
        fmu.close()


def test_cli_build_string_bad_string_exits_2_naming_it(capsys):
    code, _out, err = run_cli(["fmu", "build-string", "--string", "no-such-string"], capsys)
    assert code == 2
    assert "no-such-string" in err and "field-2200m" in err


def test_damping_ratio_parameter_equals_a_string_built_with_it(string_fmu):
    """The FMU at damping_ratio 0.05 (built at the file's 0.02) against the library's string side
    built from the file with 0.05: the same run to rounding."""
    from hammerbit.cosim.config import CosimConfig
    from hammerbit.cosim.master import cosimulate
    from hammerbit.drillstring import load_string
    zeta = 0.05
    string = load_string("field-2200m")
    assert string.modal_damping_ratio != zeta
    cfg = CosimConfig(stop=0.1, step=H, exchange="fmi", estimate=False,
                      record=("hammer_position", "hammer_velocity", "interface_force"))
    d = cosimulate(string.replace(modal_damping_ratio=zeta), cfg).data
    d0 = cosimulate(string, cfg).data
    W = cfg.weight_on_bit
    fmu = _instance(string_fmu, damping_ratio=zeta)
    try:
        worst = 0.0
        for n in range(len(d) - 1):
            fmu.set(hammer_position=d["hammer_position"][n], hammer_velocity=d["hammer_velocity"][n])
            fmu.step(H)
            worst = max(worst, abs(fmu.get("interface_force")[0] - d["interface_force"][n + 1]))
    finally:
        fmu.close()
    assert np.max(np.abs(d["interface_force"] - d0["interface_force"])) > 1e3 * 1e-9 * W   # it matters
    assert worst <= 1e-9 * W


def test_model_description_lists_the_geometry_and_the_parameters(string_fmu):
    from fmpy import read_model_description
    from hammerbit.drillstring import load_string
    string = load_string("field-2200m")
    md = read_model_description(str(string_fmu), validate=False)
    var = {v.name: v for v in md.modelVariables}
    length = sum(s.length for s in string.sections)
    assert float(var["string_length"].start) == pytest.approx(length, rel=1e-15)
    assert var["string_length"].variability == "constant"
    assert f"{length:g} m" in md.description and string.name in md.description
    for name in ("damping_ratio", "wob", "hammer_position_at_rest", "extrapolation"):
        assert var[name].causality == "parameter", name
    assert float(var["damping_ratio"].start) == string.modal_damping_ratio
    assert {v.variable.name for v in md.outputs} >= {"interface_force", "held_force", "held_force_change", "hook_load"}


@pytest.mark.parametrize("gain", ["proportional_gain", "integral_gain"])
def test_auto_driller_gain_parameter_equals_a_side_built_with_it(string_fmu, gain):
    """The auto-driller at three times the build's gain against the library's side with that gain."""
    from hammerbit.cosim.config import CosimConfig
    from hammerbit.cosim.master import cosimulate
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    probe = _instance(string_fmu)
    gains = dict(zip(("proportional_gain", "integral_gain"), probe.get("proportional_gain", "integral_gain")))
    probe.close()
    default = dict(gains)
    gains[gain] *= 3.0
    cfg = CosimConfig(stop=0.1, step=H, exchange="fmi", estimate=False,
                      top=TopCondition.auto_driller(gains["proportional_gain"], gains["integral_gain"]),
                      record=("hammer_position", "hammer_velocity", "interface_force", "hook_load"))
    string = load_string("field-2200m")
    d = cosimulate(string, cfg).data
    d0 = cosimulate(string, cfg.replace(top=TopCondition.auto_driller(default["proportional_gain"],
                                                                       default["integral_gain"]))).data
    W = cfg.weight_on_bit
    fmu = _instance(string_fmu, integers={"top_condition": 2}, **{gain: gains[gain]})
    try:
        worst = 0.0
        for n in range(len(d) - 1):
            fmu.set(hammer_position=d["hammer_position"][n], hammer_velocity=d["hammer_velocity"][n])
            fmu.step(H)
            F, hook = fmu.get("interface_force", "hook_load")
            worst = max(worst, abs(F - d["interface_force"][n + 1]), abs(hook - d["hook_load"][n + 1]))
    finally:
        fmu.close()
    tol = 1e-11 * W
    assert np.max(np.abs(d["hook_load"] - d0["hook_load"])) > 100 * tol     # the gain matters
    assert worst <= tol


@pytest.mark.parametrize("directory", ["deleted", "kept"])
def test_a_build_after_running_a_pythonfmu_fmu_in_this_process_carries_its_binaries(built_string_fmu, tmp_path,
                                                                                   directory):
    """A pythonfmu FMU run in a Python host imports the pythonfmu copy packed in its resources,
    which stays in ``sys.modules`` after the FMU is freed, and leaves its resources directory on
    ``sys.path``.  A build afterwards in the same process still writes pythonfmu's binaries (it
    would otherwise write an FMU without any): after ``fmpy.simulate_fmu`` (the directory deleted),
    and after a user's own loop that keeps its extraction directory (an import would find the
    copy there again)."""
    import subprocess
    import sys
    import zipfile
    run = {"deleted": f"fmpy.simulate_fmu({str(built_string_fmu)!r}, stop_time=0.01)\n",
           "kept": ("from fmpy import extract, read_model_description\n"
                    "from fmpy.fmi2 import FMU2Slave\n"
                    f"md = read_model_description({str(built_string_fmu)!r})\n"
                    f"d = extract({str(built_string_fmu)!r}, unzipdir={str(tmp_path / 'x')!r})\n"
                    "s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier='Drillstring', instanceName='x')\n"
                    "s.instantiate(); s.setupExperiment(startTime=0.0)\n"
                    "s.enterInitializationMode(); s.exitInitializationMode(); s.doStep(0.0, 1e-3)\n"
                    "s.terminate(); s.freeInstance()\n"
                    "assert any(p.startswith(str(d)) for p in sys.path), 'the FMU left no path entry'\n")}[directory]
    code = ("import sys, fmpy\n" + run +
            "assert 'resources' in sys.modules['pythonfmu'].__file__, 'the FMU did not shadow pythonfmu'\n"
            "from hammerbit.fmu.build_string import build_string_fmu\n"
            f"print(build_string_fmu('lab', {str(tmp_path / 'Drillstring.fmu')!r}))\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    with zipfile.ZipFile(tmp_path / "Drillstring.fmu") as zf:
        assert any(n.startswith("binaries/linux64/") and n.endswith(".so") for n in zf.namelist())

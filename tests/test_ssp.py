"""drilling.ssp: one package, three runners (libcosimpy, FMPy's SSP runner, hammerbit cosim --ssp)."""
import zipfile

import pytest

from cli_run import run_cli

H = 1e-3
FAST_STOP = 0.2
#: the drilling case of docs/cosim.md: the field hammer (A = 15 kN) at 22.5 Hz slips every cycle
DRILLING_HZ = 22.5
#: the runners and the master step the same FMUs with the same inputs: equal to rounding
SAME_RUN_REL = 1e-9


@pytest.fixture(scope="module")
def drilling_ssp(built_ssp):
    """The drilling case (``conftest.built_ssp``): 22.5 Hz, 2 s, H = 1 ms."""
    from hammerbit.ssp.document import read_ssd
    with zipfile.ZipFile(built_ssp) as z:
        sd = read_ssd(z.read("SystemStructure.ssd"))
    assert sd.component("hammer").parameters["frequency"] == DRILLING_HZ and sd.step_size == H
    return built_ssp


def _ours(path, stop, **kw):
    from hammerbit.ssp.run import cosimulate_ssp
    return cosimulate_ssp(path, stop=stop, step=H, adaptive=False, **kw)


def _same(a, b, scale):
    return abs(a - b) <= SAME_RUN_REL * scale


def test_ssd_round_trip_and_libcosim_annotation():
    from hammerbit.ssp.document import Component, Connection, SystemDescription, read_ssd, write_ssd
    sd = SystemDescription("s", [Component("a", "resources/a.fmu", {"x": ("output", "m")},
                                           {"p": 0.1 + 0.2, "n": 2, "b": False})],
                           [Connection("a", "x", "a", "x")], 0.0, 2.5, 1.25e-3)
    xml = write_ssd(sd)
    back = read_ssd(xml)
    assert back.component("a").parameters == {"p": 0.1 + 0.2, "n": 2, "b": False}
    assert (back.stop_time, back.step_size) == (2.5, 1.25e-3)
    assert b'type="com.opensimulationplatform"' in xml and b'baseStepSize="0.00125"' in xml


def test_package_holds_both_fmus_wired(drilling_ssp):
    from hammerbit.ssp.document import read_ssd
    with zipfile.ZipFile(drilling_ssp) as z:
        names = set(z.namelist())
        sd = read_ssd(z.read("SystemStructure.ssd"))
    assert {"SystemStructure.ssd", "resources/Drillstring.fmu", "resources/HammerBitRock.fmu"} <= names
    wires = {(c.start_element, c.start_connector, c.end_element, c.end_connector) for c in sd.connections}
    assert ("string", "held_force_change", "hammer", "harmonic_force") in wires
    hammer = sd.component("hammer").parameters
    assert hammer["preload"] == sd.component("string").parameters["wob"]
    assert hammer["initial_hammer_position"] == sd.component("string").parameters["hammer_position_at_rest"]


def test_libcosim_runs_the_package_as_hammerbit_does(drilling_ssp):
    from hammerbit.ssp.runners import run_libcosim
    lib = run_libcosim(drilling_ssp, FAST_STOP)
    ours = _ours(drilling_ssp, FAST_STOP, estimate=False)
    assert lib.data["time"][-1] == pytest.approx(FAST_STOP, abs=1e-12)
    assert ours.penetration_m > 1e-4                      # the bit moved: a run, not a rest state
    assert _same(lib.penetration_m, ours.penetration_m, ours.penetration_m)


def test_fmpy_runs_the_package_as_hammerbit_does(drilling_ssp):
    from hammerbit.ssp.runners import run_fmpy
    fm = run_fmpy(drilling_ssp, FAST_STOP, H)
    ours = _ours(drilling_ssp, FAST_STOP, estimate=False)
    assert _same(fm.penetration_m, ours.penetration_m, ours.penetration_m)


@pytest.mark.slow
@pytest.mark.parametrize("runner", ["libcosim", "fmpy"])
def test_two_seconds_equal_hammerbit_and_within_its_estimate_of_the_reference(drilling_ssp, runner):
    """2 s at H = 1 ms: the runner equals ``hammerbit cosim --ssp --step 0.001`` to 1e-9 and lies
    within that run's error estimate of the monolithic reference."""
    from hammerbit.ssp.run import monolithic_ssp
    from hammerbit.ssp.runners import run_fmpy, run_libcosim
    stop = 2.0
    res = run_libcosim(drilling_ssp, stop) if runner == "libcosim" else run_fmpy(drilling_ssp, stop, H)
    ours = _ours(drilling_ssp, stop)
    assert _same(res.penetration_m, ours.penetration_m, ours.penetration_m)
    ref = monolithic_ssp(drilling_ssp, stop=stop)
    assert abs(res.penetration_m - ref.penetration_m) <= ours.estimate.penetration_m


def test_cli_cosim_ssp_refuses_what_the_package_fixes(drilling_ssp, capsys):
    code, _out, err = run_cli(["cosim", "--ssp", str(drilling_ssp), "--wob", "3"], capsys)
    assert code == 2 and "--wob" in err and "3.0" in err
    code, _out, err = run_cli(["cosim", "--ssp", str(drilling_ssp), "--step", "-0.001"], capsys)
    assert code == 2 and "--step" in err and "-0.001" in err


def test_cli_ssp_build_bad_step_exits_2_naming_it(capsys, tmp_path):
    code, _out, err = run_cli(["ssp", "build", "--string", "field-2200m", "--step", "0", "--out",
                               str(tmp_path / "x.ssp")], capsys)
    assert code == 2 and "--step" in err and "0.0" in err and "(0, 2]" in err
    assert not (tmp_path / "x.ssp").exists()


def test_libcosim_runs_the_auto_driller_as_hammerbit_does(drilling_ssp, tmp_path):
    """The same package with the string's top set to the auto-driller in the SSD (libcosim applies
    the SSD's parameter values): libcosim and hammerbit cosim --ssp still agree, and the block moves."""
    from hammerbit.ssp.document import read_ssd, write_ssd
    from hammerbit.ssp.runners import run_libcosim
    auto = tmp_path / "auto.ssp"
    with zipfile.ZipFile(drilling_ssp) as z, zipfile.ZipFile(auto, "w") as out:
        sd = read_ssd(z.read("SystemStructure.ssd"))
        sd.component("string").parameters["top_condition"] = 2
        for name in z.namelist():
            out.writestr(name, write_ssd(sd) if name == "SystemStructure.ssd" else z.read(name))
    lib = run_libcosim(auto, FAST_STOP)
    ours = _ours(auto, FAST_STOP, estimate=False, record=("hook_load", "bit_position"))
    fixed = _ours(drilling_ssp, FAST_STOP, estimate=False, record=("hook_load", "bit_position"))
    assert ours.config.top.kind == "auto-driller"
    assert _same(lib.penetration_m, ours.penetration_m, ours.penetration_m)
    # the top acted: the hook load moved off the fixed hook's (0.25 N in 0.2 s; rounding is below 1e-4 N)
    assert abs(ours.data["hook_load"][-1] - fixed.data["hook_load"][-1]) > 0.05


def test_a_users_own_jacobi_loop_is_fmpys_runner_and_the_wrong_wiring_is_not(drilling_ssp):
    """``run_user_loop`` (the loop docs/cosim.md's step table is measured with) gives FMPy's
    penetration; ``interface_force - wob`` into ``harmonic_force`` does not."""
    from hammerbit.ssp.runners import run_fmpy, run_user_loop
    fm = run_fmpy(drilling_ssp, FAST_STOP, H)
    ours = run_user_loop(drilling_ssp, FAST_STOP, H)
    wrong = run_user_loop(drilling_ssp, FAST_STOP, H, wiring="interface_force - wob")
    assert fm.penetration_m > 1e-4
    assert _same(ours.penetration_m, fm.penetration_m, fm.penetration_m), (ours.penetration_m, fm.penetration_m)
    assert abs(wrong.penetration_m - fm.penetration_m) > 1e-3 * fm.penetration_m

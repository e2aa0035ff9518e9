"""Continuation of periodic orbits (hammerbit.continuation): branches, located bifurcations, the
period-doubled branch, and ``hammerbit continue``."""
import json
import subprocess
import sys

import numpy as np
import pytest

from cli_run import run_cli
from hammerbit.continuation import correct_orbit, orbit_from_simulation, period_map
from hammerbit.continuation.bifurcation import detect, switch_period_doubling
from hammerbit.continuation.continuation import follow_branch
from hammerbit.continuation.parameter import Parameter
from hammerbit.model.presets import preset
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper

ORACLE = SolverOptions(rtol=1e-12, atol=1e-12)


@pytest.fixture(scope="module")
def p1_branch():
    """The period-1 branch of paper-fig9 from a = 0.2 down to 0.16, through its period-doubling."""
    base = preset("paper-fig9").replace(a=0.2)
    n, s = orbit_from_simulation(base)
    orbit = correct_orbit(base, s, n)
    param = Parameter.on("a", base)
    branch = follow_branch(param, base, orbit, 0.16)
    return base, param, branch, detect(param, base, branch.points, 0)


def test_the_branch_reaches_the_end_of_its_range_through_points_that_are_orbits(p1_branch):
    base, param, branch, _ = p1_branch
    assert branch.period == 1 and not branch.stopped and not branch.ended
    assert branch.points[-1].value == pytest.approx(0.16, abs=1e-3)
    assert np.all(np.diff(branch.values) < 0)
    for p in branch.points[::4]:
        st = Stepper(p.orbit.groups, solver=ORACLE, y0=p.orbit.state, compile_helper=False)
        st.advance(p.orbit.groups.period)
        y = st.y[:4]
        back = np.array([y[0] - y[2], y[1], 0.0, y[3]])
        assert np.max(np.abs(back - p.orbit.state)) <= 1e-9 * max(1.0, p.orbit.max_multiplier)


def test_the_period_doubling_is_located_to_1e_6_by_the_multipliers(p1_branch):
    base, param, branch, bifs = p1_branch
    pd = [b for b in bifs if b.kind == "period-doubling"]
    assert len(pd) == 1
    a_pd = pd[0].value
    assert 0.16 < a_pd < 0.2
    # independent of the location: orbits corrected by Newton at a_pd -+ 1e-6 have their critical
    # multiplier on either side of -1 (stable above, unstable below)
    sides = []
    for a in (a_pd + 1e-6, a_pd - 1e-6):
        g = base.replace(a=a)
        orb = correct_orbit(g, pd[0].orbit.s, 1)
        sides.append(np.min(orb.multipliers.real))
    assert sides[0] > -1.0 > sides[1]


def test_the_switch_at_the_period_doubling_gives_a_period_2_orbit(p1_branch):
    base, param, branch, bifs = p1_branch
    pd = next(b for b in bifs if b.kind == "period-doubling")
    orb = switch_period_doubling(param, base, pd)
    assert orb is not None and orb.period == 2
    g = orb.groups
    once = period_map(g, orb.s, 1, jacobian=False).s_end
    assert np.max(np.abs(once - orb.s)) > 1e-6  # not the period-1 orbit counted twice
    twice = period_map(g, orb.s, 2, jacobian=False).s_end
    assert np.max(np.abs(twice - orb.s)) <= 1e-9 * max(1.0, orb.max_multiplier)
    assert abs(param.value(g) - pd.value) <= 2e-3


def test_a_parameter_given_by_its_si_name_moves_the_orbit_like_its_group():
    """f [Hz] is eta times the natural frequency: continuing in f and in eta are the same branch."""
    base = preset("paper-fig9").replace(a=0.2)
    param = Parameter.on("f", base)
    assert param.value(base) == pytest.approx(1.0 / base.period_s, rel=1e-12)
    g = param.at(base, 1.01 * param.value(base))
    assert g.eta == pytest.approx(1.01 * base.eta, rel=1e-12)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "hammerbit", "continue", *args], capture_output=True, text=True,
                          timeout=600)


@pytest.mark.parametrize("args, option", [
    (["--param", "nonsense", "--range", "0.2", "0.1"], "--param nonsense"),
    (["--param", "a", "--range", "0.2", "-1"], "--range -1"),
    (["--param", "a", "--range", "0.2", "0.2"], "--range 0.2 0.2"),
    (["--param", "a", "--range", "0.2", "0.1", "--seeds", "1"], "--seeds 1"),
    (["--param", "a", "--range", "0.2", "0.1", "--plot", "x.txt"], "--plot x.txt"),
])
def test_bad_input_exits_2_naming_the_option(args, option, capsys):
    code, out, err = run_cli(["continue", *args], capsys)
    assert code == 2, err
    assert option in err and "Traceback" not in err and out == ""


def test_bad_input_in_a_new_process_exits_2_without_a_traceback():
    """The console's process boundary: the exit code and the message reach the shell as they are."""
    r = _cli("--param", "nonsense", "--range", "0.2", "0.1")
    assert r.returncode == 2, r.stderr
    assert "--param nonsense" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow
def test_continue_json_has_the_issues_shape_and_its_states_restart_a_stepper(tmp_path):
    r = _cli("--preset", "paper-fig9", "--param", "a", "--range", "0.2", "0.19", "--seeds", "2", "--json",
             "--csv", str(tmp_path / "b.csv"), "--out", str(tmp_path / "b.nc"), "--plot", str(tmp_path / "b.png"))
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert set(d) >= {"branches", "bifurcations", "curves"}
    br = d["branches"][0]
    assert br["period"] == 1
    pt = br["points"][-1]
    assert set(pt) >= {"a", "state", "multipliers", "stable", "rop_x0_per_period"}
    g = preset("paper-fig9").replace(a=pt["a"])
    st = Stepper(g, solver=ORACLE, y0=pt["state"][:4], compile_helper=False)
    assert [int(st.istate[0]), int(st.istate[1])] == pt["state"][4:]
    st.advance(g.period)
    assert st.y[1] == pytest.approx(pt["state"][1], abs=1e-8)
    assert st.y[2] == pytest.approx(pt["rop_x0_per_period"], abs=1e-8)
    header = (tmp_path / "b.csv").read_text().splitlines()[0]
    assert header.startswith("a [1],") and "rop [m/h]" in header
    import xarray as xr
    with xr.open_dataset(tmp_path / "b.nc") as ds:
        n_points = sum(len(b["points"]) for b in d["branches"])
        assert ds.sizes["point"] == n_points and ds["rop"].attrs["units"] == "m/h"
        assert ds["a"].values[0] == pytest.approx(d["branches"][0]["points"][0]["a"])
    assert (tmp_path / "b.png").stat().st_size > 0


@pytest.mark.slow
def test_continue_exits_5_naming_the_value_where_no_orbit_settles():
    """The chaos preset: runs from rest settle to no period, and the command says where (exit 5)."""
    r = _cli("--preset", "chaos", "--param", "a", "--range", "0.1967", "0.1966", "--seeds", "2")
    assert r.returncode == 5, (r.returncode, r.stderr)
    assert "a = 0.1967" in r.stderr and "no period" in r.stderr and "Traceback" not in r.stderr


def test_the_period_doubling_followed_in_eta_stays_on_the_multiplier_minus_one(p1_branch):
    """Each point (a, eta) of the boundary: orbits corrected at a -+ 1e-6 there straddle the multiplier -1."""
    from hammerbit.continuation.boundary import follow_boundary
    base, param, branch, bifs = p1_branch
    pd = next(b for b in bifs if b.kind == "period-doubling")
    curve = follow_boundary(base, pd, "a", "eta", 0.98, 1.02, points=4)
    assert not curve.stopped
    etas = [w for _, w in curve.points]
    assert min(etas) == pytest.approx(0.98) and max(etas) == pytest.approx(1.02)
    for a, eta in curve.points[::2]:
        mins = [np.min(correct_orbit(base.replace(a=a + d, eta=eta), pd.orbit.s, 1).multipliers.real)
                for d in (1e-6, -1e-6)]
        assert mins[0] > -1.0 > mins[1], (a, eta, mins)


def test_map_overlay_refuses_a_file_without_curves_before_any_work(tmp_path, capsys):
    bad = tmp_path / "c.json"
    bad.write_text('{"branches": []}')
    code, _, err = run_cli(["map", "--axis", "a=0.1:0.2:3", "--axis", "eta=0.9:1.1:3", "--plot",
                            str(tmp_path / "m.png"), "--overlay", str(bad)], capsys)
    assert code == 2 and f"--overlay {bad}" in err and "curves" in err and "Traceback" not in err
    assert not (tmp_path / "m.png").exists()


def test_the_overlay_draws_the_curves_that_name_both_map_axes():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from hammerbit.continuation.output import draw_curves
    curves = [{"kind": "period-doubling", "points": [{"a": 0.17, "eta": 0.9}, {"a": 0.18, "eta": 1.0}]},
              {"kind": "fold", "points": [{"a": 0.1, "b": 0.5}, {"a": 0.2, "b": 0.6}]}]
    fig, ax = plt.subplots()
    assert draw_curves(ax, curves, "eta", "a") == 1
    (line,) = ax.get_lines()
    assert list(line.get_xdata()) == [0.9, 1.0] and list(line.get_ydata()) == [0.17, 0.18]
    plt.close(fig)

"""Studies over many scenes: executor, regime maps, optimizer, bifurcation, sweeps.

Oracles: ``simulate`` of the same scene (maps, bifurcation columns,
penetration sweeps), a grid evaluated here with ``simulate`` and
``params.regime`` (optimizer), the runaway condition integrated on both sides,
``cosimulate`` without a reused string side (sweep).
"""
from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cli_run import run_cli
from hammerbit.scene.analysis import detect_period
from hammerbit.model.presets import preset
from hammerbit.model.settings import apply_settings
from hammerbit.model.validation import ParameterError
from hammerbit.scene.simulate import Record, simulate
from hammerbit.studies.bifurcation import bifurcation, penetration_sweep
from hammerbit.studies.executor import ExecutorOptions, chunk_bounds, chunk_plan
from hammerbit.studies.map import Axis, map_to_json, regime_map
from hammerbit.studies.optimize import Bound, OptimizeConfig, optimize

IN_PROCESS = ExecutorOptions(workers=1)


# ---------------------------------------------------------------------------
# executor
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("n,cost,target", [(1, 1.0, 0.1), (10, 0.01, 0.1), (7, 0.05, 0.1), (100, 1e-4, 0.2)])
def test_chunk_bounds_cover_items_once(n, cost, target):
    b = chunk_bounds(n, cost, target)
    assert b[0][0] == 0 and b[-1][1] == n
    assert all(a1 == b0 for (_, a1), (b0, _) in zip(b[:-1], b[1:]))
    sizes = [hi - lo for lo, hi in b]
    assert min(sizes) >= 1
    # every chunk but the last carries at least the target work
    assert all(s * cost >= target - 1e-12 for s in sizes[:-1])


@pytest.mark.parametrize("n,cost,target,workers", [(1, 1.0, 0.1, 2), (961, 6e-3, 0.2, 2), (961, 6e-3, 0.2, 16),
                                                    (10, 1e-4, 0.2, 4), (5000, 1e-3, 0.1, 3), (31, 1.0, 0.2, 2)])
def test_chunk_plan_covers_items_once_largest_first(n, cost, target, workers):
    plan = chunk_plan(n, cost, target, workers)
    assert np.array_equal(np.sort(np.concatenate(plan)), np.arange(n))
    sizes = [len(c) for c in plan]
    assert sizes == sorted(sizes, reverse=True)
    least = max(1, math.ceil(target / cost))
    # every chunk but the last carries at least the target work, none more than n / (2 workers)
    assert all(s >= least for s in sizes[:-1])
    assert all(s <= max(least, math.ceil(n / (2 * workers))) for s in sizes)
    # spread out: a chunk of a grid holds items from all over it, not one contiguous run
    if cost >= target:                  # nothing to amortise: one item per task
        assert sizes == [1] * n
    big = plan[0]
    if len(big) >= 20:
        assert big.max() - big.min() > 0.8 * n and np.max(np.diff(big)) < n / 4


def test_scheduler_from_the_environment(monkeypatch):
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:8786")
    o = ExecutorOptions(workers=1)
    assert o.address == "tcp://127.0.0.1:8786" and not o.in_process
    assert ExecutorOptions(scheduler="tcp://h:1").address == "tcp://h:1"


def test_executor_options_validate():
    with pytest.raises(ParameterError, match="workers"):
        ExecutorOptions(workers=0)
    assert ExecutorOptions(workers=1).in_process
    assert not ExecutorOptions(workers=1, dask=True).in_process
    assert not ExecutorOptions(workers=1, scheduler="tcp://127.0.0.1:1").in_process


# ---------------------------------------------------------------------------
# maps
# ---------------------------------------------------------------------------
def _small_axes():
    return [Axis.parse("a=0.04:0.09:3"), Axis.parse("eta=0.8:1.0:2")]


def test_axis_parse_and_errors():
    ax = Axis.parse("a=0.05:0.25:5")
    assert ax.values == tuple(np.linspace(0.05, 0.25, 5)) and ax.unit == "1"
    assert Axis.parse("f=1:2:3").unit == "Hz"
    assert Axis.parse("A=4").values == (4.0,)
    with pytest.raises(ParameterError, match="nosuch"):
        Axis.parse("nosuch=0:1:3")
    with pytest.raises(ParameterError, match="LO:HI:N"):
        Axis.parse("a=0:1:x")


def test_map_cells_equal_simulate_bit_for_bit():
    """paper-fig12 (impact device): every cell's figures from simulate of the same scene."""
    g = preset("paper-fig12")
    periods = 40
    ds = regime_map(g, _small_axes(), periods=periods, options=IN_PROCESS)
    half = periods // 2
    for i, a in enumerate(ds["a"].values):
        for j, eta in enumerate(ds["eta"].values):
            s = apply_settings(g, {"a": float(a), "eta": float(eta)})
            r = simulate(s, periods, record=Record(poincare=True, events=True))
            x3 = r.poincare["bit_position"]
            rop = (x3[periods] - x3[half]) / (periods - half)
            assert ds["rop_x0_per_period"].values[i, j] == rop         # bit for bit
            assert ds["rop_m_per_h"].values[i, j] == s.rop(rop)["m_per_h"]
            n = detect_period(r.poincare)
            assert (math.isnan(ds["period"].values[i, j]) if n is None else ds["period"].values[i, j] == n)
            late = r.events[r.events["time"] >= half * s.period]
            imp = np.count_nonzero(late["kind"] == "impact")
            assert ds["impacts_per_period"].values[i, j] == imp / (periods - half)
            seps = late[late["kind"] == "separation"]
            peak = seps["peak_contact_force"].max() if len(seps) else 0.0
            if r.events["kind"][-1] != "impact":            # no contact still open at the end
                assert ds["peak_contact_force_steady_n"].values[i, j] == peak * s.scales.friction_force
            # the whole-run peak: every contact's, start-up included; the same figure as simulate's
            all_seps = r.events[r.events["kind"] == "separation"]["peak_contact_force"]
            assert ds["peak_contact_force_n"].values[i, j] >= (all_seps.max() if len(all_seps) else 0.0) \
                * s.scales.friction_force
            assert ds["peak_contact_force_n"].values[i, j] == r.peak_contact_force_n()
            f = r.flags
            assert [ds[k].values[i, j] for k in ("runaway", "bounce", "tension", "transient")] == \
                [int(f.runaway), int(f.bounce), int(f.tension), int(f.transient)]
            assert ds["min_drive_f0"].values[i, j] == f.min_drive
            assert ds["valid"].values[i, j] == int(not (f.runaway or f.bounce))
            # the paper's rules written out here (not the map's own regime())
            floor = s.mu if s.gamma_hat > 0.0 else 1.0
            assert [ds[k].values[i, j] for k in ("domain_a_ge_b", "domain_a_plus_b_gt_1", "domain_b_gt_mu")] \
                == [int(s.a >= s.b), int(s.a + s.b > 1.0), int(s.b > floor)]
    assert np.nansum(ds["impacts_per_period"].values) > 0        # the case has impacts


@settings(max_examples=300, deadline=None)
@given(n_rows=st.integers(1, 140), period=st.integers(1, 40), scale=st.sampled_from([0.0, 1e-7, 1e-5, 1e-3]),
       seed=st.integers(0, 2**32 - 1), nan=st.booleans())
def test_cell_period_equals_detect_period(n_rows, period, scale, seed, nan):
    """The map's compiled period (scene flags) against analysis.detect_period: period-n rows with
    perturbations around the tolerance, short arrays, NaN."""
    from hammerbit.scene.flags import N_SETTLING, S_PERIOD, settling_rows
    from hammerbit.scene.analysis import relative_coordinates
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(period, 5)) * rng.choice([1e-3, 1.0, 1e3])
    rows = base[np.arange(n_rows) % period] + scale * rng.normal(size=(n_rows, 5))
    rows[:, 0] = np.arange(n_rows)
    if nan:
        rows[rng.integers(n_rows), rng.integers(1, 5)] = np.nan
    out = np.zeros(N_SETTLING)
    settling_rows(relative_coordinates(rows), 32, 1e-5, out)
    n = detect_period(rows)
    assert out[S_PERIOD] == (0 if n is None else n)


def test_map_si_axis_uses_cell_scales():
    """An SI axis (K) changes the scales of each cell: ROP in mm per period follows x0 = F0/K."""
    g = preset("paper-fig9").replace(a=0.2)
    ds = regime_map(g, [Axis.parse("K=2000:4000:2")], periods=30, options=IN_PROCESS)
    for k, K_ in enumerate(ds["K"].values):
        s = apply_settings(g, {"K": float(K_)})
        assert ds["rop_mm_per_period"].values[k] == pytest.approx(
            ds["rop_x0_per_period"].values[k] * s.scales.length * 1e3, rel=1e-15)
    assert ds["K"].attrs["units"] == "N/m"


def test_map_netcdf_round_trip(tmp_path):
    import xarray as xr
    ds = regime_map(preset("paper-fig9"), [Axis.parse("a=0.05:0.2:3")], periods=20, options=IN_PROCESS,
                    attrs={"preset": "paper-fig9"})
    path = tmp_path / "m.nc"
    ds.to_netcdf(path, engine="scipy")
    back = xr.open_dataset(path, engine="scipy").load()
    for v in ds.data_vars:
        np.testing.assert_array_equal(back[v].values, ds[v].values)
        assert back[v].attrs["units"] == ds[v].attrs["units"]
    np.testing.assert_array_equal(back["a"].values, ds["a"].values)
    assert back.attrs["preset"] == "paper-fig9" and json.loads(back.attrs["groups"])["b"] == 0.55


def test_map_json_nested_lists():
    ds = regime_map(preset("paper-fig9"), [Axis.parse("a=0.3:0.6:2"), Axis.parse("b=0.5:0.55:2")],
                    periods=10, options=IN_PROCESS)
    d = map_to_json(ds)
    assert [a["name"] for a in d["axes"]] == ["a", "b"]
    assert len(d["period"]) == 2 and len(d["period"][0]) == 2
    # a = 0.6 >= b and a + b > 1: outside the paper's domain; the flags come from the dynamics
    assert set(d["paper_domain_outside"][1][0]) == {"a >= b", "a + b > 1"}
    assert "rop" not in d and "rop_x0_per_period" in d and "min_drive_f0" in d
    for i in range(2):
        for j in range(2):
            assert d["flags"][i][j] == [f for f in ("runaway", "bounce", "tension", "stall", "transient")
                                        if int(ds[f].values[i, j])]
            # the verdict's integer is the sum of its bits (the codes of regime_codes, spelled out)
            bits = {"runaway": 1, "bounce": 2, "tension": 4, "stall": 8, "transient": 16}
            assert d["regime"][i][j] == sum(bits[f] for f in d["flags"][i][j])
            assert d["regime_bits"] == bits


#: The kinetic friction ratio the runaway tests are written for (the floor b crosses).
RUNAWAY_MU = 0.85


@pytest.mark.parametrize("field,base,setting,below,above", [
    ("domain_a_ge_b", {"b": 0.3}, "a", 0.3 - 1e-9, 0.3),                     # a >= b
    ("domain_a_plus_b_gt_1", {"b": 0.5}, "a", 0.5 - 1e-9, 0.5 + 1e-9),       # a + b > 1
    ("domain_b_gt_mu", {"a": 0.0}, "b", 0.85 - 1e-9, 0.85 + 1e-9),           # b > mu (gamma_hat > 0)
    ("domain_b_gt_mu", {"a": 0.0, "gamma_hat": 0.0}, "b", 1.0, 1.0 + 1e-9),  # b > 1 (no velocity weakening)
])
def test_map_paper_domain_on_both_sides(field, base, setting, below, above):
    g = preset("paper-fig9").replace(mu=RUNAWAY_MU).replace(**base)
    ds = regime_map(g, [Axis(setting, (below, above))], periods=4, options=IN_PROCESS)
    assert ds[field].values.tolist() == [0, 1]


def test_map_headline_and_best_cell_use_valid_cells_only():
    """A map whose fastest cells run away: the best valid cell is the fastest of the cells with no
    flag of the verdict at all (runaway, bounce, tension, stall, transient)."""
    from hammerbit.studies.map import best_valid_cell
    ds = regime_map(preset("paper-fig9").replace(a=0.1), [Axis.parse("b=0.6:0.95:8")], periods=60,
                    options=IN_PROCESS)
    rop = ds["rop_m_per_h"].values
    run = ds["runaway"].values == 1
    clean = np.all([ds[f].values == 0 for f in ("runaway", "bounce", "tension", "stall", "transient")], axis=0)
    assert run.any() and clean.any() and np.nanmax(rop[run]) > np.nanmax(rop[clean])
    best = best_valid_cell(ds)
    assert best["rop_m_per_h"] == np.nanmax(rop[clean])


def _window_drifts(b, *, gamma_hat=None):
    g = preset("paper-fig9").replace(a=0.1, b=b, mu=RUNAWAY_MU)
    if gamma_hat is not None:
        g = g.replace(gamma_hat=gamma_hat)
    x3 = simulate(g, 300, record=Record(poincare=True)).poincare["bit_position"]
    return np.diff(x3[::100])


@pytest.mark.parametrize("mu_floor,gamma_hat", [(0.85, None), (1.0, 0.0)])
def test_runaway_condition_dynamically(mu_floor, gamma_hat):
    """Just above the kinetic floor the drift per window grows without bound; just below it
    settles (bounded mean velocity)."""
    above = _window_drifts(mu_floor + 0.01, gamma_hat=gamma_hat)
    below = _window_drifts(mu_floor - 0.01, gamma_hat=gamma_hat)
    assert above[2] > above[1] + 0.5 * (above[1] - above[0]) and above[2] > 1.5 * above[0]
    assert below[2] <= below[1] * (1 + 1e-6) and below[2] < 0.2 * above[2]


def test_map_invalid_axis_range_fails_before_work():
    with pytest.raises(ParameterError, match="mu"):
        regime_map(preset("paper-fig9"), [Axis.parse("mu=0.5:1.5:3")], periods=10, options=IN_PROCESS)


# ---------------------------------------------------------------------------
# the same map on every executor
# ---------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_cluster():
    """A real scheduler and two ``dask worker`` processes on 127.0.0.1, ended after the test."""
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", addr,
                                           "--nthreads", "1", "--no-nanny", "--no-dashboard",
                                           "--host", "127.0.0.1"], env=env,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from dask.distributed import Client
        deadline = time.monotonic() + 120
        while True:
            try:
                with Client(addr, timeout="5s") as c:
                    c.wait_for_workers(2, timeout=max(1, deadline - time.monotonic()))
                break
            except (OSError, TimeoutError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        yield addr
    finally:
        for p in reversed(procs):        # workers first, then the scheduler
            p.terminate()
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


MAP_AXES = ("a=0.03:0.09:4", "eta=0.9:1.0:2")


def _map_on(options):
    return regime_map(preset("paper-fig12"), [Axis.parse(a) for a in MAP_AXES], options=options, periods=40)


def _assert_same_map(other, ref):
    for v in ref.data_vars:
        np.testing.assert_array_equal(other[v].values, ref[v].values, err_msg=v)


def test_map_identical_on_every_executor():
    """In process (one chunk, and one chunk per cell) and on 2 local workers: the same map.
    The other Dask clusters go through the same tasks (the two tests below)."""
    ref = _map_on(IN_PROCESS)
    fine = _map_on(ExecutorOptions(workers=1, chunk_seconds=1e-9))
    local = _map_on(ExecutorOptions(workers=2, chunk_seconds=1e-9))
    assert local.attrs["workers"] == 2
    for other in (fine, local):
        _assert_same_map(other, ref)


def test_map_identical_on_a_dask_scheduler(dask_cluster):
    """A scheduler with two ``dask worker`` processes (``--scheduler``): the same map."""
    remote = _map_on(ExecutorOptions(scheduler=dask_cluster, chunk_seconds=1e-3))
    assert remote.attrs["workers"] == 2
    _assert_same_map(remote, _map_on(IN_PROCESS))


def test_map_identical_on_a_one_worker_dask_cluster():
    """``dask=True`` with one worker: a local cluster of one process, the same map."""
    one = _map_on(ExecutorOptions(workers=1, dask=True, chunk_seconds=1e-9))
    assert one.attrs["workers"] == 1
    _assert_same_map(one, _map_on(IN_PROCESS))


def test_ctrl_c_in_a_map_on_local_workers_exits_130_and_leaves_no_processes(monkeypatch, capsys):
    """``hammerbit map --workers 2`` in this process, Ctrl-C after the first chunk came back (the
    main thread is then in the executor's wait for results, where a Ctrl-C lands): exit 130, no
    traceback, and every worker process the map started ends.  The signal itself, in a new
    process: ``test_cli_map_interrupted_leaves_no_processes`` (slow set)."""
    psutil = pytest.importorskip("psutil")
    from hammerbit.studies.executor import Executor
    me = psutil.Process()
    before = {p.pid for p in me.children(recursive=True)}

    class CtrlC:
        """The progress bar of the map: a KeyboardInterrupt at its first update."""
        done, workers = 0, []

        def update(self, n):
            CtrlC.done += n
            # the map's processes; multiprocessing's resource tracker and its fork server (a
            # child of this process; the workers it forks carry its command line) live as long as
            # this process, whichever test started them
            CtrlC.workers = [p for p in me.children(recursive=True) if p.pid not in before
                             and "resource_tracker" not in " ".join(p.cmdline())
                             and not ("forkserver import main" in " ".join(p.cmdline())
                                      and p.ppid() == me.pid)]
            raise KeyboardInterrupt

        def close(self):
            pass

    monkeypatch.setattr(Executor, "_progress", lambda self, total, label: CtrlC())
    cells = 20 * 12
    code, out, err = run_cli(["map", "--axis", "a=0.05:0.25:20", "--axis", "eta=0.6:1.4:12", "--periods", "300",
                              "--workers", "2"], capsys)
    assert code == 130 and "interrupted" in err and "Traceback" not in err, err
    assert 0 < CtrlC.done < cells                       # inside the run: cells still to come
    assert len(CtrlC.workers) >= 2
    gone, alive = psutil.wait_procs(CtrlC.workers, timeout=30)
    assert not alive, [p.cmdline() for p in alive]


def test_cli_map_interrupted_leaves_no_processes(tmp_path):
    """Ctrl-C during a map on 2 local workers: exit 130 and no worker process left behind."""
    psutil = pytest.importorskip("psutil")
    cmd = [sys.executable, "-m", "hammerbit", "map", "--axis", "a=0.05:0.25:60", "--axis",
           "eta=0.6:1.4:80", "--periods", "1000", "--workers", "2"]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    proc = psutil.Process(p.pid)

    def worker_cpu_s():
        """CPU time [s] of each worker process (the resource tracker and the fork server left out;
        the workers are forked by the fork server, so they carry its command line)."""
        out = []
        for k in proc.children(recursive=True):
            try:
                line = " ".join(k.cmdline())
                fork_server = "forkserver import main" in line and k.ppid() == proc.pid
                if "python" in k.name().lower() and "resource_tracker" not in line and not fork_server:
                    out.append(sum(k.cpu_times()[:2]))
            except psutil.Error:        # ended or not yet readable
                pass
        return out

    # Inside the run: both workers past their start-up (imports, kernel load, warm-up scene) and
    # into the cells.  Measured in CPU time, which a busy machine does not stretch as it does the
    # wall clock; the cells of the map take several times the margin above the start-up.
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and p.poll() is None:
        cpu = worker_cpu_s()
        if len(cpu) >= 2 and min(cpu) >= 1.2:
            break
        time.sleep(0.1)
    assert p.poll() is None, p.stderr.read()
    kids = proc.children(recursive=True)
    p.send_signal(signal.SIGINT)
    rc = p.wait(timeout=60)
    assert rc == 130
    gone, alive = psutil.wait_procs(kids, timeout=30)
    assert not alive, [k.cmdline() for k in alive]


# ---------------------------------------------------------------------------
# optimizer
# ---------------------------------------------------------------------------
def test_optimizer_known_optimum_on_the_threshold_not_the_papers_bounce_rule():
    """b = 0.4, amplitude free: the ROP grows with a and the drive never falls below -F_s while
    stuck for a <= 0.6, so the optimum is on a + b = 1, beyond the paper's static rule a < b."""
    g = preset("paper-fig9").replace(b=0.4)
    F0 = g.scales.friction_force
    res = optimize(g, OptimizeConfig(bounds=(Bound("A", 0.1 * F0, 0.6 * F0),), periods=60), options=IN_PROCESS)
    o = res.optimum
    assert o.feasible and o.margins["bounce"] >= 0 and o.margins["threshold"] >= 0
    assert o.groups.a == pytest.approx(0.6, abs=2e-3) and o.groups.a > o.groups.b
    # oracle: nothing on a fine scan without bounce beats it
    for a in np.linspace(0.1, 0.6, 12):
        r = simulate(g.replace(a=float(a)), 60, record=Record(poincare=True))
        x3 = r.poincare["bit_position"]
        assert r.counts["bounce"] == 0
        assert g.replace(a=float(a)).rop((x3[60] - x3[30]) / 30)["m_per_h"] <= o.rop_m_per_h * (1 + 1e-12)


def test_optimizer_beats_every_feasible_cell_of_a_21x21_grid():
    """lab preset over (frequency, amplitude): the optimum is at least every feasible cell
    of a 21 x 21 grid evaluated here with simulate (a + b <= 1, no bounce)."""
    g = preset("lab")
    rig = g.to_rig()
    F0 = g.scales.friction_force
    periods = 30
    bounds = (Bound("frequency", 0.8 * rig.frequency, 1.2 * rig.frequency), Bound("amplitude", 0.1 * F0, 0.6 * F0))
    res = optimize(g, OptimizeConfig(bounds=bounds, periods=periods, grid=21, max_evaluations=25, starts=1),
                   options=IN_PROCESS)
    best = -math.inf
    for f in np.linspace(bounds[0].lo, bounds[0].hi, 21):
        for A in np.linspace(bounds[1].lo, bounds[1].hi, 21):
            s = apply_settings(g, {"frequency": float(f), "amplitude": float(A)})
            if s.a + s.b > 1.0:             # lab: b = 0.55 < mu = 0.90, runaway cannot happen
                continue
            r = simulate(s, periods, record=Record(poincare=True))
            if r.counts["bounce"]:
                continue
            x3 = r.poincare["bit_position"]
            best = max(best, s.rop((x3[periods] - x3[periods // 2]) / (periods - periods // 2))["m_per_h"])
    assert res.optimum.rop_m_per_h >= best
    assert res.best_grid.rop_m_per_h == pytest.approx(best, rel=1e-12)
    periods_seen = {r.period for r in res.runners_up}
    assert res.optimum.period not in periods_seen and len(periods_seen) == len(res.runners_up)
    assert all(r.drilling and r.period is not None and r.rop_m_per_h > 0 for r in res.runners_up)


def test_optimizer_frequency_check_excludes_unsafe_frequencies():
    from hammerbit.drillstring import load_string
    from hammerbit.studies.optimize import frequency_windows
    g = preset("lab")
    string = load_string("lab")
    rig = g.to_rig()
    lo, hi = 0.5 * rig.frequency, 2.0 * rig.frequency
    wins = frequency_windows(string, lo, hi, 0.15)
    F0 = g.scales.friction_force
    res = optimize(g, OptimizeConfig(bounds=(Bound("frequency", lo, hi), Bound("amplitude", 0.1 * F0, 0.5 * F0)),
                                     periods=20, grid=7, starts=0), string=string, options=IN_PROCESS)
    f = res.optimum.groups.to_rig().frequency
    assert any(a <= f <= b for a, b in wins)
    assert res.optimum.margins["frequency"] >= 0


# ---------------------------------------------------------------------------
# bifurcation and penetration sweep
# ---------------------------------------------------------------------------
def test_bifurcation_column_equals_simulate_poincare():
    g = preset("paper-fig9")
    res = bifurcation(g, "a", [0.083, 0.2], periods=80, keep=16, options=IN_PROCESS)
    for i, a in enumerate(res.values):
        p = simulate(g.replace(a=float(a)), 80, record=Record(poincare=True)).poincare
        tail = np.column_stack([p[n] for n in p.dtype.names])[-16:]
        np.testing.assert_array_equal(res.points[i], tail)


def test_bifurcation_period_n_of_paper_fig9():
    """P5, P3, P2, P1 at a = 0.069, 0.083, 0.11, 0.2 (Fig. 9)."""
    res = bifurcation(preset("paper-fig9"), "a", [0.069, 0.083, 0.11, 0.2], periods=300, keep=64,
                      options=IN_PROCESS)
    assert res.periods == [5, 3, 2, 1]


def test_bifurcation_over_an_si_parameter():
    g = preset("paper-fig9")
    F0 = g.scales.friction_force
    by_si = bifurcation(g, "A", [0.2 * F0], periods=40, keep=8, options=IN_PROCESS)
    by_group = bifurcation(g, "a", [0.2], periods=40, keep=8, options=IN_PROCESS)
    np.testing.assert_allclose(by_si.points, by_group.points, rtol=1e-9, atol=1e-12)


def test_penetration_sweep_equals_simulate():
    g = preset("paper-fig9")
    vals = [0.02, 0.1, 0.2]
    pen = penetration_sweep(g, vals, periods=50, options=IN_PROCESS)
    assert pen.tolist() == [simulate(g.replace(a=v), 50).penetration for v in vals]
    assert pen[0] == 0.0 and pen[2] > pen[1] > 0.0      # a + b < 1 stays stuck; larger a drills more


# ---------------------------------------------------------------------------
# sweep
# ---------------------------------------------------------------------------
def test_sweep_reuses_the_string_side_and_detects_steady_state():
    from hammerbit.cosim.config import CosimConfig, field_hammer
    from hammerbit.cosim.master import cosimulate
    from hammerbit.drillstring import load_string
    from hammerbit.studies.sweep import steady_figures, sweep
    string = load_string("field-2200m")
    cfg = CosimConfig(stop=0.5, step=1e-3, rig=field_hammer().replace(amplitude=2e3), f_max=60.0)
    res = sweep(string, [22.0, 23.0], cfg, window_periods=4, steady_tol=0.02, max_duration=2.0,
                options=IN_PROCESS)
    for row in res:
        f, dur = float(row["frequency_hz"]), float(row["duration_s"])
        c = cfg.replace(rig=cfg.rig.replace(frequency=f), stop=dur, record=("wob", "bit_position"), progress=False)
        r = cosimulate(string, c)                      # a fresh string side: the oracle
        fig = steady_figures(r.data, f, 4, cfg.rig.scales.friction_force)
        assert row["wob_amplitude_n"] == fig["wob_amplitude_n"]
        assert row["penetration_m"] == r.penetration_m
        assert (fig["amplitude_change"] <= 0.02) == bool(row["steady"]) or dur == 2.0
    assert np.all(res["duration_s"] >= 0.5) and np.all(res["duration_s"] <= 2.0)


# ---------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------
def test_cli_map_json_and_files(tmp_path, capsys):
    from hammerbit.cli.main import main
    out, png = tmp_path / "m.nc", tmp_path / "m.png"
    rc = main(["map", "--preset", "paper-fig9", "--axis", "a=0.05:0.25:4", "--axis", "eta=0.8:1.2:3",
               "--periods", "20", "--workers", "1", "--out", str(out), "--plot", str(png), "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert [len(d["period"]), len(d["period"][0])] == [4, 3]
    assert {"axes", "rop_x0_per_period", "flags", "rop_m_per_h", "rop_mm_per_period", "best_valid_cell"} <= set(d)
    assert out.exists() and png.exists()


@pytest.mark.parametrize("argv,needle", [
    (["map", "--axis", "nosuch=0:1:3", "--workers", "1"], "nosuch"),
    (["map", "--axis", "a=0:1", "--workers", "1"], "LO:HI:N"),
    (["map", "--workers", "1"], "--axis"),
    (["map", "--axis", "a=0.1:0.2:2", "--workers", "0"], "--workers"),
    (["optimize", "--bounds", "frequency=2:1", "--workers", "1"], "frequency"),
])
def test_cli_bad_input_exit_2(argv, needle, capsys):
    from hammerbit.cli.main import main
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_cli_optimize_lab_json(capsys):
    from hammerbit.cli.main import main
    rc = main(["optimize", "--preset", "lab", "--string", "lab", "--grid", "5", "--periods", "20",
               "--workers", "1", "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    o = d["optimum"]
    assert o["feasible"] and o["rop_m_per_h"] >= d["best_grid_cell"]["rop_m_per_h"]
    assert set(o["margins"]) == {"bounce", "threshold", "runaway", "frequency", "contact_force"}
    assert o["margins"]["frequency"]["ok"] is True


def test_cli_bifurcation(tmp_path, capsys):
    from hammerbit.cli.main import main
    rc = main(["bifurcation", "--range", "0.069", "0.2", "--num", "2", "--periods", "60", "--workers", "1",
               "--out", str(tmp_path / "b.png"), "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert len(d["period_n"]) == 2 and (tmp_path / "b.png").exists()


def test_frequency_windows_are_the_robust_passes():
    """Windows that pass at the nominal damping only do not count for the optimizer."""
    from hammerbit.drillstring import load_string
    from hammerbit.check.frequency import CheckConfig, check
    from hammerbit.studies.optimize import frequency_windows
    string = load_string("field-2200m")
    wins = frequency_windows(string, 10.0, 40.0, 0.15)
    res = check(string, CheckConfig(excitation_hz=25.0, margin=0.15, frequency_range_hz=(10.0, 40.0)))
    nominal_only = [w for w in res.windows if not w.robust]
    assert nominal_only                                   # the case has some
    for w in nominal_only:
        mid = 0.5 * (w.lo_hz + w.hi_hz)
        assert not any(a <= mid <= b for a, b in wins)
    for w in res.windows:
        if w.robust:
            mid = 0.5 * (w.lo_hz + w.hi_hz)
            assert any(a <= mid <= b for a, b in wins)

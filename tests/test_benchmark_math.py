"""The arithmetic behind the README's headline ratios, on small synthetic data.

``pareto_front``, ``time_at_error`` and ``ratio_stats`` (work–precision
analysis of ``benchmarks/bench_solvers.py``) and the README table rendering
(``benchmarks/readme_table.py``).  Every expected value below is computed by
hand in the comments, not by the code under test.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from benchmarks import fmt_ratio, fmt_time
from benchmarks.bench_solvers import NOMINAL_ERROR, pareto_front, ratio_stats, time_at_error
from benchmarks.readme_table import END, START, load_results, render_table, update_readme


# --------------------------------------------------------------------------- pareto_front
def test_pareto_front_drops_dominated_and_invalid_points():
    #        a      b      c      d      e(nan) f(err 0) g      h(same time as a, worse)  i
    err = [1e-3, 1e-5, 1e-4, 1e-6, math.nan, 0.0, 1e-4, 1e-2, 1.5e-5]
    t = [1.0, 3.0, 2.0, 10.0, 0.5, 0.5, 5.0, 1.0, 4.0]
    fe, ft = pareto_front(err, t)
    # by time: a(1, 1e-3) c(2, 1e-4) b(3, 1e-5) [i(4, 1.5e-5) dominated by b, only just]
    # [g(5, 1e-4) dominated by c] d(10, 1e-6); h ties a in time with a larger error;
    # e and f are not valid errors
    assert fe.tolist() == [1e-3, 1e-4, 1e-5, 1e-6]
    assert ft.tolist() == [1.0, 2.0, 3.0, 10.0]


def test_pareto_front_of_nothing_valid_is_empty():
    fe, ft = pareto_front([math.nan, -1.0], [1.0, math.inf])
    assert fe.size == 0 and ft.size == 0


# --------------------------------------------------------------------------- time_at_error
FRONT = (np.array([1e-3, 1e-4, 1e-5, 1e-6]), np.array([1.0, 2.0, 3.0, 10.0]))


@pytest.mark.parametrize("e, expected", [
    (1e-3, 1.0),                     # a front point
    (1e-6, 10.0),                    # the other end
    (10 ** -3.5, math.sqrt(2.0)),    # halfway in log between (1e-3, 1) and (1e-4, 2): sqrt(1 * 2)
    (10 ** -5.5, math.sqrt(30.0)),   # halfway between (1e-5, 3) and (1e-6, 10)
    (10 ** -4.25, 2.0 ** 0.75 * 3.0 ** 0.25),  # a quarter of the way from (1e-4, 2) to (1e-5, 3)
])
def test_time_at_error_interpolates_in_log_log(e, expected):
    assert time_at_error(FRONT, e) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("e", [1e-2, 1e-7])
def test_time_at_error_outside_the_front_is_nan(e):
    assert math.isnan(time_at_error(FRONT, e))


def test_time_at_error_single_point_and_empty():
    assert time_at_error((np.array([1e-4]), np.array([7.0])), 1e-4) == 7.0
    assert math.isnan(time_at_error((np.array([1e-4]), np.array([7.0])), 1e-5))
    assert math.isnan(time_at_error((np.array([]), np.array([])), 1e-4))


# --------------------------------------------------------------------------- ratio_stats
# ours: t = 1 at 1e-4, t = 10 at 1e-8  -> t_ours(e) = (e / 1e-4)^(-1/4)
# peer: t = 100 at 1e-4, 1e4 at 1e-8   -> t_peer(e) = 100 (e / 1e-4)^(-1/2)
# ratio(e) = 100 (e / 1e-4)^(-1/4): 100 at 1e-4, 1000 at 1e-8, log-linear in between
OURS = (np.array([1e-4, 1e-8]), np.array([1.0, 10.0]))
PEER = (np.array([1e-4, 1e-8]), np.array([100.0, 1e4]))


def test_ratio_stats_on_power_law_fronts():
    s = ratio_stats(OURS, PEER, floor=1e-10)
    # grid: 4 points per decade from 1e-8 to 1e-4 -> 17 points
    assert len(s["grid"]) == 17
    assert s["grid"][0] == pytest.approx(1e-8) and s["grid"][-1] == pytest.approx(1e-4)
    expected = [100.0 * (e / 1e-4) ** -0.25 for e in s["grid"]]
    assert s["ratios"] == pytest.approx(expected, rel=1e-12)
    assert s["min"] == pytest.approx(100.0, rel=1e-12)
    assert s["max"] == pytest.approx(1000.0, rel=1e-12)
    # log10 ratio runs linearly 2 .. 3 on an even grid: geometric mean 10^2.5
    assert s["geomean"] == pytest.approx(10 ** 2.5, rel=1e-12)
    assert NOMINAL_ERROR == 1e-8
    assert s["at_nominal"] == pytest.approx(1000.0, rel=1e-12)
    assert s["ours_time_at_nominal"] == pytest.approx(10.0, rel=1e-12)
    assert s["peer_time_at_nominal"] == pytest.approx(1e4, rel=1e-12)
    assert s["error_range"] == pytest.approx([1e-8, 1e-4])


def test_ratio_stats_floor_cuts_the_grid():
    # the grid starts at 10 * floor = 1e-5: 1e-5 .. 1e-4 is 5 points, ratios 100 .. 100 * 10^0.25
    s = ratio_stats(OURS, PEER, floor=1e-6)
    assert len(s["grid"]) == 5
    assert s["min"] == pytest.approx(100.0, rel=1e-12)
    assert s["max"] == pytest.approx(100.0 * 10 ** 0.25, rel=1e-12)
    # the nominal ratio does not depend on the floor
    assert s["at_nominal"] == pytest.approx(1000.0, rel=1e-12)


def test_ratio_stats_without_overlap_or_with_an_empty_front():
    ours = (np.array([1e-4, 1e-6]), np.array([1.0, 2.0]))
    peer = (np.array([1e-7, 1e-9]), np.array([1.0, 2.0]))
    s = ratio_stats(ours, peer, floor=1e-12)
    assert s["grid"] == [] and s["ratios"] == []
    assert s["min"] is None and s["geomean"] is None and s["max"] is None
    assert s["at_nominal"] is None            # 1e-8 lies on neither front
    empty = ratio_stats((np.array([]), np.array([])), PEER, floor=1e-12)
    assert empty["ratios"] == [] and empty["at_nominal"] is None


# --------------------------------------------------------------------------- formatting
@pytest.mark.parametrize("s, text", [(5e-6, "5 µs"), (0.0123, "12.3 ms"), (2.5, "2.5 s"),
                                     (None, "n/a"), (math.nan, "n/a")])
def test_fmt_time(s, text):
    assert fmt_time(s) == text


@pytest.mark.parametrize("r, text", [(3.14159, "3.14x"), (312.4, "312x"), (None, "n/a"),
                                     (math.inf, "n/a")])
def test_fmt_ratio(r, text):
    assert fmt_ratio(r) == text


# --------------------------------------------------------------------------- README table
def _result(name, rows, quick=False):
    return {"benchmark": name, "quick": quick, "summary": rows,
            "machine": {"timestamp": "2026-01-02T03:04:05", "cpu_count": 2, "cpu_model": "TestCPU",
                        "load_average": 1.5, "python": "3.x", "numpy": "1", "numba": "2", "scipy": "3"}}


def test_render_table_rows_cells_and_provenance():
    rows = [
        {"metric": "time at 1e-8 | no impact", "ours": "1.2 ms", "peer": "310 ms", "ratio": "258x",
         "goal": ">= 100x", "met": True, "command": "python -m benchmarks --only solvers"},
        {"metric": "start", "ours": 0.123456, "peer": None, "ratio": "", "goal": None, "met": False,
         "command": ""},
        "not a row",
    ]
    text = render_table([_result("solvers", rows), _result("fmu", [{"metric": "m"}], quick=True)])
    lines = text.splitlines()
    assert lines[0] == "| Benchmark | Metric | Ours | Peer | Ratio | Goal | Met | Command |"
    assert lines[1] == "|---|---|---|---|---|---|---|---|"
    # the pipe in the metric is escaped; the goal met shows a tick
    assert lines[2] == ("| solvers | time at 1e-8 \\| no impact | 1.2 ms | 310 ms | 258x | >= 100x | ✅ | "
                        "`python -m benchmarks --only solvers` |")
    # floats to 3 significant digits, missing cells as a dash, a goal missed as a cross
    assert lines[3] == "| solvers | start | 0.123 | – | – | – | ❌ | – |"
    # a non-dict row is skipped; a quick run is tagged
    assert lines[4] == "| fmu (quick) | m | – | – | – | – | – | – |"
    assert "- `solvers`: 2026-01-02T03:04:05, 2 CPUs (TestCPU), load 1.5" in text
    assert "- `fmu`:" in text and text.count("**quick run**") == 1


def test_render_table_without_results_says_so():
    text = render_table([])
    assert "no results yet" in text.splitlines()[2]
    assert "Measured on" not in text


def test_update_readme_replaces_only_between_markers(tmp_path):
    readme = tmp_path / "README.md"
    before = f"# Title\n\nintro\n{START}\nold table\n{END}\n\ntail\n"
    readme.write_text(before, encoding="utf-8")
    assert update_readme("NEW", str(readme)) is True
    assert readme.read_text(encoding="utf-8") == f"# Title\n\nintro\n{START}\nNEW\n{END}\n\ntail\n"
    # idempotent
    assert update_readme("NEW", str(readme)) is True
    assert readme.read_text(encoding="utf-8").count("NEW") == 1
    # no markers: nothing written
    other = tmp_path / "OTHER.md"
    other.write_text("no markers\n", encoding="utf-8")
    assert update_readme("NEW", str(other)) is False
    assert other.read_text(encoding="utf-8") == "no markers\n"
    assert update_readme("NEW", str(tmp_path / "missing.md")) is False


def test_load_results_skips_bad_files(tmp_path, capsys):
    (tmp_path / "b_bench.json").write_text(json.dumps({"summary": [{"metric": "x"}]}))
    (tmp_path / "a_bench.json").write_text(json.dumps({"benchmark": "named", "summary": []}))
    (tmp_path / "c.json").write_text(json.dumps({"no_summary": 1}))
    (tmp_path / "d.json").write_text("{not json")
    res = load_results(str(tmp_path))
    assert [r["benchmark"] for r in res] == ["named", "b_bench"]     # sorted by file name
    assert "d.json" in capsys.readouterr().err


# --------------------------------------------------------------------------- step_statistics
def test_step_statistics_pairs_blocks_and_takes_the_median_ratio():
    from benchmarks.bench_fmu import step_statistics
    ours = [2.0, 3.0, 4.0, 10.0]
    floor = [1.6, 2.0, 2.0, 4.0]
    st = step_statistics(ours, floor)
    # paired ratios 1.25, 1.5, 2, 2.5: median (1.5 + 2) / 2; quartiles at positions 0.75 and 2.25
    # of the sorted ratios (linear): 1.25 + 0.75 * 0.25 and 2 + 0.25 * 0.5
    assert st["ratio"] == pytest.approx(1.75)
    assert st["ratio_q1"] == pytest.approx(1.4375) and st["ratio_q3"] == pytest.approx(2.125)
    # the minima come from different pairs: 2 / 1.6
    assert st["ratio_of_min"] == pytest.approx(1.25)
    assert st["ours_s"] == pytest.approx(3.5) and st["floor_s"] == pytest.approx(2.0)
    assert st["ours_min_s"] == 2.0 and st["floor_min_s"] == 1.6


@pytest.mark.parametrize("ours, floor", [([1.0, 2.0], [1.0]), ([], []), ([1.0], [0.0])])
def test_step_statistics_refuses_unpaired_or_empty_blocks(ours, floor):
    from benchmarks.bench_fmu import step_statistics
    with pytest.raises(ValueError, match="paired positive times"):
        step_statistics(ours, floor)


def test_own_cost_ratio_takes_the_call_floor_off_both():
    from benchmarks.bench_fmu_native import own_cost_ratio
    floor_call = [1.0, 1.2, 0.9]                          # the host's cost of the calls alone
    ours = [f + 0.4 for f in floor_call]                  # own cost 0.4
    trivial = [f + 2.0 for f in floor_call]               # own cost 2.0
    r = own_cost_ratio(ours, trivial, floor_call)
    assert r["own_ratio"] == pytest.approx(0.2) and r["own_ratio_q1"] == pytest.approx(0.2)
    assert r["ours_own_s"] == pytest.approx(0.4) and r["floor_own_s"] == pytest.approx(2.0)
    assert r["call_floor_s"] == pytest.approx(1.0)


def test_warm_speed_compares_the_best_of_each_checkout_over_all_rounds():
    from benchmarks.bench_warm_speed import compare
    base = [{"s": 2.0, "t": 5.0}, {"s": 1.0, "t": 6.0}]
    ours = [{"s": 1.5, "t": 4.0}, {"s": 3.0, "t": 4.5}]
    got = compare(base, ours)
    assert got["s"] == {"before_s": 1.0, "ours_s": 1.5, "ratio": 1.5}
    assert got["t"] == {"before_s": 5.0, "ours_s": 4.0, "ratio": 0.8}


def test_warm_speed_digests_tell_every_bit_apart_and_leave_wall_time_out():
    """One bit of one array, one count, one flag each change that field's digest alone; the wall
    time changes none; a nested dataclass is compared field by field, so a field added to it
    leaves the others comparable."""
    import copy
    import dataclasses
    from benchmarks.warm_speed import result_digests

    @dataclasses.dataclass
    class Flags:
        code: int
        bounce: bool

    @dataclasses.dataclass
    class Flags2(Flags):
        stall: bool = False

    @dataclasses.dataclass
    class Result:
        final: np.ndarray
        counts: dict
        peak: float
        flags: object
        wall_time_s: float

    base = Result(np.array([0.1, 0.2, 0.3]), {"impact": 3, "stick": 2}, 1.5, Flags(1, False), 0.25)
    d0 = result_digests(base)
    assert set(d0) == {"final", "counts", "peak", "flags.code", "flags.bounce"}
    assert result_digests(copy.deepcopy(base)) == d0
    changes = {"final": lambda r: r.final.__setitem__(1, np.nextafter(r.final[1], 1.0)),
               "counts": lambda r: r.counts.__setitem__("stick", 3),
               "peak": lambda r: setattr(r, "peak", np.nextafter(1.5, 2.0)),
               "flags.bounce": lambda r: setattr(r.flags, "bounce", True)}
    for field, change in changes.items():
        r = copy.deepcopy(base)
        change(r)
        d = result_digests(r)
        assert [k for k in d0 if d[k] != d0[k]] == [field], field
    r = copy.deepcopy(base)
    r.wall_time_s = 9.0
    assert result_digests(r) == d0
    r.flags = Flags2(1, False)
    d = result_digests(r)
    assert {k: d[k] for k in d0} == d0 and set(d) - set(d0) == {"flags.stall"}
    r.final = r.final.astype(np.float32)                  # the same values in another type: other bits
    assert result_digests(r)["final"] != d0["final"]


def test_warm_speed_bits_compare_the_fields_both_return_in_every_round():
    from benchmarks.bench_warm_speed import compare_bits
    base = [{"s": {"a": "1", "b": "2", "old": "9"}}, {"s": {"a": "1", "b": "2", "old": "9"}}]
    ours = [{"s": {"a": "1", "b": "2", "new": "7"}}, {"s": {"a": "1", "b": "3", "new": "7"}}]
    got = compare_bits(base, ours)["s"]
    assert got == {"identical": ["a"], "differ": ["b"], "only_before": ["old"], "only_ours": ["new"]}
    ours[1]["s"]["b"] = "2"
    assert compare_bits(base, ours)["s"]["differ"] == []


def test_warm_speed_boot_maps_a_checkout_without_installing_it(tmp_path):
    """The probe of the code before runs on that checkout's sources, not on the installed package."""
    import subprocess
    import sys
    from benchmarks.bench_warm_speed import _BOOT
    for pkg, body in (("coupling", "WHERE = 'checkout'\n"), ("fmu_src", "WHERE = 'checkout model'\n")):
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text(body)
    probe = tmp_path / "probe.py"
    probe.write_text("import hammerbit, hammerbit.model, sys\nprint(hammerbit.WHERE, '|', hammerbit.model.WHERE,"
                     " '|', sys.argv[1])\n")
    r = subprocess.run([sys.executable, "-c", _BOOT, str(tmp_path), str(probe), "7"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "checkout | checkout model | 7"


@pytest.mark.parametrize("text, rounds", [(None, 3), ("", 3), ("8", 8), (" 12 ", 12)])
def test_warm_speed_rounds_come_from_the_environment(monkeypatch, text, rounds):
    from benchmarks import bench_warm_speed as W
    if text is None:
        monkeypatch.delenv("HAMMERBIT_BENCH_ROUNDS", raising=False)
    else:
        monkeypatch.setenv("HAMMERBIT_BENCH_ROUNDS", text)
    assert W.rounds_from_env() == rounds


@pytest.mark.parametrize("text", ["0", "-2", "three", "2.5"])
def test_warm_speed_bad_rounds_are_refused_naming_the_variable(monkeypatch, text):
    from benchmarks import bench_warm_speed as W
    monkeypatch.setenv("HAMMERBIT_BENCH_ROUNDS", text)
    with pytest.raises(ValueError, match=f"HAMMERBIT_BENCH_ROUNDS={text!r}.*positive integer"):
        W.rounds_from_env()

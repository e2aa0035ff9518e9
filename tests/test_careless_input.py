"""Careless input to every command: exit code 2 before any work, no traceback, the words typed.

Each case runs the CLI in this process (:func:`cli_run.run_cli`) in a scratch
directory holding a directory ``adir``, an empty file ``afile`` and a TOML
file that is not UTF-8 (``bad.toml``).  The runs themselves are replaced by a
function that fails the test (:func:`no_run`), so a case passes only if the
input is refused *before* the run.  The first block are the inputs of issue
24 (a new user's report); the rest are more of the same kind.

Ctrl-C: a command in a new process gets SIGINT (to its whole process group,
as a terminal sends it) and must print at most two lines and exit 130.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from cli_run import run_cli

#: the paper's rig: F0 = mu_e F_N = 54 N (docs/model.md), and the group a <= 1000 (validation.RANGES)
F0_N = 54.0
A_MAX_GROUP = 1000.0

FIELD = ["--string", "field-2200m"]
BIG_MAP = ["--axis", "a=0.05:0.25:1000000", "--axis", "eta=0.6:1.4:1000000"]

# (argv, words that must all appear on stderr); every case exits 2
ISSUE = [
    (["bifurcation", "--range", "0", "0.2", "--out", "b.txt"], ["--out", "b.txt", "txt", "png"]),
    (["map", "--axis", "a=0.1:0.2:3", "--plot", "m.foo"], ["--plot", "m.foo", "foo"]),
    (["sweep", *FIELD, "--frequencies", "15", "30", "3", "--plot", "s.doc"], ["--plot", "s.doc"]),
    (["simulate", "--plot", "/proc/x.png"], ["--plot", "/proc/x.png"]),
    (["check", *FIELD, "--frequency", "20", "--plot", "/proc/x.png"], ["--plot", "/proc/x.png"]),
    (["map", "--axis", "a=0.1:0.2:3", "--out", "adir"], ["--out", "adir", "directory"]),
    (["cosim", *FIELD, "--stop", "1", "--out", "adir"], ["--out", "adir", "directory"]),
    (["modes", *FIELD, "--csv", "adir"], ["--csv", "adir", "directory"]),
    (["simulate", "--csv", "/dev/full"], ["--csv", "/dev/full"]),
    (["bifurcation", "--range", "0", "0.2", "--out", "adir"], ["--out", "adir", "directory"]),
    (["fmu", "build", "--out", "x.txt"], ["--out", "x.txt", "fmu"]),
    (["map", *BIG_MAP], ["--axis", "1000000", "memory", "limit"]),
    (["cosim", *FIELD, "--stop", "1e9"], ["--stop", "1e+09", "memory", "limit"]),
    (["map", "--axis", "a=0.1:0.2:3", "--workers", "1000"], ["--workers", "1000", "cores"]),
    (["simulate", "--set", "A=1e9"], ["'A'", "1000000000", " N"]),
    (["optimize", "--bounds", "amplitude=0:1e9"], ["amplitude", "1000000000", " N"]),
    (["cosim", *FIELD, "--stop", "1", "--set", "A=1e12"], ["'A'", "1000000000000", " N"]),
    (["modes", "--string", "lab", "--count", "100000"], ["--count 100000", "elements"]),
    (["modes", *FIELD, "--fmax", "1e6"], ["--fmax", "elements"]),
    (["check", *FIELD, "--frequency", "20", "--range", "0", "1e6"], ["--range 0 1e+06", "elements"]),
    (["optimize", "--bounds", "foo=1:2"], ["--bounds foo", "unknown", "amplitude", "frequency"]),
    (["bifurcation", "--param", "zzz", "--range", "0", "1", "--out", "b.png"], ["--param zzz", "unknown", "eta"]),
    (["modes", "--string", "adir"], ["--string adir", "directory"]),
    (["modes", "--string", "bad.toml"], ["--string bad.toml", "UTF-8"]),
    (["check", "--string", "bad.toml", "--frequency", "20"], ["--string bad.toml", "UTF-8"]),
    (["cosim", "--string", "bad.toml", "--stop", "1"], ["--string bad.toml", "UTF-8"]),
]

MORE = [
    (["simulate", "--periods", "-5"], ["--periods", "-5"]),
    (["simulate", "--periods", "100000000000"], ["--periods 100000000000", "memory"]),
    (["simulate", "--rtol", "0"], ["--rtol", "0"]),
    (["simulate", "--set", "K=-1"], ["'K'", "-1", "N/m"]),
    (["simulate", "--set", "f=0"], ["'f'", "Hz"]),
    (["simulate", "--set", "m1=1e20"], ["'m1'", "kg"]),
    (["simulate", "--set", "zzz=1"], ["'zzz'", "unknown", "hammer_mass"]),
    (["simulate", "--set", "A=1e9", "--set", "K=4340"], ["'A'", "1000000000"]),
    (["simulate", "--set", "mu_d=0.9"], ["'mu_d'", "0.9"]),
    (["simulate", "--set", "a=x"], ["a=x", "not a number"]),
    (["simulate", "--plot", "adir"], ["--plot adir", "directory"]),
    (["simulate", "--plot", "s.xyz"], ["--plot s.xyz", "xyz"]),
    (["simulate", "--csv", "afile/x.csv"], ["--csv afile/x.csv", "afile", "not a directory"]),
    (["simulate", "--plot", "afile/x.png"], ["--plot afile/x.png", "not a directory"]),
    (["simulate", "--plot", ""], ["--plot", "empty"]),
    (["simulate", "--sample-dt", "0", "--csv", "x.csv"], ["--sample-dt", "0"]),
    (["simulate", "--method", "euler"], ["--method", "euler"]),
    (["simulate", "--preset", "nope"], ["--preset", "nope"]),
    (["bifurcation", "--num", "0", "--range", "0", "1", "--out", "b.png"], ["--num 0"]),
    (["bifurcation", "--range", "0", "1", "--out", "b.png", "--workers", "0"], ["--workers 0"]),
    (["bifurcation", "--param", "A", "--range", "0", "1e9", "--out", "b.png"], ["--param A --range", " N"]),
    (["bifurcation", "--range", "0", "1", "--out", "b.png", "--csv", "adir"], ["--csv adir", "directory"]),
    (["map", "--axis", "zzz=0:1:3"], ["--axis zzz", "unknown", "eta"]),
    (["map", "--axis", "a=0:1"], ["--axis a", "0:1", "LO:HI:N"]),
    (["map"], ["--axis"]),
    (["map", "--axis", "a=0:1:2", "--axis", "b=0:1:2", "--axis", "eta=1:2:2", "--axis", "mu=0.5:0.9:2"],
     ["--axis", "4"]),
    (["map", "--axis", "a=0.1:0.2:3", "--out", "m.txt"], ["--out m.txt", "nc"]),
    (["sweep", *FIELD, "--frequencies", "30", "15", "3"], ["--frequencies 30 15 3"]),
    (["sweep", *FIELD, "--frequencies", "15", "30", "3", "--csv", "adir"], ["--csv adir", "directory"]),
    (["sweep", *FIELD, "--frequencies", "15", "30", "3", "--workers", "1000"], ["--workers 1000"]),
    (["cosim", "--string", "adir", "--stop", "1"], ["--string adir", "directory"]),
    (["cosim", "--string", "nofile.toml", "--stop", "1"], ["nofile.toml", "field-2200m"]),
    (["cosim", *FIELD, "--stop", "1", "--step", "0"], ["--step", "0"]),
    (["cosim", *FIELD, "--stop", "1", "--interface-stiffness", "-5"], ["--interface-stiffness", "-5"]),
    (["cosim", *FIELD, "--stop", "1", "--out", "afile/r.csv"], ["--out afile/r.csv", "not a directory"]),
    (["modes", *FIELD, "--count", "0"], ["--count 0"]),
    (["modes", *FIELD, "--rtol", "5"], ["--rtol", "5"]),
    (["modes", *FIELD, "--top", "weird"], ["--top", "weird"]),
    (["modes", "--string", "lab", "--hammer-on-bottom", "--set", "A=1e12"], ["'A'", " N"]),
    (["check", *FIELD, "--frequency", "-3"], ["--frequency", "-3"]),
    (["check", *FIELD, "--frequency", "20", "--plot", "c.doc"], ["--plot c.doc", "doc"]),
    (["check", *FIELD, "--frequency", "20", "--margin", "2"], ["--margin", "2"]),
    (["check", *FIELD, "--frequency", "20", "--factor", "3"], ["--factor", "--rpm"]),
    (["check", "--string", "adir", "--frequency", "20"], ["--string adir", "directory"]),
    (["optimize", "--bounds", "frequency=2:1"], ["--bounds frequency", "2:1"]),
    (["optimize", "--bounds", "frequency=1:2:3"], ["--bounds", "frequency=1:2:3"]),
    (["optimize", "--string", "adir"], ["--string adir", "directory"]),
    (["optimize", "--workers", "1000"], ["--workers 1000"]),
    (["fmu", "build", "--out", "afile/x.fmu"], ["--out afile/x.fmu", "not a directory"]),
    (["bifurcation", "--range", "0", "1", "--out", "b.png", "--num", "1000000000000"], ["--num 1000000000000",
                                                                                      "memory"]),
    (["optimize", "--grid", "10000000"], ["--grid 10000000", "cells", "limit"]),
    (["cosim", *FIELD, "--stop", "1", "--fmu", "adir"], ["--fmu adir", "directory"]),
    (["cosim", *FIELD, "--stop", "1", "--fmu", "bad.toml"], ["--fmu bad.toml", "not an FMU"]),
    (["check", *FIELD, "--rpm", "120", "--rpm-range", "0", "1e9"], ["--rpm-range HI", "1000000000", "rev/min"]),
    (["simulate", "--csv", "x.csv", "--sample-dt", "1e-9"], ["--sample-dt 1e-09", "samples"]),
    (["sweep", *FIELD, "--frequencies", "15", "30", "1e12"], ["--frequencies 15 30 1000000000000", "limit"]),
]


def no_run(*args, **kwargs):
    raise AssertionError("the run started before the input was checked")


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """A scratch working directory with the careless files; every run replaced by :func:`no_run`."""
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("")
    (tmp_path / "bad.toml").write_bytes(b'name = "x"\n\xff\xfe = 1\n')
    monkeypatch.chdir(tmp_path)
    # modules that bind a run function at import are imported first, so that they keep the real one
    import hammerbit.cosim.reference  # noqa: F401
    import hammerbit.scene.plots  # noqa: F401
    import hammerbit.studies.executor  # noqa: F401
    import hammerbit.cli.cosim as cli_cosim
    import hammerbit.cli.main as cli_main
    import hammerbit.cli.studies as cli_studies
    import hammerbit.fmu.build as fmu_build
    import hammerbit.scene.simulate as scene
    import hammerbit.studies.bifurcation as bif
    import hammerbit.studies.map as smap
    import hammerbit.studies.optimize as opt
    import hammerbit.studies.sweep as sweep
    for mod, name in ((scene, "simulate"), (bif, "bifurcation"), (smap, "regime_map"), (opt, "optimize"),
                      (sweep, "sweep"), (fmu_build, "build_fmu")):
        monkeypatch.setattr(mod, name, no_run)
    monkeypatch.setattr(cli_main, "interruptible", no_run)
    from hammerbit.cosim import master, reference
    monkeypatch.setattr(master, "cosimulate", no_run)
    monkeypatch.setattr(reference, "monolithic", no_run)
    return tmp_path, (cli_cosim, cli_studies)


@pytest.mark.parametrize("argv, words", ISSUE + MORE, ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_careless_input_is_refused_before_the_run_in_the_users_words(argv, words, scratch, capsys):
    code, out, err = run_cli(argv, capsys)
    assert code == 2, (code, err)
    assert "Traceback" not in err and "AssertionError" not in err, err
    assert len([ln for ln in err.splitlines() if "error:" in ln]) == 1, err   # one message (argparse adds usage)
    for w in words:
        assert w in err, (w, err)
    assert "np.float64" not in err


def test_enough_careless_inputs():
    assert len(ISSUE) >= 24 and len(MORE) >= 30


def test_the_si_range_of_a_typed_amplitude_is_the_groups_limit_in_newtons(scratch, capsys):
    """A = 1e9 N: the allowed amplitude is a <= 1000 times F0 = 54 N (by hand), in N."""
    code, _, err = run_cli(["simulate", "--set", "A=1e9"], capsys)
    assert code == 2
    hi = float(err.split("allowed [0, ")[1].split("]")[0])
    assert hi == pytest.approx(A_MAX_GROUP * F0_N, rel=1e-3)


def test_missing_parent_directories_are_created_before_the_run(tmp_path, capsys):
    """The one policy: a missing parent is created (and the file probed) before the run."""
    target = tmp_path / "new" / "deeper" / "run.csv"
    code, out, err = run_cli(["simulate", "--periods", "5", "--csv", str(target)], capsys)
    assert code == 0, err
    assert target.read_text().splitlines()[0].startswith("time")


def test_a_refused_output_leaves_no_directory_behind(tmp_path, capsys):
    """A refusal after the parents were created (no write permission there) removes them again."""
    if os.geteuid() == 0:
        pytest.skip("root writes everywhere")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        code, _, err = run_cli(["simulate", "--csv", str(ro / "x.csv")], capsys)
        assert code == 2 and "--csv" in err
    finally:
        ro.chmod(0o700)


def test_fmu_build_into_an_existing_directory_passes_the_check(tmp_path):
    from hammerbit.cli.preflight import preflight
    import argparse
    preflight(argparse.Namespace(command="fmu", out=str(tmp_path)))


# --------------------------------------------------------------------------- Ctrl-C
#: a hang guard only (the command must end after SIGINT); not a timing goal
CTRL_C_GUARD_S = 120.0
#: long runs of each command, in process (``--workers 1``: the cluster variant is in test_studies)
LONG = {
    "simulate": ["simulate", "--periods", "100000000"],
    "map": ["map", "--axis", "a=0.05:0.25:400", "--axis", "eta=0.6:1.4:400", "--workers", "1"],
    "bifurcation": ["bifurcation", "--range", "0", "0.25", "--num", "4000", "--out", "b.png", "--workers", "1"],
    "optimize": ["optimize", "--grid", "200", "--workers", "1"],
    "cosim": ["cosim", *FIELD, "--stop", "200", "--json"],
    "sweep": ["sweep", *FIELD, "--frequencies", "15", "30", "50", "--workers", "1"],
    "continue": ["continue", "--param", "a", "--range", "0.22", "0.05", "--seeds", "40"],
}


def _hammerbit():
    exe = os.path.join(os.path.dirname(sys.executable), "hammerbit")
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "hammerbit"]


@pytest.mark.slow
def test_ctrl_c_prints_one_line_and_exits_130(tmp_path, built_fmu):
    """SIGINT to the process group of each long command (all at once, to share the start-up):
    exit 130, at most two lines on stderr, no traceback.  ``cosim --fmu``: the FMU's host may
    swallow the KeyboardInterrupt in a doStep; the command ends anyway."""
    long = dict(LONG, cosim_fmu=["cosim", *FIELD, "--fmu", str(built_fmu), "--stop", "200"])
    procs = {name: subprocess.Popen(_hammerbit() + argv, cwd=tmp_path, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True, start_new_session=True)
             for name, argv in long.items()}
    time.sleep(8.0)                 # past the imports, into the runs (a signal earlier is handled too)
    for p in procs.values():
        os.killpg(p.pid, signal.SIGINT)
    for name, p in procs.items():
        out, err = p.communicate(timeout=CTRL_C_GUARD_S)
        assert p.returncode == 130, (name, p.returncode, err[-2000:])
        assert "Traceback" not in err and "Status.init" not in err, (name, err[-2000:])
        assert len(err.strip().splitlines()) <= 2, (name, err[-2000:])


@pytest.mark.slow
def test_ctrl_c_in_a_map_on_a_local_cluster_prints_one_line(tmp_path):
    """The same with the workers of a local cluster (they ignore SIGINT, so only the command
    speaks).  The Ctrl-C is sent again every few seconds until the command ends, as a user would."""
    p = subprocess.Popen(_hammerbit() + ["map", "--axis", "a=0.05:0.25:400", "--axis", "eta=0.6:1.4:400",
                                         "--workers", "2"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    # wait for the cluster: the command (which runs the nannies), the resource tracker, two workers
    for _ in range(int(CTRL_C_GUARD_S / 0.5)):
        group = subprocess.run(["pgrep", "-s", str(p.pid)], capture_output=True, text=True).stdout.split()
        if len(group) >= 4 or p.poll() is not None:
            break
        time.sleep(0.5)
    time.sleep(1.0)                 # the workers start (the moment a worker would print a traceback)
    assert p.poll() is None, "the map ended before the test could interrupt it"
    out = err = None
    for _ in range(int(CTRL_C_GUARD_S / 5.0)):
        os.killpg(p.pid, signal.SIGINT)
        try:
            out, err = p.communicate(timeout=5.0)
            break
        except subprocess.TimeoutExpired:
            continue
    else:
        p.kill()
        pytest.fail("map did not end after Ctrl-C")
    assert p.returncode == 130, err[-2000:]
    assert "Traceback" not in err and "Status.init" not in err, err[-2000:]
    assert len(err.strip().splitlines()) <= 2, err[-2000:]
    for _ in range(60):             # the resource tracker ends shortly after its parent
        left = subprocess.run(["pgrep", "-s", str(p.pid)], capture_output=True, text=True).stdout.split()
        if not left:
            break
        time.sleep(0.5)
    assert not left, left


# --------------------------------------------------------------------------- files for people
def test_bifurcation_csv_is_si_with_each_values_own_scales(tmp_path, capsys):
    """Over the SI stiffness K, x0 = 54 N / K changes with each value: the mm columns follow it
    (by hand, against the nondimensional points of the same sweep run in the library)."""
    from hammerbit.model.presets import preset
    from hammerbit.studies.bifurcation import bifurcation
    from hammerbit.studies.executor import ExecutorOptions
    csv = tmp_path / "bif.csv"
    code, out, err = run_cli(["bifurcation", "--preset", "paper-fig9", "--param", "K", "--range", "2170", "4340",
                              "--num", "2", "--periods", "20", "--keep", "4", "--workers", "1",
                              "--out", str(tmp_path / "b.png"), "--csv", str(csv)], capsys)
    assert code == 0, err
    head = csv.read_text().splitlines()[0]
    assert head == "K [N/m],time [s],x_b - x_s [mm],v_b - v_s [m/s],bit velocity v_s [m/s],bit position x_s [mm]"
    rows = np.loadtxt(csv, delimiter=",", skiprows=1)
    res = bifurcation(preset("paper-fig9"), "K", np.array([2170.0, 4340.0]), periods=20, keep=4,
                      options=ExecutorOptions(workers=1))
    for i, K in enumerate((2170.0, 4340.0)):
        x0_mm = 54.0 / K * 1e3
        mine = rows[rows[:, 0] == K]
        P = res.points[i]
        assert np.allclose(mine[:, 2], (P[:, 1] - P[:, 3]) * x0_mm, rtol=1e-12)
        assert np.allclose(mine[:, 5], P[:, 3] * x0_mm, rtol=1e-12)
    assert "SI" in out


def test_a_contact_open_to_the_end_reports_its_peak_force():
    """r = 0: the hammer rests on the bit and never separates; the peak contact force is that of
    the open contact (no separation logs it), checked against densely sampled contact forces."""
    from hammerbit.model.presets import preset
    from hammerbit.scene.simulate import Record, simulate
    g = preset("paper-fig9").replace(r=0.0)
    P = 20
    t = np.linspace(0.0, P * g.period, P * 2000 + 1)
    res = simulate(g, P, record=Record(events=True, times=t))
    assert res.counts["impact"] == res.counts["separation"] + 1          # open at the end
    sampled = res.samples["contact_force"].max() * g.scales.friction_force
    assert sampled > 0
    assert sampled * (1 - 1e-9) <= res.peak_contact_force_n() <= sampled * 1.01


def test_hammer_modes_warn_when_the_exact_frequencies_show_the_tolerance_missed(capsys):
    """The warning's figure is the worst relative error of the table, recomputed here from the
    finite-element and exact frequencies the JSON reports."""
    argv = ["modes", "--string", "field-2200m", "--hammer-on-bottom", "--fmax", "40", "--exact"]
    code, out, err = run_cli(argv + ["--json"], capsys)
    assert code == 0, err
    d = __import__("json").loads(out)
    worst = max(abs(f / e - 1.0) for f, e in zip(d["frequencies_hz"], d["exact_hz"]))
    assert worst > 1e-5                                   # this case misses the default --rtol
    assert "warning" in err and "--rtol 1e-05" in err and f"{worst:.2e}" in err
    code, _, err = run_cli(argv + ["--rtol", f"{2 * worst:g}"], capsys)
    assert code == 0 and "warning" not in err


def test_fmu_build_says_what_it_does_before_the_long_build(tmp_path, capsys, monkeypatch):
    """The progress line is on stderr before the build starts (the build itself is stubbed)."""
    import hammerbit.fmu.build as fmu_build
    seen = {}

    def fake_build(out, options):
        seen["err"] = capsys.readouterr().err               # what the user saw while it builds
        return out

    monkeypatch.setattr(fmu_build, "build_fmu", fake_build)
    code, out, err = run_cli(["fmu", "build", "--out", str(tmp_path / "H.fmu")], capsys)
    assert code == 0, err
    assert "building HammerBitRock.fmu" in seen["err"] and "kernels" in seen["err"]
    assert "done in" in err and out.strip() == str(tmp_path / "H.fmu")


def test_isolated_modes_against_a_brute_force_of_band_overlaps():
    from hammerbit.check.plots import isolated_modes
    rng = np.random.default_rng(24)
    for _ in range(200):
        f = np.sort(rng.uniform(1.0, 50.0, rng.integers(1, 12)))
        m = rng.uniform(0.01, 0.3)
        want = [all(not (f[i] * (1 - m) <= f[j] * (1 + m) and f[j] * (1 - m) <= f[i] * (1 + m))
                    for j in range(f.size) if j != i) for i in range(f.size)]
        assert isolated_modes(f, m).tolist() == want


def test_no_period_is_said_in_words(capsys):
    """The chaos preset has no period (its Poincaré points never repeat; checked on them here)."""
    from hammerbit.model.presets import preset
    from hammerbit.scene.analysis import detect_period
    from hammerbit.scene.simulate import Record, simulate
    assert detect_period(simulate(preset("chaos"), 300, record=Record(poincare=True)).poincare) is None
    code, out, err = run_cli(["simulate", "--preset", "chaos", "--periods", "300"], capsys)
    assert code == 0, err
    assert "no period found" in out and "none" not in out.split("period-n")[1].splitlines()[0]

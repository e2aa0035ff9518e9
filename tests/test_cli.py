"""The ``hammerbit`` command line as a user meets it.

Exit codes, SI output (checked against scales computed by hand from the
paper's rig: x0 = 54 N / 2170 N/m, Omega = sqrt(2170 / 25.3)), regime warnings,
the CSV time series, figures, bad input without tracebacks, help text, and
every command the documentation shows.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import re
import shlex
import subprocess
import sys

import numpy as np
import pytest

from cli_run import run_cli
from hammerbit.cli.main import build_parser
from hammerbit.model.regime_codes import REGIME_BITS

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))

# the paper's rig, by hand (docs/model.md)
X0_M = 54.0 / 2170.0
OMEGA = math.sqrt(2170.0 / 25.3)
#: C of the paper-figure presets: C = 2 xi sqrt(K m1) with their calibrated xi (docs/model.md)
C_PAPER = 2.0 * 0.071 * math.sqrt(2170.0 * 25.3)


def period_s(eta: float, K: float = 2170.0, m1: float = 25.3) -> float:
    return 2.0 * math.pi / (eta * math.sqrt(K / m1))


def console(*args, cwd=None, timeout=300):
    """The installed console script (or ``python -m hammerbit`` when it is not on this venv's bin)."""
    exe = pathlib.Path(sys.executable).with_name("hammerbit")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "hammerbit"]
    return subprocess.run(cmd + list(args), capture_output=True, text=True, cwd=cwd, timeout=timeout)


# --------------------------------------------------------------------------- entry points
def test_readme_main_command(tmp_path):
    """The README's first command, through the console script: SI text, a PNG, exit 0."""
    r = console("simulate", "--preset", "paper-fig9", "--set", "a=0.083", "--periods", "300",
                "--plot", "scene.png", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert re.search(r"penetration after 300 periods \([\d.]+ s\): [\d.]+ mm", r.stdout), r.stdout
    assert re.search(r"rate of penetration .*: [\d.]+ mm/period = [\d.]+ m/h", r.stdout)
    assert "period-n of the bounded motion: 3" in r.stdout
    assert (tmp_path / "scene.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_python_m_hammerbit_and_version():
    from importlib.metadata import version
    r = subprocess.run([sys.executable, "-m", "hammerbit", "--version"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0
    assert r.stdout.strip() == f"hammerbit {version('hammerbit')}"


def test_bad_input_through_the_console_script():
    r = console("simulate", "--set", "mu_d=0.9")
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "'mu_d'" in r.stderr and "0.9" in r.stderr and "allowed" in r.stderr


# --------------------------------------------------------------------------- SI output
def test_simulate_json_si_against_hand_scales(capsys):
    code, out, err = run_cli(["simulate", "--preset", "paper-fig9", "--set", "a=0.083", "--periods", "300",
                              "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["penetration_mm"] == pytest.approx(d["penetration_x0"] * X0_M * 1e3, rel=1e-12)
    assert d["penetration_m"] == pytest.approx(d["penetration_x0"] * X0_M, rel=1e-12)
    T = period_s(1.0)
    assert d["forcing_period_s"] == pytest.approx(T, rel=1e-12)
    assert d["time_s"] == pytest.approx(300 * T, rel=1e-12)
    assert d["preload_n"] == pytest.approx(0.55 * 54.0) and d["amplitude_n"] == pytest.approx(0.083 * 54.0)
    rop = d["rop"]
    assert rop["mm_per_period"] == pytest.approx(rop["x0_per_period"] * X0_M * 1e3, rel=1e-12)
    assert rop["m_per_h"] == pytest.approx(rop["mm_per_period"] * 1e-3 / T * 3600.0, rel=1e-12)
    # the ROP is the advance over the second half: two separate runs from rest give it too
    from hammerbit.model.presets import preset
    from hammerbit.scene.simulate import simulate
    g = preset("paper-fig9").replace(a=0.083)
    p150, p300 = simulate(g, 150).penetration, simulate(g, 300).penetration
    assert rop["x0_per_period"] == pytest.approx((p300 - p150) / 150, rel=1e-7)
    assert d["period"] == 3
    assert d["flags"] == [] and d["paper_domain"] == {"inside": True, "outside": []}
    assert not d["scene_flags"]["runaway"] and not d["scene_flags"]["bounce"]
    assert d["scales"]["length_m"] == pytest.approx(X0_M, rel=1e-14)


def test_si_override_changes_the_scales(capsys):
    """K doubled: x0 halves and Omega grows by sqrt(2); the SI figures follow."""
    code, out, _ = run_cli(["simulate", "--preset", "paper-fig9", "--set", "K=4340", "--periods", "50",
                            "--json"], capsys)
    assert code == 0
    d = json.loads(out)
    assert d["penetration_mm"] == pytest.approx(d["penetration_x0"] * 54.0 / 4340.0 * 1e3, rel=1e-12)
    assert d["forcing_period_s"] == pytest.approx(period_s(d["groups"]["eta"], K=4340.0), rel=1e-12)


def test_simulate_text_is_si(capsys):
    # 300 periods: the P2 of this scene takes about 80 periods to settle from rest
    code, out, err = run_cli(["simulate", "--preset", "paper-fig12", "--set", "a=0.06", "--periods", "300"],
                             capsys)
    assert code == 0, err
    assert re.search(r"preload [\d.]+ N, amplitude [\d.]+ N", out)
    assert re.search(r"penetration after 300 periods \([\d.]+ s\): [\d.]+ mm$", out, flags=re.M)
    assert re.search(r"peak contact force: [\d.]+ N", out)  # the gap closes in this scene
    assert not re.search(r"\d x0\b", out)                   # no nondimensional lengths for people
    assert "warning" not in err                            # inside the validity domain: no warning


# --------------------------------------------------------------------------- validity domain
@pytest.mark.parametrize("settings, outside", [
    (["--preset", "chaos", "--set", "b=0.8", "--set", "eta=0.3", "--set", "a=0"], ["b > mu"]),
    (["--preset", "paper-fig9", "--set", "a=0.6"], ["a >= b", "a + b > 1"]),
    (["--preset", "paper-fig9", "--set", "a=0.5"], ["a + b > 1"]),
    (["--preset", "chaos", "--set", "b=0.59"], []),
])
def test_paper_domain_and_scene_flags_reach_the_json_and_warn(settings, outside, capsys):
    code, out, err = run_cli(["simulate", *settings, "--periods", "100", "--json"], capsys)
    assert code == 0
    d = json.loads(out)
    assert d["paper_domain"] == {"inside": not outside, "outside": outside}
    names = [f for f in ("runaway", "bounce", "tension", "stall", "transient") if d["scene_flags"][f]]
    assert d["flags"] == d["regime_names"] == names
    assert d["regime"] == sum(REGIME_BITS[f] for f in names)
    for f in ("runaway", "bounce", "tension", "stall", "transient"):
        assert (f"warning: {f}" in err) == (f in d["flags"]), err
    assert ("outside the paper's domain" in err) == bool(outside)
    assert "Traceback" not in err


def test_runaway_flag_marks_a_drift_without_bound(capsys):
    """The flagged scene really runs away; the same scene just below the threshold does not."""
    pens = {}
    for b in (0.62, 0.58):   # the chaos preset's mu is 0.6
        code, out, _ = run_cli(["simulate", "--preset", "chaos", "--set", f"b={b}", "--set", "eta=0.3",
                                "--set", "a=0", "--periods", "100", "--json"], capsys)
        d = json.loads(out)
        pens[b] = (d["penetration_x0"], d["scene_flags"]["runaway"])
    assert pens[0.62][1] and not pens[0.58][1]
    assert pens[0.62][0] > 100.0 * max(pens[0.58][0], 1.0)


# --------------------------------------------------------------------------- CSV and figures
def test_csv_time_series_in_si(tmp_path, capsys):
    path = tmp_path / "run.csv"
    code, out, err = run_cli(["simulate", "--preset", "paper-fig12", "--set", "a=0.06", "--periods", "20",
                              "--csv", str(path), "--sample-dt", "0.005", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    header = path.read_text().splitlines()[0].split(",")
    assert header[0] == "time [s]"
    names = [h.split(" [")[0] for h in header]
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    col = {n: data[:, i] for i, n in enumerate(names)}
    horizon = 20 * period_s(1.0)
    assert data.shape[0] == math.floor(horizon / 0.005) + 1
    assert np.allclose(np.diff(col["time"]), 0.005, rtol=1e-9)
    assert col["time"][0] == 0.0 and col["time"][-1] <= horizon
    # the bit never steps back, and its last sample is below the final penetration
    assert np.all(np.diff(col["bit_position"]) >= 0.0)
    assert col["bit_position"][-1] <= d["penetration_mm"] * (1 + 1e-8)
    # forces by hand in SI: F_k = K (x_b - x_s) + C (v_b - v_s)
    fk = 2170.0 * (col["hammer_position"] - col["bit_position"]) * 1e-3 \
        + C_PAPER * (col["hammer_velocity"] - col["bit_velocity"])
    assert np.allclose(col["spring_damper_force"], fk, rtol=1e-6, atol=1e-6)
    # contact only with the gap closed (R = 0.84 x0), and it happens in this scene
    gap_mm = 0.84 * X0_M * 1e3
    assert np.all(col["contact_force"][col["relative_position"] < gap_mm - 1e-9] == 0.0)
    assert col["contact_force"].max() > 0.0
    assert np.all(col["slip"][col["bit_velocity"] > 0] == 1)


def test_plot_formats_follow_the_extension(tmp_path, capsys):
    code, _, err = run_cli(["simulate", "--periods", "20", "--plot", str(tmp_path / "s.svg")], capsys)
    assert code == 0, err
    assert (tmp_path / "s.svg").read_text().lstrip().startswith("<?xml")


@pytest.mark.parametrize("target, words", [
    ("afile/x.png", ["afile", "is a file, not a directory"]),         # missing parents are created,
    ("/proc/x.png", ["/proc/x.png", "cannot write"]),                  # a file as a parent is refused
    ("out.xyz", ["unsupported format", "xyz"]),
])
def test_bad_plot_path_refused_before_the_run(target, words, tmp_path, capsys, monkeypatch):
    import hammerbit.scene.simulate as sim

    def must_not_run(*a, **k):
        raise AssertionError("the run started before the output path was checked")
    monkeypatch.setattr(sim, "simulate", must_not_run)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    code, out, err = run_cli(["simulate", "--plot", target], capsys)
    assert code == 2
    assert all(w in err for w in words), err
    assert "Traceback" not in err


# --------------------------------------------------------------------------- bad input
BAD = [
    (["simulate", "--set", "mu_d=0.9"], ["'mu_d'", "0.9"]),
    (["simulate", "--set", "a=abc"], ["a=abc", "not a number"]),
    (["simulate", "--set", "nonsense=1"], ["'nonsense'"]),
    (["simulate", "--set", "a"], ["NAME=VALUE"]),
    (["simulate", "--set", "A=-5"], ["'A'", "-5"]),
    (["simulate", "--set", "eta=nan"], ["'eta'", "nan"]),
    (["simulate", "--periods", "0"], ["--periods"]),
    (["simulate", "--rtol", "5"], ["--rtol"]),
    (["simulate", "--sample-dt", "0.1"], ["--csv"]),
    (["simulate", "--csv", "x.csv", "--sample-dt", "-1"], ["--sample-dt"]),
    (["simulate", "--csv", "x.csv", "--sample-dt", "1e-9"], ["--sample-dt", "samples"]),
    (["simulate", "--preset", "nope"], ["nope"]),
    (["simulate", "--periods", "ten"], ["ten"]),
    (["no-such-command"], ["no-such-command"]),
    (["modes", "--string", "no-such-file.toml"], ["no-such-file.toml"]),
    (["check", "--string", "field-2200m", "--frequency", "nan"], ["nan"]),
    (["cosim", "--string", "field-2200m", "--fmu", "notazip.fmu", "--stop", "0.01"], ["notazip.fmu"]),
    (["cosim", "--string", "field-2200m", "--stop", "0.01", "--step", "1"], ["step", "1"]),
    (["cosim", "--string", "field-2200m", "--stop", "0.01", "--set", "nonsense=1"], ["'nonsense'"]),
]


@pytest.mark.parametrize("argv, words", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_input_exits_2_naming_what_was_typed(argv, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notazip.fmu").write_text("not a zip file")
    code, out, err = run_cli(argv, capsys)
    assert code == 2, (code, err)
    assert "Traceback" not in err
    assert all(w in err for w in words), err
    assert not (tmp_path / "x.csv").exists()


# --------------------------------------------------------------------------- help
def _subcommands():
    ap = build_parser()
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    return ap, sub


def test_every_command_and_option_has_help():
    ap, sub = _subcommands()
    helps = {c.dest: c.help for c in sub._choices_actions}
    missing = []
    for name, p in sub.choices.items():
        if not helps.get(name):
            missing.append(name)
        for a in p._actions:
            if a.option_strings and not a.help:
                missing.append(f"{name} {a.option_strings[0]}")
    assert not missing, missing


def test_help_shows_defaults(capsys):
    code, out, _ = run_cli(["simulate", "--help"], capsys)
    assert code == 0
    text = " ".join(out.split())
    assert "(default: paper-fig9)" in text and "(default: 100)" in text and "(default: adaptive)" in text


@pytest.mark.parametrize("name", list(_subcommands()[1].choices))
def test_every_command_has_working_help(name, capsys):
    code, out, err = run_cli([name, "--help"], capsys)
    assert code == 0 and f"hammerbit {name}" in out and "error" not in err


# --------------------------------------------------------------------------- documented commands
#: A documented command whose trailing comment says ``# exit N`` (e.g. ``# exit 5: estimate > tol``)
#: shows a non-zero exit on purpose.
DOCUMENTED_EXIT = re.compile(r"#\s*exit\s+(\d+)\b")


def documented_commands():
    """Every ``hammerbit ...`` command line in a ```bash block of README.md and docs/*.md:
    ``[(document name, argv, documented exit code or None)]``."""
    found = []
    for doc in DOCS:
        in_bash = False
        pending = ""
        for line in doc.read_text(encoding="utf-8").splitlines():
            if line.startswith("```"):
                in_bash = line.strip() in ("```bash", "```sh", "```console")
                pending = ""
                continue
            if not in_bash:
                continue
            line = pending + line
            if line.rstrip().endswith("\\"):
                pending = line.rstrip()[:-1] + " "
                continue
            pending = ""
            for part in line.split("&&"):
                words = shlex.split(part, comments=True)
                # the shell's redirections and pipes are not the command's arguments
                cut = [i for i, w in enumerate(words) if w in (">", ">>", "|", "2>", "2>&1")]
                words = words[:cut[0]] if cut else words
                if words[:1] == ["hammerbit"]:
                    code = DOCUMENTED_EXIT.search(part)
                    found.append((doc.name, words[1:], int(code.group(1)) if code else None))
    return found


def test_documented_commands_are_found():
    cmds = documented_commands()
    assert any(a[:1] == ["simulate"] and "--plot" in a for _, a, _ in cmds)
    assert len({a[0] for _, a, _ in cmds}) >= 4


@pytest.fixture(scope="module")
def parser():
    """The command line's parser, built once (a parse keeps nothing in it: its state is the namespace's)."""
    return build_parser()


@pytest.mark.parametrize("doc, argv", [(d, a) for d, a, _ in documented_commands()],
                         ids=[f"{d}: {' '.join(a)}" for d, a, _ in documented_commands()])
def test_documented_command_parses(doc, argv, parser):
    """Every command shown in the docs names a real command with real options."""
    try:
        ns = parser.parse_args(argv)
    except SystemExit as e:
        pytest.fail(f"{doc}: hammerbit {' '.join(argv)} does not parse (exit {e.code})")
    assert callable(ns.func)


# --------------------------------------------------------------------------- nothing writes tracked files
def test_benchmark_harness_writes_scratch_unless_update(tmp_path, monkeypatch):
    import benchmarks
    from benchmarks import __main__ as harness
    mod = tmp_path / "fake_bench_mod.py"
    mod.write_text("from benchmarks import save_result, summary_row\n"
                   "def run(quick=False):\n"
                   "    r = {'summary': [summary_row('fake metric', '1 s')]}\n"
                   "    save_result('fakebench', r)\n"
                   "    return r\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(benchmarks, "SCRATCH_DIR", str(tmp_path / "scratch"))
    tracked = pathlib.Path(benchmarks.TRACKED_RESULTS_DIR)
    before = {p.name: p.stat().st_mtime_ns for p in tracked.iterdir()}
    monkeypatch.setattr(harness, "discover", lambda: {"fakebench": "fake_bench_mod"})
    monkeypatch.setattr(harness.readme_table, "update_readme",
                        lambda *a, **k: pytest.fail("README written without --update"))
    try:
        assert harness.main(["--only", "fakebench"]) == 0
    finally:
        benchmarks.configure_output(False)
    assert (tmp_path / "scratch" / "results" / "fakebench.json").exists()
    assert {p.name: p.stat().st_mtime_ns for p in tracked.iterdir()} == before

"""Every option of every command is used or refused, driven from argparse's own tables.

For each command the parser builds (:func:`hammerbit.cli.options.command_options`),
every option has an entry in :data:`DRIVE` (a new option without one fails
:func:`test_every_option_is_driven`), and each entry is run against a small
base invocation of its command:

* ``v(*value)`` -- the option with this value changes the output (stdout
  with the wall-clock figures left out, and the files written), or is refused
  with exit 2;
* ``n(partner, *value)`` -- an option that only matters with ``partner``:
  alone it exits 2 naming itself; with ``partner`` it changes the output;
* ``w(context, *value)`` / ``r(context, *value)`` -- it changes the output
  where it matters (``context``), against the same context / the plain base;
* ``F(name)`` -- an output file: written where it was not.

Besides: every single-valued option given twice exits 2, and the do-nothing
combinations that were accepted silently are refused.
"""
from __future__ import annotations

import hashlib
import json
import os
from collections import namedtuple

import pytest

from cli_run import run_cli
from hammerbit.cli.main import build_parser
from hammerbit.cli.options import command_options

#: how one option is driven: its value; ``context`` (``~--opt`` removes ``--opt`` and its value from the
#: base, other words are added) applied to both runs, or (``plain_reference``) to the option's run only;
#: ``alone_refused``: the option without its context exits 2 naming itself
Spec = namedtuple("Spec", "value context alone_refused plain_reference", defaults=((), False, False))
F = namedtuple("F", "name")


def v(*value):
    """The option with ``value`` changes the output (or is refused)."""
    return Spec(tuple(value))


def n(partner, *value):
    """Only with ``partner``: alone it exits 2; with it, it changes the output."""
    return Spec(tuple(value), tuple(partner), True)


def w(context, *value):
    """Changes the output in ``context`` (where it matters), against the same context without it."""
    return Spec(tuple(value), tuple(context))


def r(context, *value):
    """Given in ``context`` (replacing another option) instead of the plain base: the output changes."""
    return Spec(tuple(value), tuple(context), False, True)


#: an option that matters only where the dynamics call for it (a sweep run that has not settled by its
#: first duration): accepted, and its effect not shown by a cheap base run; each one is listed here
C = namedtuple("C", "value")
CONDITIONAL = {("sweep", "--max-duration"), ("sweep", "--steady-tol")}


def in_context(base, context):
    out = list(base)
    for word in context:
        if word.startswith("~"):
            i = out.index(word[1:])
            del out[i:i + 2]
    return out + [word for word in context if not word.startswith("~")]


LAB = ["--string", "lab"]
#: the base invocation of each command (small, a few seconds at most)
BASE = {
    "simulate": ["simulate", "--periods", "8", "--json"],
    "modes": ["modes", *LAB, "--count", "3", "--json"],
    "check": ["check", *LAB, "--frequency", "1.47", "--json"],
    "bifurcation": ["bifurcation", "--range", "0.1", "0.12", "--num", "2", "--periods", "20", "--keep", "4",
                    "--workers", "1", "--out", "b.png", "--json"],
    "map": ["map", "--axis", "a=0.1:0.12:2", "--periods", "20", "--workers", "1", "--json"],
    "optimize": ["optimize", "--grid", "3", "--periods", "20", "--workers", "1", "--json"],
    "cosim": ["cosim", *LAB, "--stop", "0.5", "--json"],
    "sweep": ["sweep", *LAB, "--frequencies", "1.4", "1.5", "2", "--duration", "3", "--workers", "1", "--json"],
    "fmu build": ["fmu", "build", "--out", "h.fmu", "--no-portable-cache", "--no-native-front"],
    "fmu build-string": ["fmu", "build-string", *LAB, "--out", "s.fmu"],
    "ssp build": ["ssp", "build", *LAB, "--out", "d.ssp"],
    "continue": ["continue", "--seeds", "2", "--json", "--param", "a", "--range", "0.18", "0.16"],
    "fmu build-system": ["fmu", "build-system", *LAB, "--out", "ds.fmu"],
}
SCENE = {"--preset": v("paper-fig12"), "--set": v("a=0.09"), "--rtol": v("1e-5")}
EXECUTOR = {"--workers": v("2"), "--scheduler": v("tcp://127.0.0.1:9")}
HAMMER = {"--wob": v("20"), "--interface-stiffness": v("3e6"), "--interface-damping": v("1e3"), "--set": v("A=10")}
COSIM = {"--string": v("field-2200m"), "--fmu": v("nofile.fmu"), "--step": v("5e-4"), "--scheme": v("gauss-seidel"),
         "--extrapolation": v("1"), "--f-max": v("50"), "--ramp": v("0.1"), "--harmonic-source": v("master"),
         "--top": v("feed:1"), **HAMMER}
#: how each option of each command is driven
DRIVE = {
    "simulate": {**SCENE, "--method": v("rk4"), "--rtol": v("1e-5"), "--steps-per-period": n(["--method", "rk4"], "50"),
                 "--periods": v("9"), "--json": v(), "--plot": F("s.png"), "--csv": F("s.csv"),
                 "--sample-dt": n(["--csv", "s.csv"], "0.05")},
    "modes": {"--string": v("field-2200m"), "--top": v("free"), "--bottom": v("fixed"), "--count": v("4"),
              "--fmax": v("50"), "--mass": v("lumped"), "--rtol": v("1e-3"), "--exact": v(),
              "--hammer-on-bottom": v(), "--csv": F("m.csv"), "--json": v(),
              **{k: n(["--hammer-on-bottom"], *val.value) for k, val in HAMMER.items()},
              "--set": n(["--hammer-on-bottom"], "m1=30")},
    "check": {"--string": v("field-2200m"), "--frequency": v("2.5"), "--rpm": r(["~--frequency"], "60"),
              "--factor": n(["~--frequency", "--rpm", "60"], "3"), "--margin": v("0.5"), "--top": v("free"),
              "--on-bottom": v("free"), "--off-bottom": v("fixed"), "--range": v("0", "50"),
              "--rpm-range": n(["~--frequency", "--rpm", "60"], "10", "100"), "--resonance-limit": v("3"),
              "--damping-range": v("0.9", "1.1"), "--rtol": v("1e-3"), "--mass": v("lumped"), "--json": v(),
              "--plot": F("c.png"), "--strict": w(["~--frequency", "--frequency", "4.55"])},
    "bifurcation": {**SCENE, "--rtol": w(["--csv", "b.csv"], "1e-5"), "--param": v("b"), "--range": v("0.1", "0.13"), "--num": v("3"), "--periods": v("24"),
                    "--keep": v("5"), **EXECUTOR, "--out": F("b2.png"), "--csv": F("b.csv"), "--json": v()},
    "map": {**SCENE, "--axis": v("eta=0.9:1.1:2"), "--periods": v("24"), **EXECUTOR, "--out": F("m.nc"),
            "--overlay": n(["--axis", "eta=0.9:1.1:2", "--plot", "m.png"], "curves.json"),
            "--plot": F("m.png"), "--json": v()},
    "optimize": {**SCENE, "--string": v("lab"), "--bounds": v("amplitude=3:30"),
                 "--margin": n(["--string", "lab"], "0.3"), "--max-contact-force": v("50"), "--periods": v("24"),
                 "--grid": v("4"), "--confirm": n(["--string", "lab"]),
                 "--confirm-periods": n(["--string", "lab", "--confirm"], "4"),
                 "--fmu": n(["--string", "lab", "--confirm"], "nofile.fmu"),
                 "--interface-stiffness": n(["--string", "lab", "--confirm"], "3e6"),
                 "--interface-damping": n(["--string", "lab", "--confirm"], "1e3"), **EXECUTOR, "--json": v()},
    "cosim": {**COSIM, "--stop": v("0.4"), "--ssp": v("nofile.ssp"), "--tol": v("1e-2"),
              "--adaptive": n(["--step", "5e-4", "--f-max", "50"]), "--monolithic": v(), "--json": v(), "--out": F("c.csv"),
              "--output-derivatives": v()},
    "sweep": {**COSIM, "--frequencies": v("1.4", "1.6", "2"), "--duration": v("2"),
              "--max-duration": C("3"), "--window-periods": v("3"), "--steady-tol": C("0.5"), **EXECUTOR, "--plot": F("s.png"),
              "--csv": F("s.csv"), "--json": v()},
    "fmu build": {"--out": F("h2.fmu"), "--set": v("hammer_mass=30"), "--no-portable-cache": v(),
                  "--no-native-front": v(), "--runtime": v("native"),
                  "--fmi-version": n(["--runtime", "native"], "3")},
    "fmu build-string": {"--string": v("field-2200m"), "--out": F("s2.fmu"), "--top": v("feed:1"),
                         "--runtime": v("native"), "--step": n(["--runtime", "native"], "5e-4"),
                         "--fmi-version": n(["--runtime", "native"], "3")},
    "ssp build": {"--string": v("field-2200m"), "--hammer": v("nofile.fmu"), "--out": F("d2.ssp"), "--stop": v("3"),
                  "--step": v("5e-4"), "--wob": v("20"), "--top": v("feed:1"), "--runtime": v("native"),
                  "--set": v("A=10")},
    "continue": {"--preset": v("paper-fig12"), "--set": v("eta=1.02"), "--param": v("eta"),
                 "--range": v("0.2", "0.16"), "--seeds": v("3"), "--json": v(),
                 "--param2": r(["--range2", "0.98", "1.02"], "eta"),
                 "--range2": r(["--param2", "eta"], "0.98", "1.02"),
                 "--curve-points": w(["--param2", "eta", "--range2", "0.98", "1.02"], "3"),
                 "--csv": F("c.csv"), "--out": F("c.nc"), "--plot": F("c.png")},
    "fmu build-system": {"--string": v("field-2200m"), "--top": v("feed:1"), "--f-max": v("50"),
                         "--tolerance": v("1e-4"), "--out": F("ds2.fmu"), "--wob": v("20000"),
                         "--interface-stiffness": v("3e6"), "--interface-damping": v("1e3"), "--set": v("A=10"),
                         "--fmi-version": v("3")},
}
#: commands cheap enough for the fast set (the others: slow)
FAST = ("simulate",)
#: wall-clock figures: they differ between any two runs
CLOCK_KEYS = ("wall", "setup_time", "total_time", "per_second", "cpu")


def _scrub(obj):
    if isinstance(obj, dict):
        return {k: _scrub(x) for k, x in obj.items() if not any(c in k for c in CLOCK_KEYS)}
    if isinstance(obj, list):
        return [_scrub(x) for x in obj]
    return obj


def _files(folder):
    out = {}
    for root, _, names in os.walk(folder):
        for name in names:
            p = os.path.join(root, name)
            out[os.path.relpath(p, folder)] = hashlib.sha256(open(p, "rb").read()).hexdigest()
    return out


#: input files an option reads, put in every run's folder (so they are not among the files written)
SEED_FILES = {"curves.json": json.dumps({"curves": [{"kind": "period-doubling",
                                                     "points": [{"a": 0.1, "eta": 0.95}, {"a": 0.12, "eta": 1.05}]}]})}


def outcome(argv, folder, capsys, monkeypatch):
    """(exit code, stdout as scrubbed JSON or lines without clock figures, files written, stderr)."""
    folder.mkdir()
    for name, text in SEED_FILES.items():
        (folder / name).write_text(text)
    monkeypatch.chdir(folder)
    code, out, err = run_cli(list(argv), capsys)
    try:
        shown = _scrub(json.loads(out))
    except ValueError:
        shown = [line for line in out.splitlines() if " s" not in line and "wall" not in line]
    return code, shown, _files(folder), err


def _cases(commands):
    return [(c, o) for c in commands for o in DRIVE[c]]


#: options not driven here yet, each named (a new option must be driven or listed)
NOT_YET_DRIVEN = {}


def test_every_option_is_driven():
    """Each option of each command (argparse's tables) has its entry in DRIVE or is named in
    NOT_YET_DRIVEN, and no entry is stale."""
    table = command_options(build_parser())
    assert set(table) >= {"simulate", "map", "cosim", "fmu build"}
    for command, actions in table.items():
        names = {a.option_strings[-1] for a in actions if a.option_strings[-1] != "--version"}
        if not names:               # a group of commands (fmu, ssp)
            continue
        driven = set(DRIVE.get(command, {})) | NOT_YET_DRIVEN.get(command, set())
        assert command in DRIVE or command in NOT_YET_DRIVEN, command
        assert driven == names, (command, names ^ driven)


def _drive(command, option, tmp_path, capsys, monkeypatch):
    spec = DRIVE[command][option]
    base = BASE[command]
    if isinstance(spec, C):
        assert (command, option) in CONDITIONAL, (command, option)
        got = outcome(base + [option, spec.value], tmp_path / "opt", capsys, monkeypatch)
        assert got[0] in (0, 2, 4, 5) and "Traceback" not in got[3], (command, option, got)
        return
    if isinstance(spec, F):
        ref = outcome(base, tmp_path / "base", capsys, monkeypatch)
        plain = in_context(base, [f"~{option}"]) if option in base else base
        got = outcome(plain + [option, spec.name], tmp_path / "opt", capsys, monkeypatch)
        assert got[0] == ref[0] and spec.name in got[2] and spec.name not in ref[2], (command, option, got)
        return
    if spec.alone_refused:
        code, _, _, err = outcome(base + [option, *spec.value], tmp_path / "alone", capsys, monkeypatch)
        assert code == 2 and option in err, (command, option, code, err)
    context = in_context(base, spec.context)
    ref = outcome(base if spec.plain_reference else context, tmp_path / "base", capsys, monkeypatch)
    assert ref[0] in (0, 4, 5), (command, "base run", ref)
    got = outcome(context + [option, *spec.value], tmp_path / "opt", capsys, monkeypatch)
    if got[0] == 2:
        assert got[3].strip() and "Traceback" not in got[3], (command, option, got)
        return
    assert got[:3] != ref[:3], f"{command} {option} {' '.join(spec.value)}: accepted and changed nothing"


@pytest.mark.parametrize("command, option", _cases(FAST), ids=[f"{c} {o}" for c, o in _cases(FAST)])
def test_option_used_or_refused(command, option, tmp_path, capsys, monkeypatch):
    _drive(command, option, tmp_path, capsys, monkeypatch)


SLOW = [c for c in DRIVE if c not in FAST]


@pytest.mark.soak
@pytest.mark.slow
@pytest.mark.parametrize("command, option", _cases(SLOW), ids=[f"{c} {o}" for c, o in _cases(SLOW)])
def test_option_used_or_refused_slow(command, option, tmp_path, capsys, monkeypatch):
    _drive(command, option, tmp_path, capsys, monkeypatch)


@pytest.mark.parametrize("command", list(BASE))
def test_every_single_valued_option_given_twice_exits_2(command, capsys):
    """argparse keeps the last of a repeated option: each one (but the repeatable) refuses a second.
    One parser serves every parse (what an option saw is kept in the parse's namespace)."""
    parser = build_parser()
    for action in command_options(parser)[command]:
        option = action.option_strings[-1]
        if action.__class__.__name__ not in ("StoreOnce", "StoreTrueOnce"):
            assert option in ("--set", "--axis", "--step", "--version"), (command, option, action)
            continue
        value = ["1"] * (action.nargs if isinstance(action.nargs, int) else 1) if action.nargs != 0 else []
        if action.choices:
            value = [str(next(iter(action.choices)))]
        argv = command.split() + [option, *value, option, *value]
        with pytest.raises(SystemExit) as e:
            parser.parse_args(argv)
        assert e.value.code == 2
        assert f"{option} given twice" in capsys.readouterr().err, argv


#: the do-nothing combinations that were accepted silently (issue 33) and other members of the class
DO_NOTHING = [
    (["simulate", "--method", "rk4", "--rtol", "1e-6"], ["--rtol 1e-06", "rk4"]),
    (["simulate", "--steps-per-period", "10"], ["--steps-per-period 10", "adaptive"]),
    (["simulate", "--sample-dt", "0.1"], ["--sample-dt 0.1", "--csv"]),
    (["simulate", "--set", "a=0.1", "--set", "a=0.2"], ["--set a=0.2", "already set"]),
    (["optimize", "--bounds", "amplitude=1:2", "amplitude=2:3"], ["--bounds amplitude=2:3", "already given"]),
    (["optimize", "--fmu", "X.fmu"], ["--fmu X.fmu", "--confirm"]),
    (["optimize", "--confirm"], ["--confirm", "--string"]),
    (["optimize", "--margin", "0.2"], ["--margin 0.2", "--string"]),
    (["optimize", "--string", "lab", "--confirm", "--fmu", "notzip.fmu"], ["--fmu notzip.fmu"]),
    (["cosim", *LAB, "--stop", "1", "--adaptive"], ["--adaptive", "--step"]),
    (["cosim", *LAB, "--stop", "1", "--monolithic", "--tol", "1e-4"], ["--tol 0.0001", "--monolithic"]),
    (["cosim", *LAB, "--stop", "1", "--monolithic", "--scheme", "gauss-seidel"], ["--scheme gauss-seidel"]),
    (["modes", *LAB, "--wob", "1000"], ["--wob 1000", "--hammer-on-bottom"]),
    (["bifurcation", "--range", "0", "1", "--out", "x.png", "--periods", "10", "--keep", "20"], ["--keep 20"]),
    (["fmu", "build", "--runtime", "native", "--no-native-front"], ["--no-native-front", "native"]),
]


@pytest.mark.parametrize("argv, words", DO_NOTHING, ids=[" ".join(a) for a, _ in DO_NOTHING])
def test_do_nothing_combinations_exit_2_before_any_work(argv, words, tmp_path, capsys, monkeypatch):
    """Refused with the option, its value and why, before any work: the optimizer never starts
    (it would take seconds; the refusal comes from the checks before it)."""
    import hammerbit.studies.optimize as opt
    monkeypatch.setattr(opt, "optimize", lambda *a, **k: pytest.fail("the optimization started"))
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(argv, capsys)
    assert code == 2, (code, err)
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, (w, err)
    assert os.listdir(tmp_path) == []


def test_monolithic_csv_has_no_nan_column(tmp_path, capsys):
    """``cosim --monolithic --out``: every column is computed (hook_load, which the reference does not
    compute, is left out), and the columns are the co-simulation's but that one."""
    import numpy as np
    from hammerbit.cli.cosim_report import RECORD
    path = tmp_path / "m.csv"
    code, _, err = run_cli(["cosim", *LAB, "--stop", "0.05", "--monolithic", "--out", str(path)], capsys)
    assert code == 0, err
    header = path.read_text().splitlines()[0].split(",")
    names = [h.split(" [")[0] for h in header]
    assert names == ["time"] + [r for r in RECORD if r != "hook_load"]
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape[0] > 10 and np.isfinite(data).all()

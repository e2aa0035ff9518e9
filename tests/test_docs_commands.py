"""Every shell command in README.md and docs/*.md runs, with the exit code the docs annotate.

A command is a line (joined over ``\\`` continuations, without a ``$ ``
prompt) of a ```bash, ```sh, ```console or ```shell block, split at ``&&``.
Each runs with ``bash -c`` in a fresh directory that holds
``dist/HammerBitRock.fmu`` (and ``drilling.ssp`` where a command reads it),
with this environment's ``hammerbit``, ``python`` and fmpy first on the PATH.
It must exit 0, or the code its comment gives (``# exit 5: ...``).

Long commands run at reduced size (:data:`REDUCE`: fewer periods, cells or
seconds; the options and the path through the code stay).  Skipped, with the
reason (:data:`SKIP`): installing packages (``apt-get``, ``pip install``),
rewriting tracked files (``--update``), and the test suite itself.  The fast
set runs :data:`FAST`, a few cheap commands; the slow set runs every one.
"""
from __future__ import annotations

import os
import pathlib
import re
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
SHELL_FENCES = ("```bash", "```sh", "```console", "```shell")
EXIT = re.compile(r"#\s*exit\s+(\d+)\b")
#: commands not run, by a pattern of their text, with the reason
SKIP = [
    (re.compile(r"\bapt-get\b"), "installs system packages"),
    (re.compile(r"\bpip install\b"), "installs packages into the environment the tests run in"),
    (re.compile(r"--update\b"), "rewrites tracked files"),
    (re.compile(r"\bpytest\b"), "the test suite itself"),
]
#: (pattern, replacement) applied to a command before it runs: the same options at a smaller size
REDUCE = [
    (re.compile(r"--periods (\d+)"), lambda m: f"--periods {min(int(m.group(1)), 60)}"),
    (re.compile(r"--axis (\w+)=([-\d.e]+):([-\d.e]+):(\d+)"), lambda m: f"--axis {m.group(1)}={m.group(2)}:"
                                                                      f"{m.group(3)}:{min(int(m.group(4)), 3)}"),
    (re.compile(r"--num (\d+)"), lambda m: f"--num {min(int(m.group(1)), 3)}"),
    (re.compile(r"--bounds frequency=1\.0:2\.0 amplitude=3:30"), lambda m: m.group(0) + " --grid 3"),
    (re.compile(r"--frequencies ([\d.]+) ([\d.]+) (\d+)"), lambda m: f"--frequencies {m.group(1)} {m.group(2)} 2"),
    (re.compile(r"(cosim [^#]*--stop )(\d+)"), lambda m: m.group(1) + str(min(int(m.group(2)), 2))),
]
#: commands that read what the command before them in their block builds: the fixture that holds it
PREPARE = {"--interface-type ModelExchange": "built_native_fmu"}
#: a file a command reads that an earlier command of its document writes (``> FILE``): that one runs first
READS = re.compile(r"--overlay (\S+)")
#: cheap commands run in the fast set (documents' line numbers change; matched by text)
FAST = ("hammerbit simulate --preset paper-fig12 --set a=0.06 --method rk4",
        "hammerbit modes --string lab --count 8 --csv lab_modes.csv",
        "python -m fmpy validate dist/HammerBitRock.fmu")


def shell_commands():
    """``[(document, line, command, documented exit code or None)]`` of every shell block."""
    found = []
    for doc in DOCS:
        lines = doc.read_text(encoding="utf-8").splitlines()
        in_block, pending, start = False, "", 0
        for i, line in enumerate(lines, start=1):
            if line.startswith("```"):
                in_block = (not in_block) and line.strip() in SHELL_FENCES
                pending = ""
                continue
            if not in_block:
                continue
            if not pending:
                start = i
                line = line[2:] if line.startswith("$ ") else line
            text = pending + (line.lstrip() if pending else line)
            if text.rstrip().endswith("\\"):
                pending = text.rstrip()[:-1].rstrip() + " "
                continue
            pending = ""
            comment = EXIT.search(text)
            body = _without_comment(text)
            for part in body.split("&&"):
                if part.strip():
                    found.append((doc.name, start, part.strip(), int(comment.group(1)) if comment else None))
    return found


def _without_comment(text: str) -> str:
    """The command without its trailing ``# ...`` comment (a ``#`` inside quotes stays)."""
    quote = None
    for i, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1].isspace()):
            return text[:i].rstrip()
    return text.rstrip()


def reduced(command: str) -> str:
    for pattern, repl in REDUCE:
        command = pattern.sub(repl, command)
    return command


def skip_reason(command: str):
    return next((why for pattern, why in SKIP if pattern.search(command)), None)


def _ids(cmds):
    return [f"{d}:{line}: {c[:70]}" for d, line, c, _ in cmds]


def test_the_command_finder_on_a_made_up_document(tmp_path, monkeypatch):
    text = ("# t\n```bash\n$ hammerbit simulate --periods 5   # a comment\n"
            "hammerbit cosim --stop 2 \\\n    --json   # exit 5: above tol\n"
            "python -m pip install -e '.[test]' && hammerbit simulate --json\n```\n"
            "```python\nprint('no')\n```\n")
    doc = tmp_path / "t.md"
    doc.write_text(text)
    monkeypatch.setattr(sys.modules[__name__], "DOCS", [doc])
    assert shell_commands() == [("t.md", 3, "hammerbit simulate --periods 5", None),
                                ("t.md", 4, "hammerbit cosim --stop 2 --json", 5),
                                ("t.md", 6, "python -m pip install -e '.[test]'", None),
                                ("t.md", 6, "hammerbit simulate --json", None)]
    assert skip_reason("python -m pip install -e '.[test]'") and not skip_reason("hammerbit simulate --json")
    assert reduced("hammerbit map --axis a=0.05:0.25:81 --periods 300") == \
        "hammerbit map --axis a=0.05:0.25:3 --periods 60"
    assert reduced("hammerbit cosim --string x --stop 20 --json") == "hammerbit cosim --string x --stop 2 --json"


def test_every_document_has_its_commands_found():
    cmds = shell_commands()
    assert {d for d, *_ in cmds} >= {"README.md", "cli.md", "cosim.md", "drillstring.md", "fmu.md", "model.md"}
    assert all(any(c == f for _, _, c, _ in cmds) for f in FAST), "a FAST command is no longer in the docs"


def _producer(doc, line, command):
    """(command, code) of the last command of ``doc`` before ``line`` that writes the file ``command`` reads."""
    m = READS.search(command)
    if not m:
        return None
    writes = re.compile(r">\s*" + re.escape(m.group(1)) + r"(\s|$)")
    return next(((c, k) for d, n, c, k in reversed(shell_commands()) if d == doc and n < line and writes.search(c)),
                None)


def _run(doc, line, command, code, tmp_path, request):
    why = skip_reason(command)
    if why:
        pytest.skip(why)
    (tmp_path / "dist").mkdir()
    if "HammerBitRock.fmu" in command or "fmu build" in command:
        shutil.copy(request.getfixturevalue("built_fmu"), tmp_path / "dist" / "HammerBitRock.fmu")
    if "drilling.ssp" in command and "ssp build" not in command:
        shutil.copy(request.getfixturevalue("built_ssp"), tmp_path / "drilling.ssp")
    if "docs/figures" in command:
        (tmp_path / "docs" / "figures").mkdir(parents=True)
    for words, fixture in PREPARE.items():
        if words in command:
            shutil.copy(request.getfixturevalue(fixture), tmp_path / "dist" / "HammerBitRock.fmu")
    if "libcosimpy" in command:
        pytest.importorskip("libcosimpy")
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""),
               MPLBACKEND="Agg")
    first = _producer(doc, line, command)
    if first:
        r = subprocess.run(["bash", "-c", reduced(first[0])], cwd=tmp_path, capture_output=True, text=True,
                           timeout=1800, env=env)
        assert r.returncode == (0 if first[1] is None else first[1]), (doc, first[0], r.returncode, r.stderr[-3000:])
    r = subprocess.run(["bash", "-c", reduced(command)], cwd=tmp_path, capture_output=True, text=True,
                       timeout=1800, env=env)
    assert "Traceback" not in r.stderr, (doc, command, r.stderr[-3000:])
    assert r.returncode == (0 if code is None else code), (doc, command, r.returncode, r.stderr[-3000:])


def _first_of_each(commands):
    """``commands`` with each command text only at its first place (the same words in another
    document run the same way: their second run belongs to the soak set)."""
    seen = set()
    return [c for c in commands if not (c[2] in seen or seen.add(c[2]))]


FAST_CMDS = _first_of_each([c for c in shell_commands() if c[2] in FAST])


@pytest.mark.parametrize("doc, line, command, code", FAST_CMDS, ids=_ids(FAST_CMDS))
def test_documented_command_runs(doc, line, command, code, tmp_path, request):
    _run(doc, line, command, code, tmp_path, request)


SLOW_CMDS = [c for c in shell_commands() if c not in FAST_CMDS]


@pytest.mark.soak
@pytest.mark.slow
@pytest.mark.parametrize("doc, line, command, code", SLOW_CMDS, ids=_ids(SLOW_CMDS))
def test_documented_command_runs_slow(doc, line, command, code, tmp_path, request):
    _run(doc, line, command, code, tmp_path, request)


def test_the_transient_example_of_model_md():
    """docs/model.md, "transient": paper-fig12 at a = 0.089 has no period over the last half of 300
    periods and is flagged transient, its last quarter showing P2 (only what the run saw); at 1000
    periods it is P1 and not flagged.
    At a = 0.05 it is P3, not transient."""
    from hammerbit.model.presets import preset
    from hammerbit.scene.analysis import detect_period
    from hammerbit.scene.simulate import Record, simulate
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    assert "`paper-fig12` at `a = 0.089`" in text
    g = preset("paper-fig12").replace(a=0.089)
    short = simulate(g, 300, record=Record(poincare=True))
    assert detect_period(short.poincare) is None and short.flags.transient
    assert short.flags.settling_period == 2
    long = simulate(g, 1000, record=Record(poincare=True))
    assert detect_period(long.poincare) == 1 and not long.flags.transient
    p3 = simulate(preset("paper-fig12").replace(a=0.05), 300, record=Record(poincare=True))
    assert detect_period(p3.poincare) == 3 and not p3.flags.transient


# --------------------------------------------------------------------------- docs/fmu.md: statements and tests
TEST_REF = re.compile(r"`(tests/test_\w+\.py)::(test_\w+)`")


def statement_table(doc=ROOT / "docs" / "fmu.md"):
    """``[(statement, [(file, test name), ...])]`` of the table under "Where each statement is tested"."""
    text = doc.read_text(encoding="utf-8")
    section = text.split("## Where each statement is tested", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 2 and cells[0] not in ("statement", "---"):
            rows.append((cells[0], TEST_REF.findall(cells[1])))
    return rows


def test_every_row_of_the_fmu_statement_table_names_a_test():
    rows = statement_table()
    assert len(rows) >= 25
    for statement, refs in rows:
        assert refs, f"docs/fmu.md: {statement!r} names no test"
        for path, name in refs:
            source = (ROOT / path).read_text(encoding="utf-8") if (ROOT / path).exists() else ""
            assert re.search(rf"^def {name}\(", source, re.M), f"docs/fmu.md: {statement!r}: no {path}::{name}"


def test_the_statement_table_checker_catches_a_missing_test(tmp_path):
    doc = tmp_path / "fmu.md"
    doc.write_text("## Where each statement is tested\n\n| statement | test |\n|---|---|\n"
                   "| a | `tests/test_fmu.py::test_no_such_test` |\n| b | no test |\n\n## Next\n")
    rows = statement_table(doc)
    assert rows == [("a", [("tests/test_fmu.py", "test_no_such_test")]), ("b", [])]
    source = (ROOT / "tests" / "test_fmu.py").read_text(encoding="utf-8")
    assert not re.search(r"^def test_no_such_test\(", source, re.M)


def test_after_fmi2_error_only_reset_set_state_and_free_remain(built_fmu):
    """FMI 2.0, 2.1.3: after fmi2Error the simulation goes on only through fmi2SetFMUstate or fmi2Reset
    (or ends with fmi2FreeInstance); inquiries still answer. docs/fmu.md, "Statuses and errors"."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(str(built_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    where = extract(str(built_fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=where, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="after-error")
    s.instantiate()
    try:
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        for k in range(10):
            s.doStep(k * 1e-3, 1e-3)
        saved = s.getFMUstate()
        x = s.getReal([vr["bit_position"]])
        with pytest.raises(Exception, match="status 3"):
            s.doStep(0.5, 1e-3)                         # not the FMU's time: fmi2Error
        assert s.getReal([vr["bit_position"]]) == x     # an inquiry answers; nothing changed
        for call in (lambda: s.doStep(1e-2, 1e-3), s.terminate):
            with pytest.raises(Exception, match="status 3"):
                call()
        s.setFMUstate(saved)                            # goes on from the saved state
        s.doStep(1e-2, 1e-3)
        with pytest.raises(Exception, match="status 3"):
            s.doStep(0.5, 1e-3)
        s.reset()                                       # or from the start
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        s.doStep(0.0, 1e-3)
        s.freeFMUstate(saved)
        s.terminate()
    finally:
        s.freeInstance()

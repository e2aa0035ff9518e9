"""The slow set's table (``SLOW_TESTS`` in tests/conftest.py): each test it moves out of the fast
set exists, and its named twin exists and stays in the fast set.

The node ids come from this session's collection when it saw every file the table names (the
README's test command collects them all), else from ``pytest --collect-only`` of those files."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import conftest

ROOT = Path(__file__).resolve().parent.parent


def _file(nodeid: str) -> str:
    return nodeid.split("::")[0]


def _collected(files) -> dict:
    """``{node id: slow?}`` of every test in ``files``."""
    if all(any(_file(n) == f for n in conftest.COLLECTED) for f in files):
        return dict(conftest.COLLECTED)
    out = {}
    for marks, slow in (("not slow", False), ("slow", True)):
        r = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-n", "0", "-p",
                            "no:cacheprovider", "-m", marks, *sorted(files)],
                           cwd=ROOT, capture_output=True, text=True, timeout=600)
        ids = [line for line in r.stdout.splitlines() if "::" in line]
        assert r.returncode in (0, 5) and ids, r.stdout[-2000:] + r.stderr[-2000:]
        out.update(dict.fromkeys(ids, slow))
    return out


def _matches(name: str, collected: dict) -> list:
    """The collected node ids ``name`` stands for (itself, or every case of a parametrised test)."""
    return [n for n in collected if n == name or n.split("[")[0] == name]


def test_every_slow_test_has_a_twin_in_the_fast_set():
    table = conftest.SLOW_TESTS
    collected = _collected({_file(n) for pair in table.items() for n in pair})
    problems = []
    for slow, twin in table.items():
        moved = _matches(slow, collected)
        if not moved:
            problems.append(f"{slow}: no such test")
        elif not all(collected[n] for n in moved):
            problems.append(f"{slow}: still in the fast set")
        kept = [n for n in _matches(twin, collected) if not collected[n]]
        if not kept:
            problems.append(f"{slow}: its twin {twin} is not a test of the fast set")
    assert not problems, "\n".join(problems)

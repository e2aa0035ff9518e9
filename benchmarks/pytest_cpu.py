"""A pytest plugin for the tests benchmark: the CPU time of each test, its own and its subprocesses'.

Wall time per test misleads on two cores: it counts the other worker's load and
the machine's.  Loaded with ``-p benchmarks.pytest_cpu`` and ``HAMMERBIT_TEST_CPU_DIR``
set, each test process (every pytest-xdist worker) writes one tab-separated row
per test to ``cpu-<pid>.tsv`` in that directory: its own CPU seconds (user +
system, ``getrusage(RUSAGE_SELF)``), its children's (``RUSAGE_CHILDREN``: the
subprocesses it waited for), and its node id.  Setup and teardown count with
the test, so a fixture's cost lands on the first test that uses it.
:func:`summarise` reads the rows back.
"""
from __future__ import annotations

import os
import resource
from pathlib import Path

import pytest

#: the environment variable naming the directory the rows go to (the plugin does nothing without it)
DIR_VARIABLE = "HAMMERBIT_TEST_CPU_DIR"
_OUT = {}


def _cpu(who) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    directory = os.environ.get(DIR_VARIABLE)
    if not directory:
        yield
        return
    own, children = _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN)
    yield
    if "file" not in _OUT:
        _OUT["file"] = open(Path(directory) / f"cpu-{os.getpid()}.tsv", "a", encoding="utf-8")
    _OUT["file"].write(f"{_cpu(resource.RUSAGE_SELF) - own:.4f}\t{_cpu(resource.RUSAGE_CHILDREN) - children:.4f}"
                       f"\t{item.nodeid}\n")
    _OUT["file"].flush()


def summarise(directory, total_cpu_s: float, most: int = 15) -> dict:
    """The rows of ``directory`` against the run's ``total_cpu_s``: the seconds inside tests (own
    and subprocesses), outside them (starting, collecting, shutting down the processes) and the
    ``most`` tests of the largest CPU time."""
    rows = []
    for path in sorted(Path(directory).glob("cpu-*.tsv")):
        for line in path.read_text(encoding="utf-8").splitlines():
            own, children, test = line.split("\t", 2)
            rows.append((float(own), float(children), test))
    own = sum(r[0] for r in rows)
    children = sum(r[1] for r in rows)
    top = sorted(rows, key=lambda r: r[0] + r[1], reverse=True)[:most]
    return {"tests": len(rows), "in_tests_own_s": own, "in_tests_subprocesses_s": children,
            "outside_tests_s": total_cpu_s - own - children,
            "largest": [{"cpu_s": o + c, "own_s": o, "subprocesses_s": c, "test": t} for o, c, t in top]}

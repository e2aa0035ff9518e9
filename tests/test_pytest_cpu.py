"""The tests benchmark's CPU plugin (benchmarks/pytest_cpu.py): rows written per test, summed back.

The plugin runs in a pytest of its own on two made-up tests: one that spends CPU itself, one
whose subprocess does; the rows say which, and the summary's parts add up to the total given.
"""
import subprocess
import sys
import textwrap

from benchmarks import REPO_ROOT
from benchmarks.pytest_cpu import DIR_VARIABLE, summarise

#: the made-up tests' pytest: no installed plugin but this one (xdist, hypothesis ...: seconds of imports)
ENV = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(REPO_ROOT), "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"}

_TESTS = textwrap.dedent('''
    import subprocess, sys, time

    def _spin(seconds):
        end = time.process_time() + seconds
        while time.process_time() < end:
            pass

    def test_own():
        _spin(0.3)

    def test_child():
        subprocess.run([sys.executable, "-c",
                        "import time\\nend = time.process_time() + 0.3\\nwhile time.process_time() < end: pass"],
                       check=True)
''')


def _run_made_up(tmp_path, tests: str, env: dict) -> None:
    """Run ``tests`` as the only test file of a pytest of its own in ``tmp_path``, with the plugin."""
    (tmp_path / "pytest.ini").write_text("[pytest]\n")         # not this repository's configuration
    (tmp_path / "test_made_up.py").write_text(tests)
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "benchmarks.pytest_cpu",
                        "test_made_up.py"],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


def test_each_test_gets_its_own_and_its_subprocesses_cpu(tmp_path):
    rows = tmp_path / "rows"
    rows.mkdir()
    _run_made_up(tmp_path, _TESTS, dict(ENV, **{DIR_VARIABLE: str(rows)}))
    got = summarise(rows, total_cpu_s=5.0, most=2)
    by_name = {row["test"].split("::")[-1]: row for row in got["largest"]}
    assert got["tests"] == 2
    assert by_name["test_own"]["own_s"] >= 0.3 and by_name["test_own"]["subprocesses_s"] < 0.1
    assert by_name["test_child"]["subprocesses_s"] >= 0.3 and by_name["test_child"]["own_s"] < 0.2
    assert abs(got["in_tests_own_s"] + got["in_tests_subprocesses_s"] + got["outside_tests_s"] - 5.0) < 1e-9


def test_without_its_directory_the_plugin_writes_nothing(tmp_path):
    _run_made_up(tmp_path, "def test_nothing():\n    pass\n", ENV)
    assert list(tmp_path.rglob("cpu-*.tsv")) == []

"""The figure worker draws what this process would draw, reports its errors, and never decides an outcome.

Oracle: the same drawing function run in this process (the file must be the
same byte for byte); the exceptions the function raises here.
"""
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from hammerbit.scene import figure_worker
from hammerbit.scene.figure_worker import figure_formats
from hammerbit.model.presets import preset
from hammerbit.scene.plots import scene_figure
from hammerbit.scene.figure import draw_scene
from cli_run import run_cli


@pytest.fixture(scope="module")
def scene():
    return scene_figure(preset("paper-fig9").replace(a=0.083), 40, preset="paper-fig9")


@pytest.fixture(autouse=True)
def _on(monkeypatch):
    """The worker on, although this process has imported matplotlib (where it is off by default)."""
    monkeypatch.setattr(figure_worker, "enabled", lambda: True)


def test_worker_saves_what_this_process_saves_and_raises_what_it_raises(scene, tmp_path):
    with pytest.raises(FileNotFoundError) as here:
        draw_scene(scene, tmp_path / "missing" / "x.png")
    with figure_worker.start() as w:
        assert w.formats() == figure_formats()
        assert w.draw(draw_scene, scene, tmp_path / "missing" / "x.png")
        with pytest.raises(FileNotFoundError) as there:
            w.result()
    assert str(there.value) == str(here.value)


def test_a_worker_that_dies_without_an_answer_leaves_the_drawing_to_the_caller():
    w = figure_worker.start()
    assert w.draw(os._exit, 3)  # the worker ends without answering
    assert w.result() is None
    assert w._proc.returncode == 3


def test_a_caller_that_fails_first_does_not_wait_for_the_worker(capsys, monkeypatch):
    """Bad input found after the worker started: the worker is stopped, not waited for."""
    started, real_start = [], figure_worker.start

    def start():
        started.append(real_start())
        return started[-1]

    monkeypatch.setattr(figure_worker, "start", start)
    code, _, err = run_cli(["simulate", "--set", "a=abc", "--plot", "x.png"], capsys)
    assert code == 2 and "a=abc" in err
    assert len(started) == 1 and started[0]._proc.returncode == -signal.SIGTERM


@pytest.mark.parametrize("env, cores, matplotlib_loaded, on", [
    ("1", 2, False, True), ("0", 2, False, False), ("1", 1, False, False), ("1", 2, True, False)])
def test_on_only_where_it_can_save_time(env, cores, matplotlib_loaded, on, monkeypatch):
    monkeypatch.undo()  # the real enabled()
    monkeypatch.setenv(figure_worker.ENV, env)
    monkeypatch.setattr(os, "cpu_count", lambda: cores)
    if not matplotlib_loaded:
        monkeypatch.delitem(sys.modules, "matplotlib", raising=False)
    else:
        import matplotlib  # noqa: F401
    assert figure_worker.enabled() is on


def test_simulate_plot_is_the_same_with_and_without_the_worker(tmp_path, capsys, monkeypatch):
    argv = ["simulate", "--preset", "paper-fig9", "--set", "a=0.083", "--periods", "40", "--plot"]
    assert run_cli(argv + [str(tmp_path / "with.png")], capsys)[0] == 0
    monkeypatch.setenv(figure_worker.ENV, "0")
    assert run_cli(argv + [str(tmp_path / "without.png")], capsys)[0] == 0
    assert (tmp_path / "with.png").read_bytes() == (tmp_path / "without.png").read_bytes()


def test_the_parser_loads_neither_numba_nor_matplotlib():
    """Every command builds the whole parser: it must not pay for the solver or the plots."""
    code = textwrap.dedent("""
        import sys
        from hammerbit.cli.main import build_parser
        build_parser()
        print(sorted(m for m in ("numba", "matplotlib", "scipy") if m in sys.modules))
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_a_function_keeps_its_name_in_the_string_package_whatever_loads_first():
    """``modes`` and ``state_space`` are functions and submodules; the package's name is the function."""
    code = textwrap.dedent("""
        import types
        import hammerbit.drillstring.state_space       # loads the submodules modes and state_space
        import hammerbit.drillstring as d
        print(type(d.modes).__name__, type(d.state_space).__name__, d.modes.__module__)
        print(all(hasattr(d, n) for n in d.__all__))
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["function", "function", "hammerbit.drillstring.modes", "True"]


def test_scene_figure_data_is_the_scene_in_si():
    """The panels' data: the last periods in seconds, the bit never moving back, mm of the rig's x0."""
    g = preset("paper-fig12").replace(a=0.06)
    d = scene_figure(g, 40, last=5, preset="paper-fig12")
    T = g.period_s
    assert d.time_s[0] == pytest.approx(35 * T) and d.time_s[-1] == pytest.approx(40 * T)
    assert np.all(np.diff(d.bit_mm) >= -1e-12)            # the bit only drifts forward (v_s >= 0)
    assert np.allclose(d.relative_mm, d.hammer_mm - d.bit_mm)
    assert d.gap_mm == pytest.approx(g.r * g.scales.length * 1e3)
    assert len(d.section_mm) == 41 - 41 // 2               # Poincaré points at t = 0, T, ..., 40 T
    assert 0 < len(d.window_points_mm) <= 6
    assert "paper-fig12" in d.title and "period" in d.title

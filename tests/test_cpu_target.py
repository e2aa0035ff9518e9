"""An FMU master selects the FMU's portable CPU target before numba loads, and the FMU then compiles nothing.

Oracle: numba's own configuration in a fresh process, and the user cache the
FMU compiles into when it cannot load the kernels it ships (it must stay empty).
"""
import os
import subprocess
import sys
import textwrap

import pytest

_SELECT = textwrap.dedent("""
    import os, sys
    from hammerbit.model.numba_target import select_portable, runs_portable
    chose = select_portable()
    import numba
    print(chose, runs_portable(), numba.config.CPU_NAME, os.environ.get("NUMBA_CPU_NAME"))
""")


def _env(**extra):
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
    env.update(extra)
    return env


@pytest.mark.parametrize("preset_cpu, expected", [
    (None, "True True generic generic"),
    ("skylake", "False False skylake skylake"),      # the user's choice is kept
])
def test_select_portable_before_numba(preset_cpu, expected):
    env = _env(**({"NUMBA_CPU_NAME": preset_cpu} if preset_cpu else {}))
    r = subprocess.run([sys.executable, "-c", _SELECT], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == expected.split()


def test_select_portable_after_numba_changes_nothing():
    code = "import numba\n" + _SELECT
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=120)
    assert r.returncode == 0, r.stderr
    chose, runs, cpu, env_cpu = r.stdout.split()
    assert (chose, runs, env_cpu) == ("False", "False", "None") and cpu != "generic"


def test_cosim_through_the_fmu_loads_the_kernels_it_ships(built_fmu, tmp_path):
    """``hammerbit cosim --fmu``: no compile notice, no hammer kernel compiled into an empty user cache
    (the string side's own exact step, ``hammerbit.model.string_step``, is the master's to compile)."""
    cache = tmp_path / "cache"
    r = subprocess.run([sys.executable, "-m", "hammerbit", "cosim", "--string", "field-2200m", "--fmu",
                        str(built_fmu), "--stop", "0.05", "--step", "5e-4", "--json"],
                       capture_output=True, text=True, env=_env(HAMMERBIT_CACHE_DIR=str(cache)), timeout=600)
    assert r.returncode == 0, r.stderr
    assert "compiling" not in r.stderr
    compiled = sorted(p.name for p in cache.iterdir()) if cache.exists() else []
    assert not [n for n in compiled if n.startswith("hammerbit.model.kernel_")], compiled


def test_a_study_worker_of_an_fmu_master_compiles_nothing_at_start(tmp_path):
    """Dask workers of ``sweep --fmu`` inherit the portable target; with nothing compiled for it,
    their start-up warm-up loads no in-process solver (a sweep through the FMU never runs it)."""
    code = textwrap.dedent("""
        from hammerbit.model.numba_target import select_portable
        assert select_portable()
        from hammerbit.studies.executor import warm_worker
        from hammerbit.model import kernel_driver
        print(warm_worker(), len(kernel_driver.advance_hammer.signatures))
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env=_env(HAMMERBIT_CACHE_DIR=str(tmp_path)), timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["ok", "0"] and "compiling" not in r.stderr

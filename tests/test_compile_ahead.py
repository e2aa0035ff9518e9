"""The first compile on two cores (``numba_compile_ahead``): its plan, its guards, and a cache it leaves whole."""
import importlib
import inspect
import json
import os
import pickle
import subprocess
import sys

import numba
import pytest

from hammerbit.model import numba_cache, numba_compile_ahead as compile_ahead


def test_the_shipped_plan_is_for_these_kernels_and_this_numba():
    """Regenerate with ``python -m hammerbit.model.numba_compile_plan --record`` after a kernel change."""
    with open(compile_ahead.PLAN_FILE, "rb") as fh:
        plan = pickle.load(fh)
    assert plan["numba"] == numba.__version__
    assert plan["digest"] == numba_cache.kernels_digest(), "stale plan: re-record it"
    assert set(plan["entries"]) == {"advance_hammer", "advance"}
    for items in plan["entries"].values():
        assert len(items) > 20
        for module, name, sig in items:
            disp = getattr(importlib.import_module(f"hammerbit.model.{module}"), name)
            assert isinstance(disp, numba.core.registry.CPUDispatcher)
            assert len(sig) == len(inspect.signature(disp.py_func).parameters), name


def test_a_stale_plan_is_ignored(monkeypatch):
    assert compile_ahead.plan_for("advance_hammer")
    monkeypatch.setattr(numba_cache, "kernels_digest", lambda: "other kernels")
    assert compile_ahead.plan_for("advance_hammer") is None
    assert compile_ahead.start("advance_hammer") is False


def test_no_helper_when_disabled(monkeypatch):
    monkeypatch.setattr(compile_ahead, "ENABLED", False)
    assert compile_ahead.start("advance_hammer") is False
    assert not compile_ahead.running()


def test_the_fmu_runtime_starts_no_helper():
    code = ("import hammerbit.model.slave, hammerbit.model.numba_compile_ahead as c; print(c.ENABLED)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "False"


_SCENE = r"""
import json, sys
from hammerbit.model import kernel_layouts, numba_cache, numba_compile_ahead as compile_ahead
from hammerbit.model.presets import preset
from hammerbit.model.stepping import Stepper
g = preset("paper-fig9").replace(a=0.083)
st = Stepper(g)
started = []
real = compile_ahead.start
compile_ahead.start = lambda entry: started.append(real(entry)) or started[-1]
st.advance(60 * g.period)
print(json.dumps({"y": st.y.tolist(), "steps": int(st.istate[kernel_layouts.I_STEPS]), "helper": started,
                  "counts": numba_cache.kernel_cache_counts(), "running": compile_ahead.running()}))
"""


@pytest.mark.slow
def test_a_cold_compile_with_the_helper_leaves_a_whole_cache_and_the_same_results(tmp_path):
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=str(tmp_path / "cache"))

    def run():
        r = subprocess.run([sys.executable, "-c", _SCENE], capture_output=True, text=True, env=env, timeout=600)
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout.strip().splitlines()[-1])

    cold = run()
    assert cold["helper"] == [True]          # a helper ran beside the compile
    assert not cold["running"]               # and was ended when the compile was done
    warm = run()
    assert warm["helper"] == []              # nothing to compile: no notice, no helper
    assert warm["counts"][1] == 0            # every kernel came from the cache
    assert warm["y"] == cold["y"] and warm["steps"] == cold["steps"]

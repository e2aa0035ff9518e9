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

from hammerbit.model import numba_compile_ahead as compile_ahead


def test_the_shipped_plan_is_for_these_kernels_and_this_numba():
    """Regenerate with ``python -m hammerbit.model.numba_compile_plan --record`` after a change of a
    kernel's signature or a numba upgrade: every entry names a kernel with its argument count."""
    with open(compile_ahead.PLAN_FILE, "rb") as fh:
        plan = pickle.load(fh)
    assert plan["numba"] == numba.__version__
    assert set(plan["entries"]) == {"advance_hammer", "advance_dp54", "advance_rk4", "advance"}
    for items in plan["entries"].values():
        assert len(items) > 20
        for module, name, sig in items:
            disp = getattr(importlib.import_module(f"hammerbit.model.{module}"), name)
            assert isinstance(disp, numba.core.registry.CPUDispatcher)
            assert len(sig) == len(inspect.signature(disp.py_func).parameters), name


def test_a_plan_for_another_numba_is_ignored(monkeypatch):
    assert compile_ahead.plan_for("advance_hammer")
    monkeypatch.setattr(numba, "__version__", "0.0.0")
    assert compile_ahead.plan_for("advance_hammer") is None
    assert compile_ahead.start("advance_hammer") is False


def test_plan_entries_of_a_changed_kernel_are_skipped(monkeypatch, tmp_path):
    """An entry whose function is gone or takes another number of arguments is dropped; the rest stays."""
    with open(compile_ahead.PLAN_FILE, "rb") as fh:
        plan = pickle.load(fh)
    items = plan["entries"]["advance_hammer"]
    module, name, sig = items[0]
    plan["entries"]["advance_hammer"] = [(module, "no_such_kernel", sig), (module, name, sig + sig[:1]),
                                         ("numba_cache", "kernels_digest", ())] + items[1:]
    path = tmp_path / "plan.pkl"
    path.write_bytes(pickle.dumps(plan))
    monkeypatch.setattr(compile_ahead, "PLAN_FILE", str(path))
    assert compile_ahead.plan_for("advance_hammer") == items[1:]


def test_no_helper_when_disabled(monkeypatch):
    monkeypatch.setattr(compile_ahead, "ENABLED", False)
    assert compile_ahead.start("advance_hammer") is False
    assert not compile_ahead.running()


def test_the_fmu_runtime_starts_no_helper_and_leaves_the_switch_alone():
    """The FMU's stepper asks for no helper; importing the FMU runtime changes nothing for the process."""
    code = ("import hammerbit.model.slave as s, hammerbit.model.numba_compile_ahead as c; "
            "f = s.HammerBitRock(instance_name='x'); f.setup_experiment(0.0); f.exit_initialization_mode(); "
            "print(c.ENABLED, f._st.compile_helper)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "True False"


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

"""The string's dense linear algebra runs on one BLAS thread, from the first call in a process.

threadpoolctl limits the BLAS libraries that are loaded when the limit is set; scipy's is loaded
with ``scipy.linalg``, which the library imports where it needs it.  If the limit came first, the
first eigenproblem of a process ran on every core and gave other bits than the later ones (5e-17
in the field string's matrix, 4e-14 in DrillingSystem.fmu's modal form: two builds of one FMU in
one process differed).  Both checks run in a fresh interpreter, where nothing has loaded scipy yet.
"""
import hashlib
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

#: the variables that set a BLAS library's threads at its load
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
needs_two_cores = pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: one BLAS thread anyway")


def _fresh(code: str) -> str:
    """Standard output of ``code`` run by a new interpreter that can import this module, with
    the BLAS libraries' own thread counts (conftest sets one thread for the tests)."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, (os.path.dirname(__file__), os.environ.get("PYTHONPATH"))))
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=600,
                       env=env)
    assert r.returncode == 0, r.stderr
    return r.stdout


@needs_two_cores
def test_a_blas_loaded_inside_the_limit_runs_one_thread():
    out = _fresh("""
        import sys
        from hammerbit.model.string_step import one_blas_thread
        from threadpoolctl import threadpool_info
        assert "scipy.linalg" not in sys.modules
        with one_blas_thread():
            import scipy.linalg                      # as a body would, where it needs it
            threads = {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}
        print(len(threads), max(threads.values()))
    """)
    count, most = map(int, out.split())
    assert count >= 1 and most == 1, out


def _string_matrix_digest() -> str:
    from hammerbit.cosim.config import CosimConfig, field_hammer
    from hammerbit.cosim.string_side import StringSide
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    cfg = CosimConfig(rig=field_hammer(), top=TopCondition.parse("auto-driller"))
    return hashlib.sha256(np.ascontiguousarray(StringSide(load_string("field-2200m"), cfg).A1).tobytes()).hexdigest()


@needs_two_cores
def test_the_first_string_side_of_a_process_has_the_bits_of_every_later_one():
    """The field string's closed-loop matrix: the first of a fresh process, its second, and this
    process's (where scipy is long loaded) are one array, bit for bit."""
    out = _fresh("""
        from test_blas_threads import _string_matrix_digest
        print(_string_matrix_digest(), _string_matrix_digest())
    """)
    first, second = out.split()
    assert first == second == _string_matrix_digest()

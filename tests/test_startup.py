"""Loading the kernels does not import scipy.linalg, and numba's BLAS-backed functions still work.

The kernels hold ``scipy.linalg`` back while numba's ``arraymath`` loads and set its BLAS flag
themselves (``fmu_src/numba_startup.py``).  The fast test checks that flag against numba's own
probe, run afterwards in the same process; the slow one compiles ``np.correlate``, which the flag
steers to BLAS.
"""
import subprocess
import sys
import textwrap

_LOAD = """
    import sys
    import numpy as np
    from hammerbit.model.presets import preset
    from hammerbit.model.stepping import Stepper
    g = preset("paper-fig9")
    Stepper(g).advance(g.period)
    print("linalg_after_kernels", "scipy.linalg" in sys.modules)
"""


def _run(code: str) -> str:
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(_LOAD) + textwrap.dedent(code)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "linalg_after_kernels False" in r.stdout
    return r.stdout


def test_kernels_load_without_scipy_linalg_and_the_blas_flag_is_numbas_own():
    out = _run("""
        import numba.np.arraymath as am
        flag = am._HAVE_BLAS
        print("blas_flag", flag, "probe", am._check_blas())     # numba's probe imports scipy.linalg now
        import scipy.linalg.cython_blas
        print("linalg_importable", "scipy.linalg" in sys.modules)
    """)
    assert "blas_flag True probe True" in out, out
    assert "linalg_importable True" in out


def test_kernels_load_without_scipy_linalg_and_blas_functions_still_compile():
    out = _run("""
        import numba
        @numba.njit
        def corr(a, b):
            return np.correlate(a, b)
        a = np.array([1.0, 2.0, 3.0]); b = np.array([0.5, -1.0])
        print("correlate_ok", bool(np.allclose(corr(a, b), np.correlate(a, b))))
    """)
    assert "correlate_ok True" in out

"""Loading the kernels does not import scipy.linalg, and numba's BLAS-backed functions still work."""
import subprocess
import sys
import textwrap


def test_kernels_load_without_scipy_linalg_and_blas_functions_still_compile():
    code = textwrap.dedent("""
        import sys
        import numpy as np
        from hammerbit.model.params import preset
        from hammerbit.model.stepping import Stepper
        g = preset("paper-fig9")
        Stepper(g).advance(g.period)
        print("linalg_after_kernels", "scipy.linalg" in sys.modules)
        import numba
        @numba.njit
        def corr(a, b):
            return np.correlate(a, b)
        a = np.array([1.0, 2.0, 3.0]); b = np.array([0.5, -1.0])
        print("correlate_ok", bool(np.allclose(corr(a, b), np.correlate(a, b))))
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "linalg_after_kernels False" in r.stdout
    assert "correlate_ok True" in r.stdout

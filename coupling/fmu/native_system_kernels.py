"""DrillingSystem.fmu's numba kernels as C entry points: the driver with a linear subsystem at run time.

The native ``DrillingSystem.fmu`` integrates the hammer, the bit and the string
(with its top condition) as one hybrid system, the way the co-simulation's
reference does (:func:`hammerbit.cosim.reference.monolithic`): the string and
the interface spring are the linear subsystem of the library's driver
:func:`hammerbit.model.kernel_driver.advance`.  Here the driver is bound to
DOP853 (``numba_partial.bind``, as ``advance_hammer`` is) and the subsystem
stays an argument, so the FMU passes its own matrices (CSR) from C; the
objects are emitted by :mod:`hammerbit.fmu.native_kernels` (kernel set
``system``).
"""
from __future__ import annotations

__all__ = ["SYSTEM_ENTRY_POINTS", "compile_system_entry_points"]

#: C names of the entry points and their C prototypes (model_system.h declares the same)
SYSTEM_ENTRY_POINTS = {
    "hsys_advance": "int64_t hsys_advance(double *y, int64_t *ist, double *fst, double tau_end, double *p, "
                    "double *opts, int64_t nz, int64_t *csr, double *lin, double *H)",
    "hsys_forces": "int64_t hsys_forces(double *y, int64_t *ist, double *p, double *out)",
}


def compile_system_entry_points() -> dict:
    """``{C name: numba cfunc}`` of :data:`SYSTEM_ENTRY_POINTS` (compiles them in this process)."""
    import numpy as np
    from numba import carray, cfunc, njit
    from numba.core.types import CPointer, float64, int64

    from hammerbit.fmu.native_forces import forces_entry_point
    from hammerbit.model import kernel_driver as KD
    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model import tableaux
    from hammerbit.model.numba_partial import bind

    f64p, i64p = CPointer(float64), CPointer(int64)
    NI, NF, NO, N_P = KL.N_ISTATE, KL.N_FSTATE, KL.N_OPTS, KL.N_P
    NS, NL = KL.N_SAMPLE_COLS, KL.N_LOG_COLS
    advance_system = njit(nogil=True)(bind(KD.advance, "advance_system", method=tableaux.METHODS["dop853"]))

    @cfunc(int64(f64p, i64p, f64p, float64, f64p, f64p, int64, i64p, f64p, f64p))
    def hsys_advance(yp, ip, fp, tau_end, pp, op, nz, csrp, linp, hp):
        # csr: the row pointers (nz + 1) then the column indices (nnz) of A; lin: A's values (nnz),
        # G (nz), g (2); H (nz x 2, row-major).  y holds x1..x4 then the nz subsystem states.
        ap = carray(csrp, (nz + 1,))
        nnz = ap[nz]
        ai = carray(csrp, (nz + 1 + nnz,))[nz + 1:]
        lin = carray(linp, (nnz + nz + 2,))
        sub = (nz, 0, ap, ai, lin[:nnz], carray(hp, (nz, 2)), lin[nnz:nnz + nz], lin[nnz + nz:])
        return advance_system(carray(yp, (4 + nz,)), carray(ip, (NI,)), carray(fp, (NF,)), tau_end,
                              carray(pp, (N_P,)), carray(op, (NO,)), sub,
                              (np.empty((0, 5)), np.empty(0), np.empty((0, NS)), np.empty((0, NL))))

    funcs = {"hsys_advance": hsys_advance, "hsys_forces": forces_entry_point()}
    assert set(funcs) == set(SYSTEM_ENTRY_POINTS)
    return funcs

"""The Drillstring FMU's numba step kernels as C entry points for the native flavour.

The native ``Drillstring.fmu`` steps the string with the library's own
kernels of :mod:`hammerbit.model.string_kernels` (:func:`exchange_step`, the
master's Jacobi exchange in its FMU form, which also gives the held force) and
the exponentials of a step length it was not built for
(:mod:`hammerbit.model.string_exponentials`: :func:`modal_exponentials`,
:func:`dense_exponential`), compiled
ahead of time by :mod:`hammerbit.fmu.native_kernels` exactly as the hammer's
kernels are.  The entry points take flat C arrays; the complex modal arrays
are ``double _Complex`` (interleaved real and imaginary parts).
"""
from __future__ import annotations

__all__ = ["STRING_ENTRY_POINTS", "compile_string_entry_points"]

#: C names of the entry points and their C prototypes (string_api.h in native/ declares the same)
STRING_ENTRY_POINTS = {
    "hs_exchange": "double hs_exchange(int64_t order, int64_t given, double h, int64_t modal, int64_t n, double *P, "
                   "double *xi, double *buf, double *tmp, double *frow_real, double _Complex *d, "
                   "double _Complex *G, double _Complex *irow, double *icol, double _Complex *eta, "
                   "double _Complex *frow, double *k3, double *th, double *wh, double *Fh, double *out, "
                   "double F_held, double *c, double *feed)",
    "hs_modal_exponentials": "void hs_modal_exponentials(int64_t n, double h, double *k2, double _Complex *lam, "
                             "double _Complex *B, double _Complex *frow, double _Complex *d, "
                             "double _Complex *G, double _Complex *irow, double *icol)",
    "hs_dense_exponential": "void hs_dense_exponential(int64_t n, double h, double *k2, double *A1, double *E, "
                            "double *frow, double *P, double *work)",
}


def compile_string_entry_points() -> dict:
    """``{C name: numba cfunc}`` of :data:`STRING_ENTRY_POINTS` (compiles them in this process)."""
    import numpy as np
    from numba import carray, cfunc
    from numba.core.types import CPointer, complex128, float64, int64

    from hammerbit.model.string_kernels import (EXCHANGE_HELD, N_COEFFS, DenseForm, ExchangeHistory,
                                                ExchangeScheme, HammerStep, Interface, ModalForm,
                                                exchange_step_dense, exchange_step_modal)

    f64p, c128p = CPointer(float64), CPointer(complex128)
    NC = N_COEFFS

    # the C ABI (string_api.h) is flat; the body groups it into the exchange's records
    @cfunc(float64(int64, int64, float64, int64, int64, f64p, f64p, f64p, f64p, f64p, c128p, c128p, c128p, f64p,
                   c128p, c128p, f64p, f64p, f64p, f64p, f64p, float64, f64p, f64p))
    def hs_exchange(order, given, h, modal, n, Pp, xip, bufp, tmpp, frp, dp, Gp, irp, icp, etap, fcp, k3p, thp,
                    whp, Fhp, outp, F_held, cp, feedp):
        # n: states of the dense form, or kept modes of the modal form; k3 = (ki, ci, W);
        # th (3), wh (3 x 2), Fh (3), out (4), c (6) the ExchangeHistory; returns the force the
        # hammer holds over a next step of length h (the exchange computes it: no second call)
        out = carray(outp, (4,))
        k3 = carray(k3p, (3,))
        scheme = ExchangeScheme(False, order, True, given != 0)
        iface = Interface(k3[0], k3[1], k3[2], carray(feedp, (2,)))
        hist = ExchangeHistory(carray(thp, (3,)), carray(whp, (3, 2)), carray(Fhp, (3,)), out, carray(cp, (NC,)))
        hammer = HammerStep(0.0, 0.0, F_held)
        if modal:
            form = ModalForm(carray(dp, (n,)), carray(Gp, (n, NC)), carray(irp, (n,)), carray(icp, (NC,)),
                             carray(etap, (n,)), carray(fcp, (n,)))
            return exchange_step_modal(scheme, h, form, iface, hist, hammer)[EXCHANGE_HELD]
        else:
            form = DenseForm(carray(Pp, (n + 1, n + NC)), carray(xip, (n,)), carray(bufp, (n + NC,)),
                             carray(tmpp, (n + 1,)), carray(frp, (n,)))
        return exchange_step_dense(scheme, h, form, iface, hist, hammer)[EXCHANGE_HELD]

    from hammerbit.model.string_exponentials import N_PHI, PADE_WORK, dense_exponential, modal_exponentials
    from numba.core.types import void

    # the exponentials of a step length the FMU was not built for (string_step's kernels)
    @cfunc(void(int64, float64, f64p, c128p, c128p, c128p, c128p, c128p, c128p, f64p))
    def hs_modal_exponentials(n, h, k2p, lamp, Bp, frowp, dp, Gp, irowp, icolp):
        # n kept modes; k2 = (ki, ci); writes d (n), G (n x 6), irow (n), icol (6)
        modal_exponentials(h, carray(lamp, (n,)), carray(Bp, (n, 2)), carray(frowp, (n,)), carray(k2p, (2,)),
                           carray(dp, (n,)), carray(Gp, (n, NC)), carray(irowp, (n,)), carray(icolp, (NC,)),
                           np.empty(N_PHI, np.complex128))

    @cfunc(void(int64, float64, f64p, f64p, f64p, f64p, f64p, f64p))
    def hs_dense_exponential(n, h, k2p, A1p, Ep, frowp, Pp, workp):
        # n states; writes P ((n + 1) x (n + 6)); work: PADE_WORK N^2 doubles, N = n + 7
        N = n + NC + 1
        dense_exponential(h, carray(A1p, (n, n)), carray(Ep, (n, 2)), carray(frowp, (n,)), carray(k2p, (2,)),
                          carray(Pp, (n + 1, n + NC)), carray(workp, (PADE_WORK, N, N)))

    funcs = {"hs_exchange": hs_exchange, "hs_modal_exponentials": hs_modal_exponentials,
             "hs_dense_exponential": hs_dense_exponential}
    assert set(funcs) == set(STRING_ENTRY_POINTS)
    return funcs

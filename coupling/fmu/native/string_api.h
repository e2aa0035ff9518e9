/* The Drillstring FMU's compiled numba step kernels as C functions (native flavour).
 *
 * The object kernels_<platform>.o is emitted by hammerbit.fmu.native_kernels (kernel set
 * "string", hammerbit.fmu.native_string_kernels) from hammerbit.model.string_step: the same
 * exchange_step and held_force the co-simulation master and the Python flavour run. */
#ifndef HAMMERBIT_STRING_API_H
#define HAMMERBIT_STRING_API_H

#include <complex.h>
#include <stdint.h>

/* One exchange (the master's Jacobi step in its FMU form) over h: the string state advanced in
 * place (modal eta, or dense xi with the scratch buf, tmp), the histories th, wh, Fh shifted,
 * out = [F(t+h), energy residual, frow.xi, force defect]; returns the force the hammer holds
 * over a next step of length h. k3 = (ki, ci, W).  given: c[2..5] holds the hammer motion's
 * derivatives at t (x', v', x'', v''; the input derivatives), taken instead of the extrapolation. */
double hs_exchange(int64_t order, int64_t given, double h, int64_t modal, int64_t n, double *P, double *xi,
                   double *buf, double *tmp, double *frow_real, double _Complex *d, double _Complex *G,
                   double _Complex *irow, double *icol, double _Complex *eta, double _Complex *frow,
                   double *k3, double *th, double *wh, double *Fh, double *out, double F_held, double *c,
                   double *feed);

/* The exponentials of a step h the FMU was not built for (hammerbit.model.string_exponentials): the modal
 * form's d (n), G (n x 6), irow (n), icol (6) from the n kept modes' eigenvalues lam, inputs B
 * (n x 2) and frow; or the dense form's P ((n + 1) x (n + 6)) from A1 (n x n), E (n x 2), frow,
 * with work of HS_PADE_WORK (n + 7)^2 doubles. k2 = (ki, ci). */
void hs_modal_exponentials(int64_t n, double h, double *k2, double _Complex *lam, double _Complex *B,
                           double _Complex *frow, double _Complex *d, double _Complex *G,
                           double _Complex *irow, double *icol);
void hs_dense_exponential(int64_t n, double h, double *k2, double *A1, double *E, double *frow, double *P,
                          double *work);

/* nrt_shim.c: 1 if a kernel raised an exception on this thread since the last call (then 0) */
int hb_kernel_raised(void);

#endif

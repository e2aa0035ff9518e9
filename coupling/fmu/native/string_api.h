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
 * over a next step of length h. k3 = (ki, ci, W). */
double hs_exchange(int64_t order, double h, int64_t modal, int64_t n, double *P, double *xi, double *buf,
                   double *tmp, double *frow_real, double _Complex *d, double _Complex *G,
                   double _Complex *irow, double *icol, double _Complex *eta, double _Complex *frow,
                   double *k3, double *th, double *wh, double *Fh, double *out, double F_held, double *c,
                   double *feed);

/* nrt_shim.c: 1 if a kernel raised an exception on this thread since the last call (then 0) */
int hb_kernel_raised(void);

#endif

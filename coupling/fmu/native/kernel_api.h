/* The model's compiled numba kernels as C functions (the native flavour of the FMU).
 *
 * The objects kernels_<platform>.o are emitted by hammerbit.fmu.native_kernels from the
 * library's own kernels (hammerbit.model.kernel_*); the array layouts (HBK_* offsets) are
 * written into hb_native.h by the build from the same module.  Arrays: y[4] = x1..x4,
 * ist[HBK_N_ISTATE] (int64), fst[HBK_N_FSTATE], p[HBK_N_P], opts[HBK_N_OPTS]. */
#ifndef HAMMERBIT_KERNEL_API_H
#define HAMMERBIT_KERNEL_API_H

#include <stdint.h>

/* advance the hybrid system to the nondimensional time tau_end; an HBK_ST_* status */
int64_t hb_advance(double *y, int64_t *ist, double *fst, double tau_end, double *p, double *opts);
/* hb_advance with an event log of one row (log[HBK_N_LOG_COLS]; the caller zeroes
 * ist[HBK_I_NLOG]): HBK_ST_LOG_FULL just after the first event (reset applied), its time in
 * fst[HBK_F_T] and log[HBK_L_T] */
int64_t hb_advance_to_event(double *y, int64_t *ist, double *fst, double tau_end, double *p,
                            double *opts, double *log);
/* the modes of a state at rest (stick unless x4 > 0; contact if the gap is closed) */
int64_t hb_init_modes(double *y, int64_t *ist, double *p);
/* out = [spring-damper, contact (CONTACT mode only), force on the bit, friction] / F0 */
int64_t hb_forces(double *y, int64_t *ist, double *p, double *out);
/* out = dy/dtau of the hybrid mode (mode_s, mode_c) at tau */
int64_t hb_rhs(double tau, double *y, double *p, int64_t mode_s, int64_t mode_c, double *out);
/* the event kinds watched in the current modes (at most 3 written to kinds); how many */
int64_t hb_watched(int64_t *ist, double *p, int64_t *kinds);
/* the signed indicator of an event kind: the event happens when it becomes > 0 */
double hb_watch_value(int64_t kind, double *y, double *p, int64_t mode_c);
/* the reset map of an event kind (y, ist, fst changed in place); the kind actually taken */
int64_t hb_apply_event(int64_t kind, double *y, int64_t *ist, double *fst, double *p);

/* the L1 norms of the relative oscillator's impulse responses of rho, xi (regime.oscillator_l1) */
int64_t hb_oscillator_l1(double rho, double xi, double *l1);
/* the regime bits known now (fmu_regime.causal_regime): l1 of hb_oscillator_l1, cert[HBK_N_CERT]
 * scratch */
int64_t hb_regime(double *y, int64_t *ist, double *fst, double *p, double *l1, double *cert);

/* nrt_shim.c: 1 if a kernel raised an exception on this thread since the last call (then 0) */
int hb_kernel_raised(void);

#endif

/* The native DrillingSystem model: hammer, bit, string and top condition integrated as one hybrid
 * system by the library's compiled driver, with the string as its linear subsystem:
 *   model_system.c          life cycle, inputs, fmi2DoStep, outputs, hb_model_fill (model.h)
 *   model_system_access.c   fmi2Get*, fmi2Set*, FMU states
 *   model_system_regime.c   the causal runaway and stall verdicts of the regime output
 * The subsystem, the layouts and the value references are generated (hsys_data.h, by
 * hammerbit.fmu.build_system). */
#ifndef HAMMERBIT_MODEL_SYSTEM_H
#define HAMMERBIT_MODEL_SYSTEM_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "front.h"
#include "model.h"
#include "hb_description.h"
#include "hsys_data.h"

#define SYS_STATE_MAGIC 0x48425359u  /* "HBSY": layout version of the system model state */
#define SYS_NY (4 + HSYS_NZ)

/* the compiled kernels (hammerbit.fmu.native_system_kernels) */
int64_t hsys_advance(double *y, int64_t *ist, double *fst, double tau_end, double *p, double *opts,
                     int64_t nz, int64_t *csr, double *lin, double *H);
int64_t hsys_forces(double *y, int64_t *ist, double *p, double *out);
int hb_kernel_raised(void);

/* the inputs, in the order of their value references, and their start values */
enum { IN_AMPLITUDE, IN_FREQUENCY, IN_WOB_SET_POINT, IN_FEED_VELOCITY, N_INPUTS };
static const double SYS_START_IN[N_INPUTS] = {HSYS_START_amplitude, HSYS_START_frequency,
                                              HSYS_START_wob_set_point, HSYS_START_feed_velocity};

/* one solution of the system: the solver's arrays (the main run, or the shadow run at a tighter
 * tolerance that the error estimate compares it with) */
typedef struct {
    double y[SYS_NY];
    int64_t ist[HSYS_N_ISTATE];
    double fst[HSYS_N_FSTATE];
    double opts[HSYS_N_OPTS];
} syssolution;

/* bit-position samples the runaway rule keeps since the last stick (thinned by half when full) */
#define SYS_RING 64

/* the memory of the regime verdict's causal rules (model_system_regime.c), nondimensional */
typedef struct {
    double impulse;                /* the WOB impulse since the run's start */
    double stall_since, stall_impulse; /* the stick phase the stall rule follows, the WOB impulse since */
    double ring_since, gap;        /* the stick the samples follow, the least time between two */
    int64_t n;                     /* samples held */
    double tau[SYS_RING], x[SYS_RING], imp[SYS_RING]; /* time, bit position, impulse since the start */
    int64_t verdict;               /* the runaway and stall bits now */
} sysregime;

typedef struct {
    uint32_t magic, size;
    double tolerance;
    double in[N_INPUTS];          /* inputs as set */
    double applied[N_INPUTS];     /* inputs the system runs with */
    int32_t ready, terminated;
    double t, t_start;
    /* outputs */
    double bit_position, rate_of_penetration, wob, mean_wob, hook_load, hammer_position,
        hammer_velocity, contact_force, coupling_error;
    int64_t stick_slip, impact_count, slip_count, regime;
    double penetration_scale;     /* the largest |bit position| of either run so far [x0] */
    /* the solver's arrays: the main run (y, ist, fst, opts) and the shadow run */
    double y[SYS_NY];
    int64_t ist[HSYS_N_ISTATE];
    double fst[HSYS_N_FSTATE];
    double opts[HSYS_N_OPTS];
    syssolution shadow;
    sysregime rg;
    double p[HSYS_N_P];
    double lin[HSYS_NNZ + HSYS_NZ + 2];    /* A's values, G, g (the inputs change A's column IC) */
    char error[256];
} sysstate;

typedef struct {
    hb_model_base base;          /* name, callbacks (model.h) */
    int64_t csr[HSYS_NZ + 1 + HSYS_NNZ];
    double H[2 * HSYS_NZ];
    sysstate s;
    sysstate kept;               /* the state of a step's start, put back if the step is refused */
} model;

#define FAIL(m, ...) (hb_model_log((m), fmi2Error, __VA_ARGS__), fmi2Error)

/* the shadow run's rtol is the main run's times this: its error, a small fraction of the main run's,
 * makes their difference an estimate of the main run's error (coupling_error) */
#define SYS_SHADOW_RTOL_FACTOR (1.0 / 32.0)
/* the main run's error over the shadow's: 32^p for a global error that scales as rtol^p, p = 8/9
 * for the solver's eighth-order pair under error-per-step control.  Measured on the ordinary steps
 * of field-2200m under the auto-driller (200 steps of 10 ms against a reference at rtol 1e-11): the
 * true errors' ratio 20 (median), the differences' (each run against one 32 times tighter) 27.  At a
 * step the FMU corrects, the outputs are the shadow's, and the difference over this ratio is their
 * error estimate */
#define SYS_SHADOW_ERROR_RATIO 21.77   /* 32^(8/9) */

/* the physical range of a state (model_system_access.c): every solver state within this many of
 * its scales (x0, x0 Omega, F0 / Omega; 1e6 x0 is 16 km on field-2200m), the hammer within this many
 * x0 of the bit */
#define SYS_STATE_LIMIT 1e6
#define SYS_GAP_LIMIT 100.0

/* model_system.c: the outputs of the state (after a step of nondimensional length dtau from the
 * hammer velocity x2a, bit position x3a; dtau = 0: at a communication point without a step) */
void sys_outputs(sysstate *s, double dtau, double x2a, double x3a, double tau_a);
/* model_system_regime.c: the regime memory of a run that starts now; the verdict after a step of
 * length dtau whose WOB impulse was step_impulse (logs a change of runaway or stall); why a state's
 * regime memory is refused (NULL: accepted) */
void sys_regime_start(sysstate *s);
void sys_regime_step(model *m, double step_impulse, double dtau);
const char *sys_regime_invalid(const sysstate *s);
/* model_system_access.c: why an input value is refused (NULL: accepted; idx an IN_*) */
const char *sys_input_refused(const sysstate *s, int idx, double v, char *buf, size_t n);
/* model_system_access.c: why a state is refused, checked in full (NULL: accepted; a reason that
 * names a value is written into why[n], of at least SYS_WHY_SIZE bytes).  fmi2SetFMUstate and
 * fmi2DeSerializeFMUstate refuse such a state, and fmi2DoStep refuses a step that would end in one,
 * so that every state the FMU holds can be restored */
#define SYS_WHY_SIZE 200
const char *sys_state_invalid(const sysstate *s, char *why, size_t n);
/* model_system_access.c: fmi2Get*, fmi2Set* and the FMU-state functions */
void sys_access_fill(hb_wrapper *w);

#endif

/* The native HammerBitRock model (native flavour): its state, the tables the build writes into
 * hb_native.h, and what its files share:
 *   model_native.c  life cycle, fmi2DoStep, hb_model_fill (model.h)
 *   model_params.c  parameters -> the kernel's arrays (hb_commit, hb_apply_inputs)
 *   model_checks.c  messages, ranges, the inputs' limits
 *   model_values.c  fmi2Get*, fmi2Set*
 *   model_state.c   FMU states
 *   model_me.c      Model Exchange
 *   model_derivatives.c  output derivatives */
#ifndef HAMMERBIT_MODEL_NATIVE_H
#define HAMMERBIT_MODEL_NATIVE_H

#include <stddef.h>
#include <stdint.h>

#include "front.h"
#include "model.h"

/* allowed values of one real number (hammerbit.model.validation.Range) */
typedef struct {
    double lo, hi;
    int lo_open, hi_open, allow_inf;
    const char *text;          /* Range.text(): "[lo, hi] unit" */
} hb_range;

enum { HB_INPUT, HB_FIXED, HB_TUNABLE };

/* a Real input or parameter the model stores */
typedef struct {
    unsigned vr;
    int kind;                  /* HB_INPUT, HB_FIXED, HB_TUNABLE */
    const char *name;
    double start;
    hb_range range;
} hb_stored;

typedef struct {
    const char *name;          /* the group's name, as a ParameterError names it */
    hb_range range;
} hb_group;

#include "hb_description.h"
#include "hb_native.h"

/* ------------------------------------------------------------------------------------------ */
/* State                                                                                       */
/* ------------------------------------------------------------------------------------------ */
#define MODEL_STATE_MAGIC 0x48424e32u   /* "HBN2": layout version of model_state */

typedef struct {
    uint32_t magic;
    uint32_t size;                 /* sizeof(model_state): a state of another build is refused */
    double value[HB_NSTORED];      /* parameters and inputs as set (SI) */
    int32_t impact_enabled;
    double committed[HB_NSTORED];  /* the validated values in use */
    int32_t committed_impact;
    int32_t ready, terminated, dirty, stale, has_commit;
    int32_t last_status;
    double t_start, t;
    /* solver state and parameters (kernel layout) */
    double y[4];
    int64_t ist[HBK_N_ISTATE];
    double fst[HBK_N_FSTATE];
    double p[HBK_N_P];
    double opts[HBK_N_OPTS];
    double x0, v0, F0, omega, x3_start;
    double applied_preload, applied_force;   /* inputs last written into p (NaN: none yet) */
    double l1[2];                  /* the regime certificate's L1 norms of rho, xi (hb_oscillator_l1) */
    int32_t regime_seen;           /* the regime verdict last logged (or of the commit) */
    char error[512];               /* why fmi2DoStep is refused (not initialised, ...) */
} model_state;

typedef struct {
    hb_model_base base;            /* name, callbacks (model.h) */
    model_state s;
    int event_iterations;          /* Model Exchange: mode switches in the current event mode */
    unsigned armed, fired;         /* event kinds watched when Event Mode began; taken since (bits) */
} model;

/* model_checks.c ---------------------------------------------------------------------------- */
/* record st as the call's status (last_status), log the message; st */
fmi2Status hb_fail(model *m, fmi2Status st, const char *fmt, ...);
/* v in the range r (validation.Range.contains) */
int hb_contains(const hb_range *r, double v);
/* 1 and "parameter 'name' = v is out of range: allowed ..." in out if v is outside r; else 0 */
int hb_range_error(const char *name, double v, const hb_range *r, char *out, size_t n);
/* an input value within +-1000 F0 of the parameters in use; its refusal message */
int hb_input_ok(const model_state *s, int k, double v);
void hb_input_error(const model_state *s, int k, double v, char *out, size_t n);

/* model_params.c ---------------------------------------------------------------------------- */
/* validate the values v[] (and impact) and build the solver state into s; 1, or 0 with the
 * message in err (s unchanged then); keep: carry y, ist, fst and p of s over */
int hb_commit(model_state *s, const double *v, int impact, int keep, char *err, size_t n);
/* apply the inputs as set to the kernel's parameter vector (Model Exchange: at every evaluation) */
void hb_apply_inputs(model_state *s);

/* the regime bits known now (hammerbit.model.fmu_regime.causal_regime), the inputs as applied */
int32_t hb_regime_now(model_state *s);
/* "runaway, tension" (the bits' names) or "none" into out */
void hb_regime_names(int32_t regime, char *out, size_t n);

/* model_values.c: the fmi2Get* and fmi2Set* functions of the backend table */
void hb_values_fill(hb_wrapper *w);

/* model_state.c: the FMU-state functions of the backend table */
void hb_state_fill(hb_wrapper *w);

/* model_me.c: the Model Exchange functions of the backend table */
void hb_me_fill(hb_wrapper *w);
/* d(state i)/dt [SI] in the current hybrid mode at the model's time */
double hb_derivative(model *m, int i);

/* model_derivatives.c: fmi2GetRealOutputDerivatives of the backend table */
void hb_derivatives_fill(hb_wrapper *w);

#endif

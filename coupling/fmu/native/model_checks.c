/* Checks of the native model backend: its messages (hb_fail records the status), the ranges of
 * hammerbit.model.validation (written into hb_native.h by the build) and the inputs' limits,
 * which follow the static friction threshold F0 of the parameters in use. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>

#include "model_native.h"

fmi2Status hb_fail(model *m, fmi2Status st, const char *fmt, ...) {
    char msg[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if ((int32_t)st > m->s.last_status) m->s.last_status = (int32_t)st;
    hb_model_log(m, st, "%s", msg);
    return st;
}

/* ------------------------------------------------------------------------------------------ */
/* Ranges                                                                                      */
/* ------------------------------------------------------------------------------------------ */
int hb_contains(const hb_range *r, double v) {
    if (isnan(v)) return 0;
    if (isinf(v)) return r->allow_inf && v > 0;
    if (v < r->lo || v > r->hi) return 0;
    return !((r->lo_open && v == r->lo) || (r->hi_open && v == r->hi));
}

/* "parameter 'name' = value is out of range: allowed ..." (validation.check_range); 0 if not */
int hb_range_error(const char *name, double v, const hb_range *r, char *out, size_t n) {
    if (hb_contains(r, v)) return 0;
    char rv[40];
    hb_repr(v, rv, sizeof rv);
    int non_finite = isnan(v) || (isinf(v) && !r->allow_inf);
    snprintf(out, n, "parameter '%s' = %s is out of range: allowed %s%s", name, rv,
             non_finite ? "a finite number in " : "", r->text);
    return 1;
}

/* |input| <= limit F0 for the parameters in use (F0 = mu_static normal_force) */
static double input_limit(const model_state *s, int k) {
    return (k == HBS_preload ? HB_INPUT_LIMIT_F0_preload : HB_INPUT_LIMIT_F0_harmonic_force) * s->F0;
}

int hb_input_ok(const model_state *s, int k, double v) {
    double lim = input_limit(s, k);
    return -lim <= v && v <= lim;   /* false for NaN */
}

/* "... out of range: allowed [-x, x] N (1000 F0, ...)" for an input value */
void hb_input_error(const model_state *s, int k, double v, char *out, size_t n) {
    char rv[40], lim[40], f0[40], have[40];
    hb_repr(v, rv, sizeof rv);
    snprintf(lim, sizeof lim, "%g", input_limit(s, k));
    hb_repr(s->F0, f0, sizeof f0);
    hb_repr(s->value[k], have, sizeof have);
    snprintf(out, n, "input '%s' = %s is out of range: allowed [-%s, %s] N (%g F0, F0 = mu_static "
             "normal_force = %s N, the static friction threshold); refused, %s N stays",
             HB_STORED[k].name, rv, lim, lim, input_limit(s, k) / s->F0, f0, have);
}


/* The FMI 2.0 front's shared rules (front_internal.h): logging, the state machine's checks,
 * value references and types against the model description, the model's real status. */
#define _GNU_SOURCE
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front_internal.h"

static const char *const TYPE_NAMES[] = {"Real", "Integer", "Boolean", "String"};

/* ------------------------------------------------------------------------------------------ */
/* Logging                                                                                     */
/* ------------------------------------------------------------------------------------------ */
/* The FMI logger takes a printf format: every '%' that does not start "%%" is doubled. */
static void escape_percent(const char *in, char *out, size_t n) {
    size_t j = 0;
    for (size_t i = 0; in[i] && j + 2 < n; i++) {
        if (in[i] == '%') {
            if (in[i + 1] == '%') {
                out[j++] = '%';
                out[j++] = '%';
                i++;
                continue;
            }
            out[j++] = '%';
            out[j++] = '%';
        } else {
            out[j++] = in[i];
        }
    }
    out[j] = '\0';
}

void log_to(const fmi2CallbackFunctions *cb, const char *name, fmi2Status st, const char *fmt,
                   ...) {
    if (!cb || !cb->logger) return;
    char raw[4096], msg[8200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(raw, sizeof raw, fmt, ap);
    va_end(ap);
    escape_percent(raw, msg, sizeof msg);
    const char *cat = st == fmi2OK ? "logAll"
                      : st == fmi2Warning ? "logStatusWarning"
                      : st == fmi2Discard ? "logStatusDiscard"
                      : st == fmi2Error ? "logStatusError" : "logStatusFatal";
    cb->logger(cb->componentEnvironment, name ? name : "?", st, cat, msg);
}

static int category_enabled(const hb_inst *I, const char *cat) {
    if (!I->logging_on) return 0;
    if (I->ncat == 0) return 1;
    for (size_t i = 0; i < I->ncat; i++)
        if (cat && strcmp(I->cats[i], cat) == 0) return 1;
    return 0;
}

/* pythonfmu logs through this: non-OK messages always reach the host, OK ones when enabled */
void inner_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st,
                         fmi2String cat, fmi2String message, ...) {
    hb_inst *I = (hb_inst *)env;
    if (!I) return;
    if (st > I->call_max) I->call_max = st;
    if (st == fmi2OK && !category_enabled(I, cat)) return;
    if (!I->user.logger) return;
    char msg[8200];
    escape_percent(message ? message : "", msg, sizeof msg);
    I->user.logger(I->user.componentEnvironment, name ? name : I->name, st, cat, msg);
}

/* ------------------------------------------------------------------------------------------ */
/* Helpers                                                                                     */
/* ------------------------------------------------------------------------------------------ */
static const char *state_name(int s) {
    switch (s) {
    case ST_INSTANTIATED: return "Instantiated";
    case ST_INIT: return "Initialization Mode";
    case ST_STEP_COMPLETE: return "Step Mode";
    case ST_TERMINATED: return "Terminated";
    case ST_ERROR: return "Error (after an fmi2Error: fmi2SetFMUstate or fmi2Reset recover)";
    case ST_FATAL: return "Fatal";
    case ST_EVENT: return "Event Mode";
    case ST_CONT: return "Continuous-Time Mode";
    default: return "?";
    }
}

int allowed(hb_inst *I, int mask, const char *fn) {
    if (I->state & mask) return 1;
    LOG(I, fmi2Error, "%s: illegal call sequence, not allowed in state %s", fn,
        state_name(I->state));
    if (I->state != ST_FATAL) I->state = ST_ERROR;
    I->last_status = fmi2Error;
    return 0;
}

/* Status of a call: errors put the instance into the Error state, fatal into Fatal.  An error of
 * any call, found here or by the slave, is also what the host then reads from last_status. */
fmi2Status settle(hb_inst *I, fmi2Status st) {
    if (st >= fmi2Error) I->last_status = st;
    if (st == fmi2Fatal)
        I->state = ST_FATAL;
    else if (st == fmi2Error)
        I->state = ST_ERROR;
    return st;
}

/* The calls whose status the slave records (exit of initialisation, steps, setters, state
 * restore, setup): last_status becomes their status, whatever it is. */
fmi2Status record(hb_inst *I, fmi2Status st) {
    I->last_status = st;
    return settle(I, st);
}

static const hb_var *find_var(int type, fmi2ValueReference vr) {
#if HB_VR_INDEX_LEN
    if (vr >= HB_VR_INDEX_LEN) return NULL;
    int row = HB_VAR_INDEX[type][vr];
    return row < 0 ? NULL : &HB_VARS[row];
#else
    size_t lo = 0, hi = HB_NVARS;
    while (lo < hi) {   /* HB_VARS is sorted by (type, vr) */
        size_t mid = (lo + hi) / 2;
        const hb_var *v = &HB_VARS[mid];
        if (v->type < type || (v->type == type && v->vr < vr))
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < HB_NVARS && HB_VARS[lo].type == type && HB_VARS[lo].vr == vr) return &HB_VARS[lo];
    return NULL;
#endif
}

static const char *var_name_any_type(fmi2ValueReference vr, int *type) {
    for (size_t i = 0; i < HB_NVARS; i++)
        if (HB_VARS[i].vr == vr) {
            *type = HB_VARS[i].type;
            return HB_VARS[i].name;
        }
    return NULL;
}

int check_vrs(hb_inst *I, const char *fn, int type, const fmi2ValueReference vr[], size_t nvr,
                     const void *values, int setting) {
    if (nvr == 0) return 1;
    if (!vr || !values) {
        LOG(I, fmi2Error, "%s: %s is NULL with nvr = %zu", fn, !vr ? "vr" : "value", nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; i++) {
        const hb_var *v = find_var(type, vr[i]);
        if (!v) {
            int other = -1;
            const char *name = var_name_any_type(vr[i], &other);
            if (name)
                LOG(I, fmi2Error, "%s: value reference %u is %s, a %s variable, not a %s", fn,
                    vr[i], name, TYPE_NAMES[other], TYPE_NAMES[type]);
            else
                LOG(I, fmi2Error, "%s: unknown value reference %u (no %s variable has it)", fn,
                    vr[i], TYPE_NAMES[type]);
            return 0;
        }
        /* Model Exchange's Event and Continuous-Time Modes set what Step Mode sets */
        int as = I->state & M_ME ? ST_STEP_COMPLETE : I->state;
        if (setting && !(v->set_mask & as)) {
            LOG(I, fmi2Error, "%s: %s (value reference %u; %s) cannot be set in state %s", fn,
                v->name, vr[i], v->kind, state_name(I->state));
            return 0;
        }
    }
    return 1;
}

/* The status the slave says its last call should have had (variable HB_STATUS_VR). */
fmi2Status slave_status(hb_inst *I, fmi2Status st) {
#if HB_HAS_STATUS_VR
    if (st >= fmi2Error) return st;
    fmi2ValueReference vr = HB_STATUS_VR;
    fmi2Integer v = 0;
    fmi2Status gs = hb_W.GetInteger(I->w, &vr, 1, &v);
    if (gs >= fmi2Error) return gs;
    if (v < fmi2OK || v > fmi2Fatal) {
        LOG(I, fmi2Error, "the slave reported the invalid status %d", v);
        return fmi2Error;
    }
    if ((fmi2Status)v > st) st = (fmi2Status)v;
#else
    (void)I;
#endif
    return st;
}

/* After a hot-path call (fmi2DoStep, fmi2Set*): the slave's status is read only when the call
 * was not clean (pythonfmu returned non-OK, or the slave logged a warning or worse): the slave
 * logs whenever it reports a status other than OK. */
fmi2Status hot_status(hb_inst *I, fmi2Status st) {
    if (st == fmi2OK && I->call_max == fmi2OK) return fmi2OK;
    return slave_status(I, st);
}

/* Communication times are compared with an absolute tolerance: 1 ns, or a few units in the
 * last place where t is so large that its doubles lie farther apart (beyond about 1e6 s) -- a
 * master computing t0 + n h is within that, and a step never skips a stretch of time. */
#define HB_TIME_ABS_TOL 1e-9
#define HB_TIME_ULPS 4.0
double time_tol(double t) {
    /* the spacing of the doubles above |t|, from its bits: the front links no libm */
    union { double d; uint64_t u; } next;
    next.d = t < 0 ? -t : t;
    double a = next.d;
    if (!isfinite(a)) return HB_TIME_ABS_TOL;
    next.u += 1;
    double tol = HB_TIME_ULPS * (next.d - a);
    return tol > HB_TIME_ABS_TOL ? tol : HB_TIME_ABS_TOL;
}

/* The shortest decimal text of x that reads back as x (as Python's repr). */
const char *fmt_real(char buf[32], double x) {
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, 32, "%.*g", prec, x);
        if (!isfinite(x) || strtod(buf, NULL) == x) break;
    }
    return buf;
}

void free_inst(hb_inst *I) {
    if (!I) return;
    for (size_t i = 0; i < I->ncat; i++) free(I->cats[i]);
    free(I->cats);
    free(I->name);
    free(I);
}

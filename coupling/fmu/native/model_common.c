/* What every model instance shares (model.h): its allocation with name and callbacks, the logger,
 * and the pieces of FMI functions every model has alike. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

void *hb_model_new(size_t size, const char *name, const fmi2CallbackFunctions *cb) {
    hb_model_base *m = calloc(1, size);
    if (!m || !(m->name = strdup(name))) {
        free(m);
        return NULL;
    }
    m->cb = *cb;
    return m;
}

void hb_model_free(void *m) {
    if (!m) return;
    free(((hb_model_base *)m)->name);
    free(m);
}

void hb_model_log(const void *m, fmi2Status st, const char *fmt, ...) {
    const fmi2CallbackFunctions *cb = &((const hb_model_base *)m)->cb;
    if (!cb->logger) return;
    char msg[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    const char *cat = st == fmi2OK ? "logAll"
                      : st == fmi2Warning ? "logStatusWarning"
                      : st == fmi2Discard ? "logStatusDiscard" : "logStatusError";
    /* the message is the format: the front (inner_logger) escapes its '%' for the host */
    cb->logger(cb->componentEnvironment, ((const hb_model_base *)m)->name, st, cat, msg);
}

/* the Boolean and String functions of a model with no variable of either type */
static fmi2Status no_get_boolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean v[]) {
    (void)vr, (void)v;
    return nvr ? (hb_model_log(c, fmi2Error, "fmi2GetBoolean: the model has no Boolean variable"), fmi2Error) : fmi2OK;
}

static fmi2Status no_set_boolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 const fmi2Boolean v[]) {
    (void)vr, (void)v;
    return nvr ? (hb_model_log(c, fmi2Error, "fmi2SetBoolean: the model has no Boolean variable"), fmi2Error) : fmi2OK;
}

static fmi2Status no_get_string(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String v[]) {
    (void)vr, (void)v;
    return nvr ? (hb_model_log(c, fmi2Error, "fmi2GetString: the model has no String variable"), fmi2Error) : fmi2OK;
}

static fmi2Status no_set_string(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2String v[]) {
    (void)vr, (void)v;
    return nvr ? (hb_model_log(c, fmi2Error, "fmi2SetString: the model has no String variable"), fmi2Error) : fmi2OK;
}

void hb_model_no_booleans_strings(hb_wrapper *w) {
    w->GetBoolean = no_get_boolean;
    w->SetBoolean = no_set_boolean;
    w->GetString = no_get_string;
    w->SetString = no_set_string;
}

fmi2Status hb_model_free_state(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status hb_model_no_op(fmi2Component c) {
    (void)c;
    return fmi2OK;
}

void hb_model_fill_life_cycle(hb_wrapper *w, fmi2FreeInstanceFn free_instance, fmi2SetupExperimentFn setup,
                              fmi2ComponentFn exit_init, fmi2ComponentFn terminate, fmi2ComponentFn reset) {
    w->FreeInstance = free_instance;
    w->SetupExperiment = setup;
    w->EnterInitializationMode = hb_model_no_op;
    w->ExitInitializationMode = exit_init;
    w->Terminate = terminate;
    w->Reset = reset;
}

void hb_model_fill_values(hb_wrapper *w, fmi2GetRealFn get_real, fmi2SetRealFn set_real,
                          fmi2GetIntegerFn get_integer, fmi2SetIntegerFn set_integer) {
    w->GetReal = get_real;
    w->SetReal = set_real;
    w->GetInteger = get_integer;
    w->SetInteger = set_integer;
    hb_model_no_booleans_strings(w);
}

void hb_model_fill_states(hb_wrapper *w, fmi2GetFMUstateFn get, fmi2SetFMUstateFn set,
                          fmi2SerializedFMUstateSizeFn size, fmi2SerializeFMUstateFn serialize,
                          fmi2DeSerializeFMUstateFn deserialize) {
    w->GetFMUstate = get;
    w->SetFMUstate = set;
    w->FreeFMUstate = hb_model_free_state;
    w->SerializedFMUstateSize = size;
    w->SerializeFMUstate = serialize;
    w->DeSerializeFMUstate = deserialize;
}

fmi2Status hb_model_step_check(const void *m, const char *refusal, double t_now, double t, double h,
                               double tolerance) {
    char a[40], b[40];
    if (refusal) return hb_model_log(m, fmi2Error, "fmi2DoStep refused: %s", refusal), fmi2Error;
    if (!(0.0 < h && h < INFINITY)) {
        hb_repr(h, a, sizeof a);
        hb_model_log(m, fmi2Error, "communication step size h = %s s is invalid: it must be > 0 and finite; "
                     "step refused, state unchanged", a);
        return fmi2Error;
    }
    if (t != t_now && !(fabs(t - t_now) <= tolerance * fmax(fabs(t_now), h))) {
        hb_repr(t, a, sizeof a);
        hb_repr(t_now, b, sizeof b);
        hb_model_log(m, fmi2Error, "currentCommunicationPoint = %s s is not the current time of the FMU, %s s; "
                     "step refused, state unchanged", a, b);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status hb_model_deserialize(const void *m, const fmi2Byte in[], size_t size, size_t expected,
                                const char *(*invalid)(const void *m, const void *state), fmi2FMUstate *state) {
    if (size != expected) {
        hb_model_log(m, fmi2Error, "fmi2DeSerializeFMUstate: %zu bytes, but a state of this build has %zu; "
                     "state unchanged", size, expected);
        return fmi2Error;
    }
    void *copy = malloc(size);
    if (!copy) return hb_model_log(m, fmi2Error, "fmi2DeSerializeFMUstate: out of memory"), fmi2Error;
    memcpy(copy, in, size);
    const char *why = invalid(m, copy);
    if (why) {
        free(copy);
        hb_model_log(m, fmi2Error, "fmi2DeSerializeFMUstate: the bytes are corrupt (%s); state unchanged", why);
        return fmi2Error;
    }
    *state = copy;
    return fmi2OK;
}

fmi2Status hb_model_get_integers(const void *m, const fmi2ValueReference vr[], size_t nvr, fmi2Integer out[],
                                 int (*value)(const void *m, fmi2ValueReference vr, fmi2Integer *out)) {
    for (size_t i = 0; i < nvr; i++)
        if (!value(m, vr[i], &out[i])) {
            hb_model_log(m, fmi2Error, "fmi2GetInteger: unknown value reference %u", vr[i]);
            return fmi2Error;
        }
    return fmi2OK;
}

fmi2Status hb_model_step_put_back(const void *m, void *state, const void *kept, size_t size, double t_from,
                                  double t_to, const char *why) {
    char a[40], b[40], reason[320];
    hb_repr(t_from, a, sizeof a);
    hb_repr(t_to, b, sizeof b);
    snprintf(reason, sizeof reason, "%s", why);   /* `why` may point into the state put back */
    memcpy(state, kept, size);
    hb_model_log(m, fmi2Error, "fmi2DoStep from t = %s s to %s s refused: %s; state unchanged", a, b, reason);
    return fmi2Error;
}

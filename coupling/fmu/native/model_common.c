/* What every model instance shares (model.h): its allocation with name and callbacks, the logger. */
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

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

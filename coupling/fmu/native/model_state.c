/* FMU states of the native model backend: the whole model_state as plain data (a copy per
 * fmi2GetFMUstate; serialized as its bytes, behind the front's header with magic and GUID).
 * A state read back is checked field by field before it is used. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "model_native.h"

/* ------------------------------------------------------------------------------------------ */
static fmi2Status n_get_state(fmi2Component c, fmi2FMUstate *state) {
    model *m = c;
    model_state *copy = malloc(sizeof *copy);
    if (!copy) return hb_fail(m, fmi2Error, "fmi2GetFMUstate: out of memory");
    m->s.last_status = fmi2OK;
    *copy = m->s;
    *state = copy;
    return fmi2OK;
}

/* 1 if `s` can be a state of this build (sizes, flags, modes, finite numbers); else the reason */
static const char *state_invalid(const model_state *s) {
    if (s->magic != MODEL_STATE_MAGIC || s->size != sizeof *s) return "it is not a state of this build";
    if ((s->ready | s->terminated | s->dirty | s->stale | s->has_commit | s->impact_enabled |
         s->committed_impact) & ~1)
        return "a flag is neither 0 nor 1";
    if (!isfinite(s->t) || !isfinite(s->t_start)) return "its time is not finite";
    for (int i = 0; i < 4; i++)
        if (!isfinite(s->y[i])) return "its state holds a non-finite number";
    for (int i = 0; i < HBK_N_FSTATE; i++)
        if (isnan(s->fst[i])) return "its solver state holds NaN";
    if (s->ist[HBK_I_STICK] < 0 || s->ist[HBK_I_STICK] > 1 || s->ist[HBK_I_CONTACT] < 0 ||
        s->ist[HBK_I_CONTACT] > 2)
        return "its hybrid mode is out of range";
    if (s->has_commit && !(s->x0 > 0.0 && isfinite(s->x0) && s->F0 > 0.0 && s->omega > 0.0))
        return "its scales are not positive";
    return NULL;
}

static fmi2Status n_set_state(fmi2Component c, fmi2FMUstate state) {
    model *m = c;
    const model_state *s = state;
    const char *why = state_invalid(s);
    if (why) return hb_fail(m, fmi2Error, "fmi2SetFMUstate: %s; state unchanged", why);
    m->s = *s;
    m->s.last_status = fmi2OK;
    return fmi2OK;
}

static fmi2Status n_free_state(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

static fmi2Status n_state_size(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)c, (void)state;
    *size = sizeof(model_state);
    return fmi2OK;
}

static fmi2Status n_serialize(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size) {
    if (size != sizeof(model_state))
        return hb_fail(c, fmi2Error, "fmi2SerializeFMUstate: size = %zu, the state needs %zu bytes", size,
                    sizeof(model_state));
    memcpy(out, state, sizeof(model_state));
    return fmi2OK;
}

static fmi2Status n_deserialize(fmi2Component c, const fmi2Byte in[], size_t size,
                                fmi2FMUstate *state) {
    model *m = c;
    m->s.last_status = fmi2OK;
    if (size != sizeof(model_state))
        return hb_fail(m, fmi2Error, "fmi2DeSerializeFMUstate: %zu bytes, but a state of this build has "
                    "%zu; state unchanged", size, sizeof(model_state));
    model_state *copy = malloc(sizeof *copy);
    if (!copy) return hb_fail(m, fmi2Error, "fmi2DeSerializeFMUstate: out of memory");
    memcpy(copy, in, sizeof *copy);
    const char *why = state_invalid(copy);
    if (why) {
        free(copy);
        return hb_fail(m, fmi2Error, "fmi2DeSerializeFMUstate: the bytes are corrupt (%s); state "
                    "unchanged", why);
    }
    *state = copy;
    return fmi2OK;
}


void hb_state_fill(hb_wrapper *w) {
    w->GetFMUstate = n_get_state;
    w->SetFMUstate = n_set_state;
    w->FreeFMUstate = n_free_state;
    w->SerializedFMUstateSize = n_state_size;
    w->SerializeFMUstate = n_serialize;
    w->DeSerializeFMUstate = n_deserialize;
}

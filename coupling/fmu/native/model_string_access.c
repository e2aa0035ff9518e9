/* fmi2Get*, fmi2Set* and FMU states of the native Drillstring backend: parameters and inputs as
 * set (checked at fmi2ExitInitializationMode and fmi2DoStep, as the Python slave does), outputs
 * from the state, and the whole state as plain data (a copy per fmi2GetFMUstate, its bytes when
 * serialized, checked before it is used). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "model_string.h"

/* ------------------------------------------------------------------------------------------ */
/* Values                                                                                       */
/* ------------------------------------------------------------------------------------------ */
static double *real_slot(sstate *s, fmi2ValueReference vr, int *settable) {
    *settable = 1;
    switch (vr) {
    case HS_VR_damping_ratio: return &s->damping_ratio;
    case HS_VR_wob: return &s->wob;
    case HS_VR_hammer_position_at_rest: return &s->at_rest;
    case HS_VR_feed_velocity: return &s->feed_velocity;
    case HS_VR_proportional_gain: return &s->kp;
    case HS_VR_integral_gain: return &s->kig;
    case HS_VR_hammer_position: return &s->x_in;
    case HS_VR_hammer_velocity: return &s->v_in;
    default: break;
    }
    *settable = 0;
    switch (vr) {
    case HS_VR_interface_force: return &s->interface_force;
    case HS_VR_held_force: return &s->held;
    case HS_VR_hook_load: return &s->hook_load;
    case HS_VR_top_position: return &s->top_position;
    case HS_VR_top_velocity: return &s->top_velocity;
    default: return NULL;
    }
}

static fmi2Status s_get_real(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    model *m = c;
    int settable;
    for (size_t i = 0; i < nvr; i++) {
        double *p = real_slot(m->s, vr[i], &settable);
        switch (vr[i]) {
        case HS_VR_held_force_change: value[i] = m->s->held - (m->s->ready ? m->s->W : m->s->wob); break;
        case HS_VR_string_length: value[i] = HS_STRING_LENGTH; break;
        case HS_VR_interface_stiffness: value[i] = HS_INTERFACE_STIFFNESS; break;
        case HS_VR_interface_damping: value[i] = HS_INTERFACE_DAMPING; break;
        case HS_VR_buoyed_weight: value[i] = HS_BUOYED_WEIGHT; break;
        default:
            if (!p) return FAIL(m, "fmi2GetReal: unknown value reference %u", vr[i]);
            value[i] = *p;
        }
    }
    return fmi2OK;
}

static fmi2Status s_set_real(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                             const fmi2Real value[]) {
    model *m = c;
    int settable;
    for (size_t i = 0; i < nvr; i++) {   /* the front checked settability: all or none */
        double *p = real_slot(m->s, vr[i], &settable);
        if (!p || !settable) return FAIL(m, "fmi2SetReal: value reference %u cannot be set", vr[i]);
    }
    for (size_t i = 0; i < nvr; i++) *real_slot(m->s, vr[i], &settable) = value[i];
    return fmi2OK;
}

static fmi2Status s_get_integer(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2Integer value[]) {
    model *m = c;
    for (size_t i = 0; i < nvr; i++) {
        switch (vr[i]) {
        case HS_VR_extrapolation: value[i] = m->s->extrapolation; break;
        case HS_VR_top_condition: value[i] = m->s->top_condition; break;
        case HS_VR_string_states: value[i] = HS_STRING_STATES; break;
        default: return FAIL(m, "fmi2GetInteger: unknown value reference %u", vr[i]);
        }
    }
    return fmi2OK;
}

static fmi2Status s_set_integer(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2Integer value[]) {
    model *m = c;
    for (size_t i = 0; i < nvr; i++)
        if (vr[i] != HS_VR_extrapolation && vr[i] != HS_VR_top_condition)
            return FAIL(m, "fmi2SetInteger: value reference %u cannot be set", vr[i]);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == HS_VR_extrapolation) m->s->extrapolation = value[i];
        else m->s->top_condition = value[i];
    }
    return fmi2OK;
}

/* ------------------------------------------------------------------------------------------ */
/* FMU states: the whole state as plain data                                                   */
/* ------------------------------------------------------------------------------------------ */
static const char *state_invalid(const model *m, const sstate *s) {
    if (s->magic != STATE_MAGIC || s->size != m->size) return "it is not a state of this build";
    if ((s->ready | s->terminated | s->started) & ~1) return "a flag is neither 0 nor 1";
    if (!isfinite(s->t) || !isfinite(s->t_start)) return "its time is not finite";
    if (s->ready && (s->form < 0 || s->form > 1 || !hs_any_block(&m->tab, s->form) ||
                     s->n != hs_any_block(&m->tab, s->form)->n || s->order < 0 || s->order > 2))
        return "its form or extrapolation order is not one of this FMU";
    size_t nv = 2 * (size_t)m->tab.nmax;
    for (size_t i = 0; i < nv; i++)
        if (!isfinite(s->v[i])) return "its string state holds a non-finite number";
    return NULL;
}

static fmi2Status s_get_state(fmi2Component c, fmi2FMUstate *state) {
    model *m = c;
    sstate *copy = malloc(m->size);
    if (!copy) return FAIL(m, "fmi2GetFMUstate: out of memory");
    memcpy(copy, m->s, m->size);
    *state = copy;
    return fmi2OK;
}

static fmi2Status s_set_state(fmi2Component c, fmi2FMUstate state) {
    model *m = c;
    const char *why = state_invalid(m, state);
    if (why) return FAIL(m, "fmi2SetFMUstate: %s; state unchanged", why);
    memcpy(m->s, state, m->size);
    return fmi2OK;
}

static fmi2Status s_state_size(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state;
    *size = ((model *)c)->size;
    return fmi2OK;
}

static fmi2Status s_serialize(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size) {
    model *m = c;
    if (size != m->size)
        return FAIL(m, "fmi2SerializeFMUstate: size = %zu, the state needs %zu bytes", size, m->size);
    memcpy(out, state, m->size);
    return fmi2OK;
}

static fmi2Status s_deserialize(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate *state) {
    model *m = c;
    if (size != m->size)
        return FAIL(m, "fmi2DeSerializeFMUstate: %zu bytes, but a state of this build has %zu; state "
                    "unchanged", size, m->size);
    sstate *copy = malloc(m->size);
    if (!copy) return FAIL(m, "fmi2DeSerializeFMUstate: out of memory");
    memcpy(copy, in, m->size);
    const char *why = state_invalid(m, copy);
    if (why) {
        free(copy);
        return FAIL(m, "fmi2DeSerializeFMUstate: the bytes are corrupt (%s); state unchanged", why);
    }
    *state = copy;
    return fmi2OK;
}

void hs_access_fill(hb_wrapper *w) {
    w->GetReal = s_get_real;
    w->SetReal = s_set_real;
    w->GetInteger = s_get_integer;
    w->SetInteger = s_set_integer;
    hb_model_no_booleans_strings(w);
    w->GetFMUstate = s_get_state;
    w->SetFMUstate = s_set_state;
    w->FreeFMUstate = hb_model_free_state;
    w->SerializedFMUstateSize = s_state_size;
    w->SerializeFMUstate = s_serialize;
    w->DeSerializeFMUstate = s_deserialize;
}

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

HB_GET_REAL(s_get_real) {
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

HB_SET_REAL(s_set_real) {
    model *m = c;
    int settable;
    for (size_t i = 0; i < nvr; i++) {   /* the front checked settability: all or none */
        double *p = real_slot(m->s, vr[i], &settable);
        if (!p || !settable) return FAIL(m, "fmi2SetReal: value reference %u cannot be set", vr[i]);
    }
    for (size_t i = 0; i < nvr; i++) *real_slot(m->s, vr[i], &settable) = value[i];
    return fmi2OK;
}

static int string_integer(const void *m, fmi2ValueReference vr, fmi2Integer *out) {
    const sstate *s = ((const model *)m)->s;
    switch (vr) {
    case HS_VR_extrapolation: *out = s->extrapolation; return 1;
    case HS_VR_top_condition: *out = s->top_condition; return 1;
    case HS_VR_string_states: *out = HS_STRING_STATES; return 1;
    default: return 0;
    }
}

HB_GET_INTEGER(s_get_integer) {
    return hb_model_get_integers(c, vr, nvr, value, string_integer);
}

HB_SET_INTEGER(s_set_integer) {
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
/* the largest magnitude of a state's number (forces [N], positions [m], velocities, the
 * string's coordinates): the library's state range; beyond it a step's products overflow */
#define STATE_MAGNITUDE 1e12

static int all_finite(const double *v, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (!(fabs(v[i]) <= STATE_MAGNITUDE)) return 0;   /* also NaN */
    return 1;
}

/* what exit of initialisation derives from the parameters, as it derives it */
static const char *derived_invalid(const model *m, const sstate *s) {
    const block *b = hs_any_block(&m->tab, s->form);
    double feed = HB_TOP_TAKES_FEED[s->top_condition] ? s->feed_velocity : 0.0;
    if (s->form != HB_TOP_FORM[s->top_condition] || !b || s->n != b->n || s->modal != b->modal ||
        s->order != s->extrapolation)
        return "its form, size or extrapolation order is not the one of its parameters";
    if (s->W != s->wob || s->hook_eq != HS_BUOYED_WEIGHT - s->W || s->k3[0] != HS_INTERFACE_STIFFNESS ||
        s->k3[1] != HS_INTERFACE_DAMPING || s->k3[2] != s->W || s->feed[0] != feed ||
        s->feed[1] != s->t_start)
        return "its interface or top is not the one of its parameters";
    if (s->started && !(s->th[0] > s->th[1] && s->th[1] > s->th[2]))
        return "its communication times are not increasing";
    return NULL;
}

/* NULL if `s` can be a state of this build, checked in full; else the reason */
const char *hs_state_invalid(const model *m, const sstate *s) {
    if (s->magic != STATE_MAGIC || s->size != m->size) return "it is not a state of this build";
    if ((s->ready | s->terminated | s->started) & ~1 || (s->modal & ~1)) return "a flag is neither 0 nor 1";
    if (!(fabs(s->t) <= HS_STATE_TIME_LIMIT) || !(fabs(s->t_start) <= HS_STATE_TIME_LIMIT) ||
        s->t < s->t_start)
        return "its times are out of range or t < t_start";
    if (s->form < 0 || s->form > 1 || s->order < 0 || s->order > 2 || s->extrapolation < 0 ||
        s->extrapolation > 2 || s->top_condition < 0 || s->top_condition >= HB_N_TOP_CONDITIONS)
        return "its form, extrapolation order or top condition is out of range";
    if (!memchr(s->error, '\0', sizeof s->error)) return "its error message is not terminated";
    const double reals[] = {s->damping_ratio, s->wob, s->at_rest, s->feed_velocity, s->kp, s->kig,
                            s->interface_force, s->held, s->hook_load, s->top_position,
                            s->top_velocity, s->W, s->hook_eq, s->F_held};
    /* k3 (the interface's constants) is compared with the build's below */
    if (!all_finite(reals, sizeof reals / sizeof *reals) || !all_finite(s->feed, 2) ||
        !all_finite(s->wh, 6) || !all_finite(s->Fh, 3) || !all_finite(s->out, 4))
        return "it holds a number that is not finite or above 1e12 in magnitude";
    for (int i = 0; i < 3; i++)
        if (!(fabs(s->th[i]) <= HS_STATE_TIME_LIMIT + 1.0)) return "its communication times are out of range";
    if (isnan(s->x_in) || isnan(s->v_in)) return "an input is NaN";
    for (int i = 0; i < N_COEFFS; i++)   /* the last exchange's coefficients: any finite scale */
        if (!isfinite(s->c[i])) return "it holds a non-finite number";
    if (!all_finite(s->v, 2 * (size_t)m->tab.nmax))
        return "its string state holds a number that is not finite or above 1e12 in magnitude";
    return s->ready ? derived_invalid(m, s) : NULL;
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
    const char *why = hs_state_invalid(m, state);
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

/* hs_state_invalid for hb_model_deserialize */
static const char *block_invalid(const void *m, const void *state) {
    return hs_state_invalid(m, state);
}

static fmi2Status s_deserialize(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate *state) {
    return hb_model_deserialize(c, in, size, ((model *)c)->size, block_invalid, state);
}

/* fmi2SetRealInputDerivatives (canInterpolateInputs): the first and second time derivatives of the
 * inputs hammer_position and hammer_velocity at the current time, for the next fmi2DoStep only
 * (one without them extrapolates through the history); one not given is 0.  All or none applied. */
static fmi2Status s_set_input_derivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                          const fmi2Integer order[], const fmi2Real value[]) {
    model *m = c;
    sstate *s = m->s;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != HS_VR_hammer_position && vr[i] != HS_VR_hammer_velocity)
            return FAIL(m, "fmi2SetRealInputDerivatives: value reference %u is not an input (hammer_position "
                        "%u, hammer_velocity %u); nothing changed", vr[i], HS_VR_hammer_position,
                        HS_VR_hammer_velocity);
        if (order[i] < 1 || order[i] > 2)
            return FAIL(m, "fmi2SetRealInputDerivatives: order[%zu] = %d is out of range: allowed 1, 2; "
                        "nothing changed", i, (int)order[i]);
        if (!isfinite(value[i]))
            return FAIL(m, "fmi2SetRealInputDerivatives: value[%zu] = %g is not finite; nothing changed", i,
                        value[i]);
    }
    /* der_in = (x', v', x'', v''): the Taylor coefficients c[2..5] of the exchange */
    for (size_t i = 0; i < nvr; i++)
        s->der_in[2 * (order[i] - 1) + (vr[i] == HS_VR_hammer_velocity)] = value[i];
    s->der_given = 1;
    return fmi2OK;
}

void hs_access_fill(hb_wrapper *w) {
    hb_model_fill_values(w, s_get_real, s_set_real, s_get_integer, s_set_integer);
    w->SetRealInputDerivatives = s_set_input_derivatives;
    hb_model_fill_states(w, s_get_state, s_set_state, s_state_size, s_serialize, s_deserialize);
}

/* fmi2Get* and fmi2Set* of the native model backend: parameters and inputs as set (checked
 * against the ranges of hammerbit.model.validation; a vector fmi2SetReal with one refused value
 * applies none), outputs from the state through the kernels' force formulas (hb_forces). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "kernel_api.h"
#include "model_native.h"

/* ------------------------------------------------------------------------------------------ */
static int stored_slot(fmi2ValueReference vr) {
    return vr < HB_SLOT_INDEX_LEN ? HB_SLOT_OF_VR[vr] : -1;
}

/* Initialization Mode: outputs follow the parameters set so far (invalid ones: reported at exit) */
static void refresh(model *m) {
    model_state *s = &m->s;
    if (!s->stale) return;
    s->stale = 0;
    if (s->ready) return;
    model_state trial = *s;
    char err[1024];
    if (hb_commit(&trial, s->value, s->impact_enabled, 0, err, sizeof err)) *s = trial;
}

static double real_output(model *m, fmi2ValueReference vr) {
    model_state *s = &m->s;
    double f[4];
    switch (vr) {
    case HB_VR_hammer_position: return s->y[0] * s->x0;
    case HB_VR_hammer_velocity: return s->y[1] * s->v0;
    case HB_VR_bit_position: return s->y[2] * s->x0;
    case HB_VR_bit_velocity: return s->y[3] * s->v0;
    case HB_VR_rate_of_penetration: {
        double dt = s->t - s->t_start;
        return dt <= 0.0 ? 0.0 : (s->y[2] - s->x3_start) * s->x0 / dt;
    }
    default: break;
    }
    switch (vr) {
    case HB_VR_der_hammer_position: return hb_derivative(m, 0);
    case HB_VR_der_hammer_velocity: return hb_derivative(m, 1);
    case HB_VR_der_bit_position: return hb_derivative(m, 2);
    case HB_VR_der_bit_velocity: return hb_derivative(m, 3);
    default: break;
    }
    hb_forces(s->y, s->ist, s->p, f);
    switch (vr) {
    case HB_VR_spring_force: return f[0] * s->F0;
    case HB_VR_contact_force: return f[1] * s->F0;
    case HB_VR_rock_force: return f[2] * s->F0;
    case HB_VR_friction_force: return f[3] * s->F0;
    default: return NAN;
    }
}

static fmi2Status n_get_real(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                             fmi2Real value[]) {
    model *m = c;
    refresh(m);
    for (size_t i = 0; i < nvr; i++) {
        int k = stored_slot(vr[i]);
        value[i] = k >= 0 ? m->s.value[k] : real_output(m, vr[i]);
    }
    return fmi2OK;
}

static fmi2Status n_get_integer(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2Integer value[]) {
    model *m = c;
    model_state *s = &m->s;
    refresh(m);
    for (size_t i = 0; i < nvr; i++) {
        switch (vr[i]) {
        case HB_VR_stick_slip: value[i] = (fmi2Integer)s->ist[HBK_I_STICK]; break;
        case HB_VR_impact_count: value[i] = (fmi2Integer)s->ist[HBK_I_COUNT0 + HBK_EV_IMPACT]; break;
        case HB_VR_slip_count: value[i] = (fmi2Integer)s->ist[HBK_I_COUNT0 + HBK_EV_SLIP_START]; break;
        case HB_VR_bounce_count: value[i] = (fmi2Integer)s->ist[HBK_I_COUNT0 + HBK_EV_BOUNCE]; break;
        case HB_VR_regime: value[i] = hb_regime_now(s); break;
        case HB_VR_last_status: value[i] = s->last_status; break;
        default: value[i] = 0;
        }
    }
    return fmi2OK;
}

static fmi2Status n_get_boolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                fmi2Boolean value[]) {
    model *m = c;
    refresh(m);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == HB_VR_impact_enabled)
            value[i] = m->s.impact_enabled ? fmi2True : fmi2False;
        else   /* in_contact */
            value[i] = m->s.ist[HBK_I_CONTACT] != HBK_FREE ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

static fmi2Status n_get_string(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                               fmi2String value[]) {
    (void)vr;
    for (size_t i = 0; i < nvr; i++) value[i] = "";
    return hb_fail(c, fmi2Error, "fmi2GetString: the model has no String variables");
}

/* One value of a Real variable checked; the status it earns (the message logged). */
static fmi2Status check_real(model *m, int k, double v) {
    model_state *s = &m->s;
    const hb_stored *d = &HB_STORED[k];
    char rv[40], err[1024];
    if (d->kind == HB_INPUT) {
        if (hb_input_ok(s, k, v)) return fmi2OK;   /* the hot path: no text */
        /* before initialisation the range follows parameters that may still change (in this very
           call): fmi2ExitInitializationMode checks it for the parameters it commits */
        if (!s->ready && isfinite(v)) return fmi2OK;
        hb_input_error(s, k, v, err, sizeof err);
        return hb_fail(m, fmi2Error, "%s", err);
    }
    hb_repr(v, rv, sizeof rv);
    if (s->ready) {
        if (d->kind != HB_TUNABLE) {
            char used[40];
            hb_repr(s->committed[k], used, sizeof used);
            return hb_fail(m, fmi2Error, "parameter '%s' = %s was set after initialisation, but it is "
                        "fixed (causality=parameter, variability=fixed); refused, the value %s stays "
                        "in use", d->name, rv, used);
        }
        if (hb_range_error(d->name, v, &d->range, err, sizeof err)) {
            char have[40];
            hb_repr(s->value[k], have, sizeof have);
            return hb_fail(m, fmi2Error, "invalid tunable %s; refused, the tolerance %s stays in use", err,
                        have);
        }
        return fmi2OK;
    }
    if (hb_range_error(d->name, v, &d->range, err, sizeof err))
        return hb_fail(m, fmi2Warning, "%s; fmi2ExitInitializationMode will fail unless it is corrected",
                    err);
    return fmi2OK;
}

/* fmi2SetReal is atomic: a value refused with fmi2Error leaves every value of the call unset */
static fmi2Status n_set_real(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                             const fmi2Real value[]) {
    model *m = c;
    model_state *s = &m->s;
    s->last_status = fmi2OK;
    fmi2Status st = fmi2OK;
    for (size_t i = 0; i < nvr; i++) {
        int k = stored_slot(vr[i]);
        if (k < 0) return hb_fail(m, fmi2Error, "fmi2SetReal: value reference %u is not settable", vr[i]);
        fmi2Status si = check_real(m, k, value[i]);
        if (si > st) st = si;
    }
    if (st >= fmi2Error) {
        s->last_status = st;
        return st;
    }
    for (size_t i = 0; i < nvr; i++) {
        int k = stored_slot(vr[i]);
        s->value[k] = value[i];
        if (HB_STORED[k].kind == HB_TUNABLE && s->ready) s->dirty = 1;
        if (HB_STORED[k].kind != HB_INPUT) s->stale = 1;
    }
    s->last_status = st;
    return st;
}

static fmi2Status n_set_integer(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2Integer value[]) {
    (void)value, (void)nvr;
    return hb_fail(c, fmi2Error, "fmi2SetInteger: value reference %u is not settable", vr[0]);
}

static fmi2Status n_set_boolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                const fmi2Boolean value[]) {
    model *m = c;
    model_state *s = &m->s;
    s->last_status = fmi2OK;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != HB_VR_impact_enabled)
            return hb_fail(m, fmi2Error, "fmi2SetBoolean: value reference %u is not settable", vr[i]);
        if (s->ready)
            return hb_fail(m, fmi2Error, "parameter 'impact_enabled' = %s was set after initialisation, "
                        "but it is fixed (causality=parameter, variability=fixed); refused, the value "
                        "%s stays in use", value[i] ? "True" : "False",
                        s->committed_impact ? "True" : "False");
    }
    for (size_t i = 0; i < nvr; i++) s->impact_enabled = value[i] != fmi2False;
    s->stale = 1;
    return fmi2OK;
}

static fmi2Status n_set_string(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                               const fmi2String value[]) {
    (void)vr, (void)nvr, (void)value;
    return hb_fail(c, fmi2Error, "fmi2SetString: the model has no String variables; nothing changed");
}


void hb_values_fill(hb_wrapper *w) {
    w->GetReal = n_get_real;
    w->GetInteger = n_get_integer;
    w->GetBoolean = n_get_boolean;
    w->GetString = n_get_string;
    w->SetReal = n_set_real;
    w->SetInteger = n_set_integer;
    w->SetBoolean = n_set_boolean;
    w->SetString = n_set_string;
}

/* fmi2Get*, fmi2Set* and FMU states of the native DrillingSystem backend: inputs checked when they
 * are set (a refused value leaves the input as it was), outputs from the state, and the whole state
 * as plain data (a copy per fmi2GetFMUstate, its bytes when serialized), checked in full before it
 * is used: every integer against its range, every real finite. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model_system.h"

/* ------------------------------------------------------------------------------------------ */
/* Inputs                                                                                      */
/* ------------------------------------------------------------------------------------------ */
/* the names, units and ranges the modelDescription declares (hsys_data.h, from the table and the build) */
static const double MIN_IN[N_INPUTS] = {HSYS_MIN_amplitude, HSYS_MIN_frequency, HSYS_MIN_wob_set_point,
                                        HSYS_MIN_feed_velocity};
static const double MAX_IN[N_INPUTS] = {HSYS_MAX_amplitude, HSYS_MAX_frequency, HSYS_MAX_wob_set_point,
                                        HSYS_MAX_feed_velocity};
static const char *const IN_NAME[N_INPUTS] = {HSYS_NAME_amplitude, HSYS_NAME_frequency, HSYS_NAME_wob_set_point,
                                               HSYS_NAME_feed_velocity};
static const char *const IN_UNIT[N_INPUTS] = {HSYS_UNIT_amplitude, HSYS_UNIT_frequency, HSYS_UNIT_wob_set_point,
                                               HSYS_UNIT_feed_velocity};

const char *sys_input_refused(const sysstate *s, int idx, double v, char *buf, size_t n) {
    char r[40], r2[40];
    (void)s;
    hb_repr(v, r, sizeof r);
    if (!(isfinite(v) && MIN_IN[idx] <= v && v <= MAX_IN[idx])) {
        snprintf(buf, n, "input '%s' = %s is out of range: allowed [%.6g, %.6g] %s", IN_NAME[idx], r,
                 MIN_IN[idx], MAX_IN[idx], IN_UNIT[idx]);
        return buf;
    }
    int unused = (idx == IN_WOB_SET_POINT && HSYS_TOP != HB_TOP_AUTO_DRILLER) ||
                 (idx == IN_FEED_VELOCITY && HSYS_TOP != HB_TOP_FEED);
    if (unused && v != SYS_START_IN[idx]) {
        hb_repr(SYS_START_IN[idx], r2, sizeof r2);
        snprintf(buf, n, "input '%s' = %s has no effect with the top condition '%s' this FMU was built "
                 "with (only %s uses it); allowed %s %s (rebuild with --top %s)", IN_NAME[idx], r,
                 HSYS_TOP_TEXT, idx == IN_FEED_VELOCITY ? "the feed" : "the auto-driller", r2, IN_UNIT[idx],
                 idx == IN_FEED_VELOCITY ? "feed:RATE" : "auto-driller");
        return buf;
    }
    return NULL;
}

/* ------------------------------------------------------------------------------------------ */
/* Values                                                                                       */
/* ------------------------------------------------------------------------------------------ */
static int input_index(fmi2ValueReference vr) {
    switch (vr) {
    case HSYS_VR_amplitude: return IN_AMPLITUDE;
    case HSYS_VR_frequency: return IN_FREQUENCY;
    case HSYS_VR_wob_set_point: return IN_WOB_SET_POINT;
    case HSYS_VR_feed_velocity: return IN_FEED_VELOCITY;
    default: return -1;
    }
}

static const double *real_output(const sysstate *s, fmi2ValueReference vr) {
    switch (vr) {
    case HSYS_VR_tolerance: return &s->tolerance;
    case HSYS_VR_bit_position: return &s->bit_position;
    case HSYS_VR_rate_of_penetration: return &s->rate_of_penetration;
    case HSYS_VR_wob: return &s->wob;
    case HSYS_VR_mean_wob: return &s->mean_wob;
    case HSYS_VR_hook_load: return &s->hook_load;
    case HSYS_VR_hammer_position: return &s->hammer_position;
    case HSYS_VR_hammer_velocity: return &s->hammer_velocity;
    case HSYS_VR_contact_force: return &s->contact_force;
    case HSYS_VR_coupling_error: return &s->coupling_error;
    default: return NULL;
    }
}

HB_GET_REAL(s_get_real) {
    model *m = c;
    for (size_t i = 0; i < nvr; i++) {
        int k = input_index(vr[i]);
        const double *p = k >= 0 ? &m->s.in[k] : real_output(&m->s, vr[i]);
        if (!p) return FAIL(m, "fmi2GetReal: unknown value reference %u", vr[i]);
        value[i] = *p;
    }
    return fmi2OK;
}

HB_SET_REAL(s_set_real) {
    model *m = c;
    char why[512];
    for (size_t i = 0; i < nvr; i++) {      /* all checked first: a refused call changes nothing */
        int k = input_index(vr[i]);
        if (vr[i] == HSYS_VR_tolerance) continue;
        if (k < 0) return FAIL(m, "fmi2SetReal: value reference %u is not an input or a parameter", vr[i]);
        if (sys_input_refused(&m->s, k, value[i], why, sizeof why))
            return FAIL(m, "fmi2SetReal: %s; value refused, input unchanged", why);
    }
    for (size_t i = 0; i < nvr; i++) {
        int k = input_index(vr[i]);
        if (k >= 0) m->s.in[k] = value[i];
        else m->s.tolerance = value[i];
    }
    return fmi2OK;
}

static int system_integer(const void *m, fmi2ValueReference vr, fmi2Integer *out) {
    const sysstate *s = &((const model *)m)->s;
    switch (vr) {
    case HSYS_VR_stick_slip: *out = (fmi2Integer)s->stick_slip; return 1;
    case HSYS_VR_impact_count: *out = (fmi2Integer)s->impact_count; return 1;
    case HSYS_VR_slip_count: *out = (fmi2Integer)s->slip_count; return 1;
    case HSYS_VR_regime: *out = (fmi2Integer)s->regime; return 1;
    default: return 0;
    }
}

HB_GET_INTEGER(s_get_integer) {
    return hb_model_get_integers(c, vr, nvr, value, system_integer);
}

HB_SET_INTEGER(s_set_integer) {
    (void)vr, (void)value;
    return nvr ? FAIL(c, "fmi2SetInteger: the model has no Integer input or parameter") : fmi2OK;
}

/* ------------------------------------------------------------------------------------------ */
/* FMU states: the whole state as plain data, checked in full                                  */
/* ------------------------------------------------------------------------------------------ */
static int all_finite(const double *v, size_t n) {
    /* (the subsystem's values are compared with the build's instead) */
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* why one run's solver arrays (the main run's or the shadow's) are refused (NULL: accepted; the
 * reasons that name a value are written into why[n]) */
static const char *solution_invalid(const sysstate *s, const double *y, const int64_t *ist, const double *fst,
                                    const double *opts, char *why, size_t n) {
    if (!all_finite(y, SYS_NY)) return "its solver state holds a non-finite number";
    /* the hybrid system is stiff far outside its physical range (a hammer 100 x0 inside the bit, a
     * string state of 1e12): the solver would spend minutes there before its step-storm limit */
    char a[40], b[40];
    for (int i = 0; i < SYS_NY; i++)
        if (!(fabs(y[i]) <= SYS_STATE_LIMIT)) {
            hb_repr(y[i], a, sizeof a);
            snprintf(why, n, "its solver state %d is %s of its scale, beyond the physical range of %g", i, a,
                     SYS_STATE_LIMIT);
            return why;
        }
    if (!(fabs(y[HSYS_X_HAMMER] - y[HSYS_X_BIT]) <= SYS_GAP_LIMIT)) {
        hb_repr((y[HSYS_X_HAMMER] - y[HSYS_X_BIT]) * HSYS_X0, a, sizeof a);
        hb_repr(SYS_GAP_LIMIT * HSYS_X0, b, sizeof b);
        snprintf(why, n, "its hammer is %s m from the bit, beyond the physical range of %s m (%g length scales)",
                 a, b, SYS_GAP_LIMIT);
        return why;
    }
    if (memcmp(&y[4 + HSYS_IC], &HSYS_Y0[4 + HSYS_IC], sizeof(double)) != 0)
        return "its subsystem's constant state is not 1";
    for (int i = 0; i < HSYS_N_OPTS; i++) {
        int tol = i == HSYS_O_RTOL || i == HSYS_O_ATOL;
        if (!tol && memcmp(&opts[i], &HSYS_OPTS[i], sizeof(double)) != 0)
            return "its solver options are not this build's";
    }
    for (int i = 0; i < HSYS_N_FSTATE; i++)
        if (!(isfinite(fst[i]) || (i == HSYS_F_DRIVE_MIN && fst[i] == INFINITY)))
            return "its solver state holds a non-finite number";
    if (s->ready && !(fabs(fst[HSYS_F_T] - HSYS_OMEGA * s->t) <= 1e-6 * fmax(1.0, fabs(HSYS_OMEGA * s->t))))
        return "its solver time is not its communication time";
    if (!(fst[HSYS_F_H] > 0.0)) return "its proposed solver step is not positive";
    if (ist[HSYS_I_STICK] != HSYS_STICK && ist[HSYS_I_STICK] != HSYS_SLIP) return "its stick mode is unknown";
    if (ist[HSYS_I_CONTACT] < HSYS_FREE || ist[HSYS_I_CONTACT] > HSYS_CLAMPED) return "its contact mode is unknown";
    if (ist[HSYS_I_BOUNCE] < 0 || ist[HSYS_I_BOUNCE] > 1) return "its bounce flag is neither 0 nor 1";
    for (int i = 0; i < HSYS_N_ISTATE; i++) {
        /* the forcing-period indices may be -1 (none yet) or negative before t = 0; the rest count */
        int64_t lo = (i == HSYS_I_WIN || i == HSYS_I_SWIN) ? -(INT64_C(1) << 40) : 0;
        if (ist[i] < lo || ist[i] > (INT64_C(1) << 40)) return "a counter or index of its solver state is out of range";
    }
    return NULL;
}

/* the solver tolerances of both runs, as fmi2ExitInitializationMode sets them from a tolerance in
 * range (a tolerance of 1e-300 would never finish a step); before it, the build's */
static const char *tolerances_invalid(const sysstate *s) {
    const double *o = s->opts, *so = s->shadow.opts;
    if (!s->ready)
        return memcmp(o, HSYS_OPTS, sizeof s->opts) != 0 || memcmp(so, HSYS_OPTS, sizeof s->opts) != 0
                   ? "its solver options are not this build's" : NULL;
    double rtol = o[HSYS_O_RTOL], atol = rtol * HSYS_ATOL_PER_RTOL;
    if (!(HSYS_MIN_tolerance * HSYS_RTOL_PER_TOLERANCE <= rtol && rtol <= HSYS_MAX_tolerance * HSYS_RTOL_PER_TOLERANCE))
        return "its solver tolerance is out of range";
    double srtol = rtol * SYS_SHADOW_RTOL_FACTOR, satol = atol * SYS_SHADOW_RTOL_FACTOR;
    if (memcmp(&o[HSYS_O_ATOL], &atol, sizeof atol) != 0 || memcmp(&so[HSYS_O_RTOL], &srtol, sizeof srtol) != 0 ||
        memcmp(&so[HSYS_O_ATOL], &satol, sizeof satol) != 0)
        return "its solver tolerances are not those of one tolerance";
    return NULL;
}

const char *sys_state_invalid(const sysstate *s, char *why, size_t n) {
    if (s->magic != SYS_STATE_MAGIC || s->size != sizeof *s) return "it is not a state of this build";
    if ((s->ready | s->terminated) & ~1) return "a flag is neither 0 nor 1";
    if (!(isfinite(s->t) && isfinite(s->t_start) && fabs(s->t) <= 1e9 && fabs(s->t_start) <= 1e9))
        return "its time is not finite or beyond 1e9 s";
    if (!(isfinite(s->tolerance) && HSYS_MIN_tolerance <= s->tolerance && s->tolerance <= HSYS_MAX_tolerance))
        return "its tolerance is out of range";
    for (int i = 0; i < N_INPUTS; i++)
        if (sys_input_refused(s, i, s->in[i], why, n) || sys_input_refused(s, i, s->applied[i], why, n))
            return "an input is out of range";
    const double *reals[] = {&s->bit_position, &s->rate_of_penetration, &s->wob, &s->mean_wob, &s->hook_load,
                             &s->hammer_position, &s->hammer_velocity, &s->contact_force, &s->coupling_error};
    for (size_t i = 0; i < sizeof reals / sizeof reals[0]; i++)
        if (!isfinite(*reals[i])) return "an output is not finite";
    if (s->stick_slip < 0 || s->stick_slip > 1 || s->impact_count < 0 || s->slip_count < 0 || s->regime < 0 ||
        s->regime > 31)
        return "an integer output is out of range";
    if (!(isfinite(s->penetration_scale) && s->penetration_scale >= 0.0)) return "its penetration scale is out of range";
    /* the parameters, options and subsystem are the build's, but for what the inputs set */
    for (int i = 0; i < HSYS_N_P; i++) {
        int input = i == HSYS_P_A || i == HSYS_P_ETA || i == HSYS_P_PHI;
        if (input ? !isfinite(s->p[i]) : memcmp(&s->p[i], &HSYS_P[i], sizeof(double)) != 0)
            return "its kernel parameters are not this build's";
    }
    /* the forcing as apply_inputs sets it from the applied inputs (a frequency of 1e12 times the
     * input's would make the solver step a billion times a period) */
    double a = s->applied[IN_AMPLITUDE] / HSYS_F0, eta = HB_TWO_PI * s->applied[IN_FREQUENCY] / HSYS_OMEGA;
    if (s->ready && (memcmp(&s->p[HSYS_P_A], &a, sizeof a) != 0 || memcmp(&s->p[HSYS_P_ETA], &eta, sizeof eta) != 0))
        return "its forcing is not its applied inputs'";
    if (!(s->p[HSYS_P_ETA] > 0.0 && s->p[HSYS_P_A] >= 0.0 && s->p[HSYS_P_PHI] >= 0.0 && s->p[HSYS_P_PHI] <= HB_TWO_PI))
        return "its forcing is out of range";
    double dv = s->applied[IN_FEED_VELOCITY] - HSYS_FEED_BUILD, dw = s->applied[IN_WOB_SET_POINT] - HSYS_WOB_BUILD;
    for (int64_t i = 0; i < HSYS_NZ; i++)
        for (int64_t k = HSYS_CSR[i]; k < HSYS_CSR[i + 1]; k++) {
            double want = k == HSYS_POS_IC[i] ? HSYS_COL_IC[i] + dv * HSYS_DCOL_V[i] + dw * HSYS_DCOL_W[i] : HSYS_AX[k];
            if (memcmp(&s->lin[k], &want, sizeof want) != 0) return "its subsystem is not this build's";
        }
    for (int64_t i = 0; i < HSYS_NZ + 2; i++) {
        double want = i < HSYS_NZ ? HSYS_G[i] : HSYS_GLINK[i - HSYS_NZ];
        if (i == HSYS_IC) want = HSYS_G_IC + dv * HSYS_DG_V + dw * HSYS_DG_W;
        if (memcmp(&s->lin[HSYS_NNZ + i], &want, sizeof want) != 0) return "its subsystem is not this build's";
    }
    const char *why_tol = tolerances_invalid(s);
    if (why_tol) return why_tol;
    const char *why_regime = sys_regime_invalid(s);
    if (why_regime) return why_regime;
    const char *why_run = solution_invalid(s, s->y, s->ist, s->fst, s->opts, why, n);
    return why_run ? why_run : solution_invalid(s, s->shadow.y, s->shadow.ist, s->shadow.fst, s->shadow.opts, why, n);
}

static fmi2Status s_get_state(fmi2Component c, fmi2FMUstate *state) {
    model *m = c;
    sysstate *copy = malloc(sizeof *copy);
    if (!copy) return FAIL(m, "fmi2GetFMUstate: out of memory");
    memcpy(copy, &m->s, sizeof *copy);
    *state = copy;
    return fmi2OK;
}

static fmi2Status s_set_state(fmi2Component c, fmi2FMUstate state) {
    model *m = c;
    char buf[SYS_WHY_SIZE];
    const char *why = sys_state_invalid(state, buf, sizeof buf);
    if (why) return FAIL(m, "fmi2SetFMUstate: %s; state unchanged", why);
    memcpy(&m->s, state, sizeof m->s);
    return fmi2OK;
}

static fmi2Status s_state_size(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)c, (void)state;
    *size = sizeof(sysstate);
    return fmi2OK;
}

static fmi2Status s_serialize(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size) {
    if (size != sizeof(sysstate))
        return FAIL(c, "fmi2SerializeFMUstate: size = %zu, the state needs %zu bytes", size, sizeof(sysstate));
    memcpy(out, state, size);
    return fmi2OK;
}

/* sys_state_invalid for hb_model_deserialize: the system's checks need no instance */
static const char *checked(const void *m, const void *state) {
    (void)m;
    static _Thread_local char buf[SYS_WHY_SIZE];   /* read by the caller before this thread's next call */
    return sys_state_invalid(state, buf, sizeof buf);
}

static fmi2Status s_deserialize(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate *state) {
    return hb_model_deserialize(c, in, size, sizeof(sysstate), checked, state);
}

void sys_access_fill(hb_wrapper *w) {
    hb_model_fill_values(w, s_get_real, s_set_real, s_get_integer, s_set_integer);
    hb_model_fill_states(w, s_get_state, s_set_state, s_state_size, s_serialize, s_deserialize);
}

/* The native model backend of DrillingSystem.fmu: hammer, bit, string and top condition as one
 * hybrid system (model_system.h), integrated by the library's compiled event-located driver with
 * the string as its linear subsystem, as the co-simulation's monolithic reference does.
 *
 * The master's communication step is only where it reads and writes: a step advances the solver
 * to t + h on its own adaptive steps and events.  Inputs set between steps take effect at the
 * step's start: the amplitude and frequency in the kernels' parameters (the forcing's phase kept
 * continuous), the feed velocity and the auto-driller's set point in the constant state's column
 * of the subsystem (they enter it affinely; the generated header carries the derivatives). */
#include <stdio.h>
#include <stdlib.h>
#include <float.h>
#include <string.h>

#include "model_system.h"

static void apply_inputs(sysstate *s);

static void set_start_values(model *m) {
    sysstate *s = &m->s;
    memset(s, 0, sizeof *s);
    s->magic = SYS_STATE_MAGIC;
    s->size = (uint32_t)sizeof *s;
    s->tolerance = HSYS_START_tolerance;
    memcpy(s->in, SYS_START_IN, sizeof s->in);
    memcpy(s->applied, SYS_START_IN, sizeof s->applied);
    memcpy(s->y, HSYS_Y0, sizeof s->y);
    memcpy(s->ist, HSYS_IST0, sizeof s->ist);
    memcpy(s->fst, HSYS_FST0, sizeof s->fst);
    memcpy(s->p, HSYS_P, sizeof s->p);
    memcpy(s->opts, HSYS_OPTS, sizeof s->opts);
    memcpy(s->lin, HSYS_AX, sizeof(double) * HSYS_NNZ);
    memcpy(s->lin + HSYS_NNZ, HSYS_G, sizeof(double) * HSYS_NZ);
    memcpy(s->lin + HSYS_NNZ + HSYS_NZ, HSYS_GLINK, 2 * sizeof(double));
    /* the start inputs into the subsystem as a step applies them, so that a state saved before
       initialisation passes the state check (which recomputes them from 'applied') */
    apply_inputs(s);
    memcpy(s->shadow.y, s->y, sizeof s->y);
    memcpy(s->shadow.ist, s->ist, sizeof s->ist);
    memcpy(s->shadow.fst, s->fst, sizeof s->fst);
    memcpy(s->shadow.opts, s->opts, sizeof s->opts);
    sys_regime_start(s);
    sys_outputs(s, 0.0, 0.0, 0.0, 0.0);
    snprintf(s->error, sizeof s->error, "not initialised (fmi2ExitInitializationMode)");
}

/* ------------------------------------------------------------------------------------------ */
/* Inputs                                                                                      */
/* ------------------------------------------------------------------------------------------ */
/* the inputs as set into the kernels' parameters and the subsystem */
static void apply_inputs(sysstate *s) {
    s->p[HSYS_P_A] = s->in[IN_AMPLITUDE] / HSYS_F0;
    double eta = HB_TWO_PI * s->in[IN_FREQUENCY] / HSYS_OMEGA, eta0 = s->p[HSYS_P_ETA];
    if (eta != eta0) {
        /* the forcing's phase continuous at the current time */
        double phi = fmod(s->p[HSYS_P_PHI] + (eta0 - eta) * s->fst[HSYS_F_T], HB_TWO_PI);
        s->p[HSYS_P_PHI] = phi < 0.0 ? phi + HB_TWO_PI : phi;
        s->p[HSYS_P_ETA] = eta;
    }
    double dv = s->in[IN_FEED_VELOCITY] - HSYS_FEED_BUILD, dw = s->in[IN_WOB_SET_POINT] - HSYS_WOB_BUILD;
    for (int64_t i = 0; i < HSYS_NZ; i++)
        if (HSYS_POS_IC[i] >= 0) s->lin[HSYS_POS_IC[i]] = HSYS_COL_IC[i] + dv * HSYS_DCOL_V[i] + dw * HSYS_DCOL_W[i];
    s->lin[HSYS_NNZ + HSYS_IC] = HSYS_G_IC + dv * HSYS_DG_V + dw * HSYS_DG_W;
    memcpy(s->applied, s->in, sizeof s->applied);
}

/* ------------------------------------------------------------------------------------------ */
/* Outputs                                                                                     */
/* ------------------------------------------------------------------------------------------ */
/* the WOB impulse over a step of length dtau from tau_a [F0 / Omega]: the hammer's momentum balance
 * x2' = drive + f_link - wob, with y[4 + IQ] = the integral of f_link over the step */
static double wob_impulse(const double *y, const double *p, double dtau, double x2a, double tau_a) {
    double a = p[HSYS_P_A], eta = p[HSYS_P_ETA], phi = p[HSYS_P_PHI];
    double forcing = a / eta * (cos(eta * tau_a + phi) - cos(eta * (tau_a + dtau) + phi));
    double constant = (p[HSYS_P_B] + p[HSYS_P_FEXT]) * dtau;
    return y[4 + HSYS_IQ] + forcing + constant - (y[HSYS_V_HAMMER] - x2a);
}

void sys_outputs(sysstate *s, double dtau, double x2a, double x3a, double tau_a) {
    double f[4];
    hsys_forces(s->y, s->ist, s->p, f);
    const double *y = s->y;
    s->wob = f[2] * HSYS_F0;
    s->contact_force = f[1] * HSYS_F0;
    if (dtau > 0.0) {
        s->mean_wob = wob_impulse(y, s->p, dtau, x2a, tau_a) / dtau * HSYS_F0;
        s->rate_of_penetration = (y[HSYS_X_BIT] - x3a) / dtau * HSYS_X0 * HSYS_OMEGA;
    } else {
        s->mean_wob = s->wob;
        s->rate_of_penetration = y[HSYS_V_BIT] * HSYS_X0 * HSYS_OMEGA;
    }
    s->bit_position = y[HSYS_X_BIT] * HSYS_X0;
    s->hammer_position = y[HSYS_X_HAMMER] * HSYS_X0;
    s->hammer_velocity = y[HSYS_V_HAMMER] * HSYS_X0 * HSYS_OMEGA;
    double hook = 0.0;
    for (int64_t i = 0; i < HSYS_NZ; i++) hook += HSYS_HOOK_ROW[i] * y[4 + i];
    s->hook_load = HSYS_HOOK_EQ + hook;
    s->stick_slip = s->ist[HSYS_I_STICK] == HSYS_STICK;
    s->impact_count = s->ist[HSYS_I_COUNT0 + HSYS_EV_IMPACT];
    s->slip_count = s->ist[HSYS_I_COUNT0 + HSYS_EV_SLIP_START];
}

/* the estimate of the main run's error over a step of length dtau from tau_a (x2a, x3a: the hammer
 * velocity of each run there): its difference from the shadow run, in
 * the bit position (relative to the largest penetration of either run so far) and in the WOB
 * impulse over the step (relative), whichever is larger */
static double error_estimate(sysstate *s, double dtau, double x2a, double x2a_shadow, double tau_a) {
    const double *ys = s->shadow.y;
    double xm = s->y[HSYS_X_BIT], xs = ys[HSYS_X_BIT];
    s->penetration_scale = fmax(s->penetration_scale, fmax(fabs(xm), fabs(xs)));
    double pen = s->penetration_scale > 0.0 ? fabs(xm - xs) / s->penetration_scale : 0.0;
    double im = wob_impulse(s->y, s->p, dtau, x2a, tau_a), is = wob_impulse(ys, s->p, dtau, x2a_shadow, tau_a);
    double wob = fabs(im - is) / fmax(fabs(is), DBL_MIN);
    return fmax(pen, wob);
}

/* ------------------------------------------------------------------------------------------ */
/* Life cycle                                                                                  */
/* ------------------------------------------------------------------------------------------ */
static fmi2Component s_instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String uri,
                                   const fmi2CallbackFunctions *cb, fmi2Boolean visible,
                                   fmi2Boolean logging) {
    (void)type, (void)guid, (void)uri, (void)visible, (void)logging;
    model *m = hb_model_new(sizeof *m, name, cb);
    if (!m) return NULL;
    memcpy(m->csr, HSYS_CSR, sizeof m->csr);
    memcpy(m->H, HSYS_H, sizeof m->H);
    set_start_values(m);
    return m;
}

static void s_free_instance(fmi2Component c) {
    if (c) hb_model_free(c);
}

/* the largest |time| a run may reach [s] (the kernels' time range, with margin) */
#define SYS_TIME_LIMIT 1e9
/* a communication point within this fraction of max(|t|, h) of the FMU's time t is t (a master's
 * summed step sizes drift by rounding) */
#define SYS_TIME_TOLERANCE 1e-9
/* the shortest advance the solver is asked for [s]: a master's leftover sliver (1e-13 s to land on
 * an output point) moves the FMU's clock only, and the solver catches up at the next step, so that
 * slivers leave its steps and events as they would be without them */
#define SYS_MIN_ADVANCE 1e-9

static fmi2Status s_setup_experiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                                     fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined, (void)tol;
    model *m = c;
    char r[40];
    if (!(isfinite(start) && fabs(start) <= SYS_TIME_LIMIT)) {
        hb_repr(start, r, sizeof r);
        return FAIL(m, "fmi2SetupExperiment: startTime = %s s is out of range: allowed [-1e9, 1e9] s", r);
    }
    if (stop_defined && !(isfinite(stop) && stop >= start && fabs(stop) <= SYS_TIME_LIMIT)) {
        hb_repr(stop, r, sizeof r);
        return FAIL(m, "fmi2SetupExperiment: stopTime = %s s is out of range: allowed [startTime, 1e9] s", r);
    }
    m->s.t_start = m->s.t = start;
    return fmi2OK;
}

static fmi2Status s_exit_init(fmi2Component c) {
    model *m = c;
    sysstate *s = &m->s;
    char bad[512], r[40];
    if (!(isfinite(s->tolerance) && HSYS_MIN_tolerance <= s->tolerance && s->tolerance <= HSYS_MAX_tolerance)) {
        hb_repr(s->tolerance, r, sizeof r);
        snprintf(s->error, sizeof s->error, "initialisation failed: parameter 'tolerance' = %s is out of "
                 "range: allowed [%g, %g]", r, HSYS_MIN_tolerance, HSYS_MAX_tolerance);
        return FAIL(m, "%s", s->error);
    }
    for (int i = 0; i < N_INPUTS; i++)
        if (sys_input_refused(s, i, s->in[i], bad, sizeof bad)) {
            snprintf(s->error, sizeof s->error, "initialisation failed: %s", bad);
            return FAIL(m, "%s", s->error);
        }
    double in[N_INPUTS];
    memcpy(in, s->in, sizeof in);
    double t_start = s->t_start, tol = s->tolerance;
    set_start_values(m);
    memcpy(s->in, in, sizeof in);
    s->tolerance = tol;
    s->t_start = s->t = t_start;
    s->fst[HSYS_F_T] = HSYS_OMEGA * t_start;
    if (s->fst[HSYS_F_T_STICK] >= 0.0) s->fst[HSYS_F_T_STICK] = s->fst[HSYS_F_T];
    s->opts[HSYS_O_RTOL] = tol * HSYS_RTOL_PER_TOLERANCE;
    s->opts[HSYS_O_ATOL] = s->opts[HSYS_O_RTOL] * HSYS_ATOL_PER_RTOL;
    memcpy(s->shadow.y, s->y, sizeof s->y);
    memcpy(s->shadow.ist, s->ist, sizeof s->ist);
    memcpy(s->shadow.fst, s->fst, sizeof s->fst);
    memcpy(s->shadow.opts, s->opts, sizeof s->opts);
    s->shadow.opts[HSYS_O_RTOL] *= SYS_SHADOW_RTOL_FACTOR;
    s->shadow.opts[HSYS_O_ATOL] *= SYS_SHADOW_RTOL_FACTOR;
    sys_regime_start(s);
    apply_inputs(s);
    s->ready = 1;
    s->error[0] = '\0';
    sys_outputs(s, 0.0, 0.0, 0.0, 0.0);
    return fmi2OK;
}

HB_MODEL_TERMINATE_RESET(&((model *)c)->s)

/* ------------------------------------------------------------------------------------------ */
/* fmi2DoStep                                                                                   */
/* ------------------------------------------------------------------------------------------ */
/* one run (the main or the shadow) advanced to tau_end; its status (HSYS_ST_DONE: arrived) */
static int64_t advance_run(model *m, double *y, int64_t *ist, double *fst, double *opts, double tau_end) {
    sysstate *s = &m->s;
    y[4 + HSYS_IQ] = 0.0;                 /* the link force's integral over this step */
    fst[HSYS_F_DRIVE_MIN] = INFINITY;     /* the lowest drive on the bit in this step */
    int64_t st;
    hb_kernel_raised();
    do {
        double before = fst[HSYS_F_T];
        st = hsys_advance(y, ist, fst, tau_end, s->p, opts, HSYS_NZ, m->csr, s->lin, m->H);
        if (st == HSYS_ST_MAX_STEPS && !(fst[HSYS_F_T] > before)) break;
    } while (st == HSYS_ST_MAX_STEPS);
    return hb_kernel_raised() ? -1 : st;
}

/* the end of a step: a state fmi2SetFMUstate would refuse (a bit run away beyond the physical
 * range, a hammer thrown metres from the bit) is not kept but refused with its reason, so that every
 * state the FMU holds can be restored; m->kept is the state before the step */
static fmi2Status refuse_if_unrestorable(model *m) {
    char why[SYS_WHY_SIZE], reason[SYS_WHY_SIZE + 60];
    const char *refused = sys_state_invalid(&m->s, why, sizeof why);
    if (!refused) return fmi2OK;
    snprintf(reason, sizeof reason, "the state it ends in would leave the FMU's range (%s)", refused);
    return hb_model_step_put_back(m, &m->s, &m->kept, sizeof m->s, m->kept.t, m->s.t, reason);
}

static fmi2Status s_do_step(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    model *m = c;
    sysstate *s = &m->s;
    char a[40];
    if (hb_model_step_check(m, s->ready ? NULL : s->error, s->t, t, h, SYS_TIME_TOLERANCE) != fmi2OK)
        return fmi2Error;
    if (!(fabs(s->t + h) <= SYS_TIME_LIMIT)) {
        hb_repr(s->t + h, a, sizeof a);
        return FAIL(m, "the step would end at t = %s s, beyond the FMU's time range [-1e9, 1e9] s; step "
                    "refused, state unchanged", a);
    }
    if (memcmp(s->in, s->applied, sizeof s->in) != 0) apply_inputs(s);
    double tau_end = HSYS_OMEGA * (s->t + h);
    if (tau_end - s->fst[HSYS_F_T] < SYS_MIN_ADVANCE * HSYS_OMEGA) {
        s->t = t + h;
        sys_outputs(s, 0.0, 0.0, 0.0, 0.0);
        return fmi2OK;
    }
    /* kept to put back if a solver fails: the state stays at t */
    memcpy(&m->kept, s, sizeof *s);
    double tau_a = s->fst[HSYS_F_T], x2a = s->y[HSYS_V_HAMMER], x3a = s->y[HSYS_X_BIT];
    double x2a_shadow = s->shadow.y[HSYS_V_HAMMER], x3a_shadow = s->shadow.y[HSYS_X_BIT];
    int64_t bounces = s->ist[HSYS_I_COUNT0 + HSYS_EV_BOUNCE];
    int64_t st = advance_run(m, s->y, s->ist, s->fst, s->opts, tau_end);
    if (st == HSYS_ST_DONE) st = advance_run(m, s->shadow.y, s->shadow.ist, s->shadow.fst, s->shadow.opts, tau_end);
    if (st != HSYS_ST_DONE) {
        memcpy(s, &m->kept, sizeof *s);
        hb_repr(s->t, a, sizeof a);
        return FAIL(m, "fmi2DoStep failed at t = %s s: the solver stopped (status %lld: an event storm, a "
                    "step below the time resolution or a non-finite state); state unchanged", a,
                    (long long)st);
    }
    s->t = t + h;
    double dtau = s->fst[HSYS_F_T] - tau_a;
    double difference = error_estimate(s, dtau, x2a, x2a_shadow, tau_a);
    s->coupling_error = difference;
    if (difference > s->tolerance) {
        /* the main run left the tolerance in this step (an event its steps handled otherwise, such
         * as a grazing stick, or a mean WOB near zero that its relative error is taken against): it
         * goes on from the shadow's more accurate state, and the outputs are the shadow's.  Their
         * error is the shadow's: the difference scaled down by the ratio of the two runs' errors
         * (Richardson), an upper bound where the main run missed an event the shadow caught */
        memcpy(s->y, s->shadow.y, sizeof s->y);
        memcpy(s->ist, s->shadow.ist, sizeof s->ist);
        memcpy(s->fst, s->shadow.fst, sizeof s->fst);
        x2a = x2a_shadow, x3a = x3a_shadow;
        s->coupling_error = difference / SYS_SHADOW_ERROR_RATIO;
        char at[40], d[40];
        hb_repr(t + h, at, sizeof at);
        hb_repr(difference, d, sizeof d);
        hb_model_log(m, fmi2OK, "step to t = %s s corrected: the main run differed from the shadow by %s, "
                     "beyond tolerance; it goes on from the shadow's state", at, d);
    }
    sys_outputs(s, dtau, x2a, x3a, tau_a);
    s->regime = 0;
    if (s->ist[HSYS_I_COUNT0 + HSYS_EV_BOUNCE] > bounces || s->ist[HSYS_I_BOUNCE] == 1) s->regime |= HB_REGIME_BOUNCE;
    if (s->fst[HSYS_F_DRIVE_MIN] < 0.0) s->regime |= HB_REGIME_TENSION;
    sys_regime_step(m, s->mean_wob / HSYS_F0 * dtau, dtau);
    s->regime |= s->rg.verdict;
    return refuse_if_unrestorable(m);
}

/* ------------------------------------------------------------------------------------------ */
/* The model's functions for the backend table (model.h)                                        */
/* ------------------------------------------------------------------------------------------ */
void hb_model_fill(hb_wrapper *w) {
    hb_model_fill_life_cycle(w, s_free_instance, s_setup_experiment, s_exit_init, s_terminate, s_reset);
    sys_access_fill(w);
    w->DoStep = s_do_step;
    w->Instantiate = s_instantiate;
}

/* The native model backend of the front: HammerBitRock's co-simulation slave in C around the
 * library's compiled kernels (the native flavour of the FMU; no Python in the process).
 *
 * front.c keeps the FMI state machine, the checks of value references and settability, the
 * resource URI, the logging rules and the FMU-state header; it calls this backend through the
 * same table (hb_W) it fills with pythonfmu's functions in the Python flavour.  This file does
 * what the Python slave (hammerbit.model.slave) does per call:
 *   - parameters and inputs as set, validated against the ranges of hammerbit.model.validation
 *     (written into hb_native.h by the build), at fmi2ExitInitializationMode as a whole;
 *   - SI -> the paper's groups -> the kernel's parameter vector (model_params.c), checks and
 *     messages (model_checks.c);
 *   - fmi2DoStep: the inputs held over the step, one call of the compiled solver driver to the
 *     step's end, the state restored and fmi2Discard if it fails;
 *   - values and outputs (model_values.c): outputs from the state through the kernels' own
 *     force formulas (hb_forces);
 *   - FMU state: the whole model state as plain data (model_state.c).
 * Every call records the FMI status it returns in last_status and logs every non-OK status with
 * a message naming the variable, its value and the allowed range. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front.h"
#include "kernel_api.h"
#include "model.h"
#include "model_native.h"

/* Communication times are compared with an absolute tolerance: 1 ns, or a few units in the last
 * place where t is so large that its doubles lie farther apart (a master computing t0 + n h is
 * within it, and a step never skips a stretch of time) */
#define TIME_ABS_TOL 1e-9
#define TIME_ULPS 4.0

/* ------------------------------------------------------------------------------------------ */
/* Life cycle                                                                                  */
/* ------------------------------------------------------------------------------------------ */
static void set_start_values(model_state *s) {
    memset(s, 0, sizeof *s);
    s->magic = MODEL_STATE_MAGIC;
    s->size = (uint32_t)sizeof *s;
    for (int i = 0; i < HB_NSTORED; i++) s->value[i] = HB_STORED[i].start;
    s->impact_enabled = HB_START_IMPACT_ENABLED;
    snprintf(s->error, sizeof s->error,
             "the FMU is not initialised (call fmi2ExitInitializationMode first)");
    char err[512];
    hb_commit(s, s->value, s->impact_enabled, 0, err, sizeof err);   /* outputs before initialisation */
    s->stale = 0;
}

static fmi2Component n_instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String uri,
                                   const fmi2CallbackFunctions *cb, fmi2Boolean visible,
                                   fmi2Boolean logging) {
    (void)type, (void)guid, (void)uri, (void)visible, (void)logging;
    model *m = hb_model_new(sizeof *m, name, cb);
    if (!m) return NULL;
    set_start_values(&m->s);
    return m;
}

static void n_free_instance(fmi2Component c) {
    hb_model_free(c);
}

static fmi2Status n_setup_experiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                                     fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)stop_defined, (void)stop;
    model *m = c;
    m->s.last_status = fmi2OK;
    if (!isfinite(start)) {
        char rv[40], old[40];
        hb_repr(start, rv, sizeof rv);
        hb_repr(m->s.t_start, old, sizeof old);
        return hb_fail(m, fmi2Error, "fmi2SetupExperiment: startTime = %s s is not finite; refused, the "
                    "start time stays %s s", rv, old);
    }
    m->s.t_start = m->s.t = start;
    m->s.stale = 1;
    if (tol_defined) {
        const hb_range *r = &HB_STORED[HBS_tolerance].range;
        if (hb_contains(r, tol)) {
            m->s.value[HBS_tolerance] = tol;
        } else {
            char rv[40], have[40];
            hb_repr(tol, rv, sizeof rv);
            hb_repr(m->s.value[HBS_tolerance], have, sizeof have);
            return hb_fail(m, fmi2Warning, "fmi2SetupExperiment: tolerance = %s is outside %s; the FMU's "
                        "tolerance %s is used", rv, r->text, have);
        }
    }
    return fmi2OK;
}

static fmi2Status n_enter_init(fmi2Component c) {
    ((model *)c)->s.last_status = fmi2OK;
    return fmi2OK;
}

static fmi2Status n_exit_init(fmi2Component c) {
    model *m = c;
    model_state *s = &m->s;
    s->last_status = fmi2OK;
    s->stale = 0;
    char err[1024];
    model_state trial = *s;
    int ok = hb_commit(&trial, s->value, s->impact_enabled, 0, err, sizeof err);
    for (int k = HBS_preload; ok && k <= HBS_harmonic_force; k++)
        if (!hb_input_ok(&trial, k, s->value[k])) {   /* the inputs' range follows F0 */
            hb_input_error(&trial, k, s->value[k], err, sizeof err);
            ok = 0;
        }
    if (!ok) {
        s->ready = 0;
        snprintf(s->error, sizeof s->error, "initialisation failed: %s", err);
        return hb_fail(m, fmi2Error, "%s", s->error);
    }
    *s = trial;
    s->t = s->t_start;
    s->ready = 1;
    s->error[0] = '\0';
    return fmi2OK;
}

static fmi2Status n_terminate(fmi2Component c) {
    model *m = c;
    m->s.last_status = fmi2OK;
    m->s.terminated = 1;
    return fmi2OK;
}

static fmi2Status n_reset(fmi2Component c) {
    model *m = c;
    set_start_values(&m->s);
    return fmi2OK;
}

/* ------------------------------------------------------------------------------------------ */
/* fmi2DoStep                                                                                   */
/* ------------------------------------------------------------------------------------------ */
static const char *solver_failure(int64_t status) {
    switch (status) {
    case HBK_ST_EVENT_STORM:
        return "event storm: more events in one forcing period than max_events_per_period (e.g. a "
               "chattering contact or a force at the friction threshold)";
    case HBK_ST_STEP_TOO_SMALL:
        return "step size fell below the resolution of t; the problem is too stiff for these "
               "tolerances";
    case HBK_ST_STEP_STORM:
        return "step storm: more accepted steps in one forcing period than max_steps_per_period; the "
               "regime is too stiff for these tolerances";
    case HBK_ST_NONFINITE: return "state became non-finite";
    case HBK_ST_MAX_STEPS: return "more steps than max_steps in one call";
    case HBK_ST_BAD_INPUT:
        return "the kernel refused its input: a non-finite state or end time, or an end time before "
               "the current time";
    default: return "the solver stopped";
    }
}

/* the tolerance was set since the last commit: new solver options, the state carried over */
static int apply_tolerance(model *m) {
    model_state *s = &m->s;
    model_state trial = *s;
    char err[1024];
    if (!hb_commit(&trial, s->value, s->impact_enabled, 1, err, sizeof err)) {
        s->value[HBS_tolerance] = s->committed[HBS_tolerance];
        hb_fail(m, fmi2Error, "invalid tunable parameter: %s", err);
        return 0;
    }
    *s = trial;
    return 1;
}

/* the kernel's advance to tau_end; to_event: stop just after the first event later than the
 * step's start (one at the start was reported by the step that ended there) */
static int64_t advance(model_state *s, double tau_end, int to_event, int *stopped) {
    *stopped = 0;
    if (!to_event) return hb_advance(s->y, s->ist, s->fst, tau_end, s->p, s->opts);
    double tau0 = s->fst[HBK_F_T], log[HBK_N_LOG_COLS];
    int64_t status;
    do {
        s->ist[HBK_I_NLOG] = 0;
        status = hb_advance_to_event(s->y, s->ist, s->fst, tau_end, s->p, s->opts, log);
    } while (status == HBK_ST_LOG_FULL && !(s->fst[HBK_F_T] > tau0));
    /* the row is read (the event's time is the state's): no record is kept between steps, as
     * every FMU state must have (model_state.c checks it), so a state saved now can be restored */
    s->ist[HBK_I_NLOG] = 0;
    *stopped = status == HBK_ST_LOG_FULL;
    return *stopped ? HBK_ST_DONE : status;
}

/* the one warning of a change of the regime verdict, at the end of a step */
static void regime_check(model *m) {
    model_state *s = &m->s;
    int32_t regime = hb_regime_now(s);
    if (regime == s->regime_seen) return;
    char now[128], was[128], t[40];
    hb_regime_names(regime, now, sizeof now);
    hb_regime_names(s->regime_seen, was, sizeof was);
    hb_repr(s->t, t, sizeof t);
    s->regime_seen = regime;
    hb_model_log(m, fmi2Warning, "regime at t = %s s: %s (regime = %d; was %s)", t, now, (int)regime, was);
}

static fmi2Status do_step(model *m, fmi2Real t, fmi2Real h, int to_event, fmi2Real *reached) {
    model_state *s = &m->s;
    s->last_status = fmi2OK;
    if (s->terminated)
        return hb_fail(m, fmi2Error, "fmi2DoStep refused: the FMU was terminated (fmi2Terminate)");
    if (!s->ready) return hb_fail(m, fmi2Error, "fmi2DoStep refused: %s", s->error);
    if (s->dirty && !apply_tolerance(m)) return fmi2Error;
    char a[40], b[40];
    if (!(0.0 < h && h < INFINITY)) {
        hb_repr(h, a, sizeof a);
        return hb_fail(m, fmi2Error, "communication step size h = %s s is invalid: it must be > 0 and "
                    "finite; step refused, state unchanged", a);
    }
    if (h * s->committed[HBS_frequency] > HB_MAX_PERIODS_PER_STEP) {
        /* the solver's limits count per forcing period: beyond this many periods a step's work
         * has no useful bound (minutes), so it is refused at once */
        hb_repr(h, a, sizeof a);
        hb_repr(s->committed[HBS_frequency], b, sizeof b);
        return hb_fail(m, fmi2Error, "communication step size h = %s s spans %.6g forcing periods "
                    "(frequency = %s Hz), more than MAX_PERIODS_PER_STEP = %.0f (h <= %.6g s): the "
                    "solver's limits count per period, so such a step's work has no useful bound; take "
                    "shorter steps; step refused, state unchanged", a, h * s->committed[HBS_frequency], b,
                    HB_MAX_PERIODS_PER_STEP, HB_MAX_PERIODS_PER_STEP / s->committed[HBS_frequency]);
    }
    if (t != s->t) {
        double tol = fmax(TIME_ABS_TOL, TIME_ULPS * (nextafter(fabs(s->t), INFINITY) - fabs(s->t)));
        if (!(fabs(t - s->t) <= tol)) {
            hb_repr(t, a, sizeof a);
            hb_repr(s->t, b, sizeof b);
            return hb_fail(m, fmi2Error, "currentCommunicationPoint = %s s is not the current time of "
                        "the FMU, %s s (tolerance %g s); step refused, state unchanged", a, b, tol);
        }
    }
    double old_b = s->p[HBK_P_B], old_f = s->p[HBK_P_FEXT];
    double old_ap = s->applied_preload, old_af = s->applied_force;
    hb_apply_inputs(s);
    double y[4], fst[HBK_N_FSTATE];
    int64_t ist[HBK_N_ISTATE];
    memcpy(y, s->y, sizeof y);
    memcpy(ist, s->ist, sizeof ist);
    memcpy(fst, s->fst, sizeof fst);
    hb_kernel_raised();
    int stopped;
    int64_t status = advance(s, (t + h - s->t_start) * s->omega, to_event, &stopped);
    int raised = hb_kernel_raised();
    if (raised || status != HBK_ST_DONE) {
        double tau = s->fst[HBK_F_T];
        memcpy(s->y, y, sizeof y);
        memcpy(s->ist, ist, sizeof ist);
        memcpy(s->fst, fst, sizeof fst);
        s->p[HBK_P_B] = old_b;
        s->p[HBK_P_FEXT] = old_f;
        s->applied_preload = old_ap;
        s->applied_force = old_af;
        hb_repr(t, a, sizeof a);
        hb_repr(h, b, sizeof b);
        if (!raised && (status == HBK_ST_STEP_STORM || status == HBK_ST_EVENT_STORM ||
                        status == HBK_ST_STEP_TOO_SMALL)) {
            /* the kernel counts steps and events per forcing period at absolute times: no shorter
             * communication step gets past this time */
            char tf[40];
            hb_repr(s->t_start + tau / s->omega, tf, sizeof tf);
            return hb_fail(m, fmi2Error, "%s: the solver cannot get past t = %s s, with this step "
                        "from t = %s s or any shorter one (its limits count per forcing period of the "
                        "model); state restored to t = %s s; change the parameters or the tolerance",
                        solver_failure(status), tf, a, a);
        }
        return hb_fail(m, fmi2Discard, "solver failure in the step from t = %s s with h = %s s: %s at "
                    "tau = %.9g; state restored to t = %s s (retry with a shorter step)", a, b,
                    raised ? "a kernel raised an exception" : solver_failure(status), tau, a);
    }
    s->t = stopped ? fmin(s->t_start + s->fst[HBK_F_T] / s->omega, t + h) : t + h;
    *reached = s->t;
    regime_check(m);
    return fmi2OK;
}

static fmi2Status n_do_step(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    fmi2Real reached;
    return do_step(c, t, h, 0, &reached);
}

static fmi2Status n_step_to_event(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Real *reached) {
    return do_step(c, t, h, 1, reached);
}
/* ------------------------------------------------------------------------------------------ */
/* The model's functions for the backend table (model.h)                                        */
/* ------------------------------------------------------------------------------------------ */
void hb_model_fill(hb_wrapper *w) {
    w->FreeInstance = n_free_instance;
    w->SetupExperiment = n_setup_experiment;
    w->EnterInitializationMode = n_enter_init;
    w->ExitInitializationMode = n_exit_init;
    w->Terminate = n_terminate;
    w->Reset = n_reset;
    hb_values_fill(w);
    hb_state_fill(w);
    w->DoStep = n_do_step;
    w->StepToEvent = n_step_to_event;
    hb_me_fill(w);
    hb_derivatives_fill(w);
    w->Instantiate = n_instantiate;
}

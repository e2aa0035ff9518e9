/* The native model backend of the front: HammerBitRock's co-simulation slave in C around the
 * library's compiled kernels (the native flavour of the FMU; no Python in the process).
 *
 * front.c keeps the FMI state machine, the checks of value references and settability, the
 * resource URI, the logging rules and the FMU-state header; it calls this backend through the
 * same table (hb_W) it fills with pythonfmu's functions in the Python flavour.  This file does
 * what the Python slave (hammerbit.model.slave) does per call:
 *   - parameters and inputs as set, validated against the ranges of hammerbit.model.validation
 *     (written into hb_native.h by the build), at fmi2ExitInitializationMode as a whole;
 *   - SI -> the paper's groups -> the kernel's parameter vector, exactly as RigParameters.to_groups
 *     and Groups.to_kernel compute it (same operations in the same order);
 *   - fmi2DoStep: the inputs held over the step, one call of the compiled solver driver to the
 *     step's end, the state restored and fmi2Discard if it fails;
 *   - values and outputs (model_values.c): outputs from the state through the kernels' own
 *     force formulas (hb_forces);
 *   - FMU state: the whole model state as plain data (model_state.c).
 * Every call records the FMI status it returns in last_status and logs every non-OK status with
 * a message naming the variable, its value and the allowed range. */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front.h"
#include "kernel_api.h"
#include "model_native.h"

#define TWO_PI 6.283185307179586   /* 2.0 * math.pi, as Python rounds it */
/* Communication times are compared with an absolute tolerance: 1 ns, or a few units in the last
 * place where t is so large that its doubles lie farther apart (a master computing t0 + n h is
 * within it, and a step never skips a stretch of time) */
#define TIME_ABS_TOL 1e-9
#define TIME_ULPS 4.0

/* ------------------------------------------------------------------------------------------ */
/* Messages                                                                                    */
/* ------------------------------------------------------------------------------------------ */
void hb_mlog(model *m, fmi2Status st, const char *fmt, ...) {
    if (!m->cb.logger) return;
    char msg[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    const char *cat = st == fmi2OK ? "logAll"
                      : st == fmi2Warning ? "logStatusWarning"
                      : st == fmi2Discard ? "logStatusDiscard" : "logStatusError";
    /* the message is the format: the front (inner_logger) escapes its '%' for the host */
    m->cb.logger(m->cb.componentEnvironment, m->name, st, cat, msg);
}

fmi2Status hb_fail(model *m, fmi2Status st, const char *fmt, ...) {
    char msg[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if ((int32_t)st > m->s.last_status) m->s.last_status = (int32_t)st;
    hb_mlog(m, st, "%s", msg);
    return st;
}

/* ------------------------------------------------------------------------------------------ */
/* Ranges                                                                                      */
/* ------------------------------------------------------------------------------------------ */
int hb_contains(const hb_range *r, double v) {
    if (isnan(v)) return 0;
    if (isinf(v)) return r->allow_inf && v > 0;
    if (v < r->lo || v > r->hi) return 0;
    return !((r->lo_open && v == r->lo) || (r->hi_open && v == r->hi));
}

/* "parameter 'name' = value is out of range: allowed ..." (validation.check_range); 0 if not */
int hb_range_error(const char *name, double v, const hb_range *r, char *out, size_t n) {
    if (hb_contains(r, v)) return 0;
    char rv[40];
    hb_repr(v, rv, sizeof rv);
    int non_finite = isnan(v) || (isinf(v) && !r->allow_inf);
    snprintf(out, n, "parameter '%s' = %s is out of range: allowed %s%s", name, rv,
             non_finite ? "a finite number in " : "", r->text);
    return 1;
}

/* |input| <= limit F0 for the parameters in use (F0 = mu_static normal_force) */
static double input_limit(const model_state *s, int k) {
    return (k == HBS_preload ? HB_INPUT_LIMIT_F0_preload : HB_INPUT_LIMIT_F0_harmonic_force) * s->F0;
}

int hb_input_ok(const model_state *s, int k, double v) {
    double lim = input_limit(s, k);
    return -lim <= v && v <= lim;   /* false for NaN */
}

/* "... out of range: allowed [-x, x] N (1000 F0, ...)" for an input value */
void hb_input_error(const model_state *s, int k, double v, char *out, size_t n) {
    char rv[40], lim[40], f0[40], have[40];
    hb_repr(v, rv, sizeof rv);
    snprintf(lim, sizeof lim, "%g", input_limit(s, k));
    hb_repr(s->F0, f0, sizeof f0);
    hb_repr(s->value[k], have, sizeof have);
    snprintf(out, n, "input '%s' = %s is out of range: allowed [-%s, %s] N (%g F0, F0 = mu_static "
             "normal_force = %s N, the static friction threshold); refused, %s N stays",
             HB_STORED[k].name, rv, lim, lim, input_limit(s, k) / s->F0, f0, have);
}

/* ------------------------------------------------------------------------------------------ */
/* Parameters -> kernel arrays (RigParameters -> Groups -> Stepper, as the slave's _commit)     */
/* ------------------------------------------------------------------------------------------ */
/* Validate the values v[] (and impact) and build the solver state into s; 1, or 0 with the
 * message in err (nothing of s changed then). keep: carry y, ist, fst and p of s over. */
int hb_commit(model_state *s, const double *v, int impact, int keep, char *err, size_t n) {
    static const int other[] = {HBS_gap, HBS_initial_hammer_position, HBS_initial_bit_position,
                                HBS_tolerance};
    for (size_t i = 0; i < sizeof other / sizeof *other; i++)
        if (hb_range_error(HB_STORED[other[i]].name, v[other[i]], &HB_STORED[other[i]].range, err, n))
            return 0;
    double gap = impact ? v[HBS_gap] : INFINITY;
    for (size_t i = 0; i < HB_NRIG; i++) {
        int k = HB_RIG_ORDER[i];
        double x = k == HBS_gap ? gap : k < 0 ? 0.0 : v[k];   /* k < 0: preload (an input) */
        const hb_range *r = k < 0 ? &HB_RANGE_PRELOAD : &HB_STORED[k].range;
        if (hb_range_error(k < 0 ? "preload" : HB_STORED[k].name, x, r, err, n)) return 0;
    }
    if (v[HBS_mu_kinetic] > v[HBS_mu_static]) {
        char rv[40], ms[40];
        hb_repr(v[HBS_mu_kinetic], rv, sizeof rv);
        snprintf(ms, sizeof ms, "%g", v[HBS_mu_static]);
        snprintf(err, n, "parameter 'mu_kinetic' = %s is out of range: allowed (0, mu_static = %s]: "
                 "kinetic friction above static", rv, ms);
        return 0;
    }
    /* Scales and RigParameters.to_groups */
    double m1 = v[HBS_hammer_mass], K = v[HBS_stiffness];
    double F0 = v[HBS_mu_static] * v[HBS_normal_force];
    double Om = sqrt(K / m1), x0 = F0 / K;
    double g[HB_NGROUPS];
    g[0] = v[HBS_bit_mass] / m1;                                         /* rho */
    g[1] = v[HBS_damping] / (2.0 * sqrt(K * m1));                        /* xi */
    g[2] = TWO_PI * v[HBS_frequency] / Om;                               /* eta */
    g[3] = v[HBS_amplitude] / F0;                                        /* a */
    g[4] = 0.0 / F0;                                                     /* b: an input */
    g[5] = gap / x0;                                                     /* r */
    g[6] = v[HBS_mu_kinetic] / v[HBS_mu_static];                         /* mu */
    g[7] = v[HBS_friction_decay] * x0 * Om;                              /* gamma_hat */
    g[8] = v[HBS_contact_stiffness] * pow(x0, v[HBS_contact_exponent]) / F0;   /* kc */
    g[9] = v[HBS_contact_exponent];                                      /* n */
    g[10] = v[HBS_contact_damping] * x0 * Om;                            /* lam_hat */
    g[11] = v[HBS_phase];                                                /* phi */
    for (int i = 0; i < HB_NGROUPS; i++)
        if (hb_range_error(HB_GROUPS[i].name, g[i], &HB_GROUPS[i].range, err, n)) return 0;
    if (s->t_start != 0.0) {
        /* absolute-time forcing on the kernel's clock tau = Omega (t - t_start) */
        double omega_f = TWO_PI * v[HBS_frequency];
        g[11] = fmod(v[HBS_phase] + omega_f * s->t_start, TWO_PI);
        if (hb_range_error("phi", g[11], &HB_GROUPS[11].range, err, n)) return 0;
    }
    double y0[4] = {v[HBS_initial_hammer_position] / x0, 0.0, v[HBS_initial_bit_position] / x0, 0.0};
    if (hb_range_error("y0[0] (hammer position x1)", y0[0], &HB_RANGE_STATE_POSITION, err, n) ||
        hb_range_error("y0[2] (bit position x3)", y0[2], &HB_RANGE_STATE_POSITION, err, n))
        return 0;
    double tol = v[HBS_tolerance], atol = 1e-2 * tol;
    if (hb_range_error("rtol", tol, &HB_RANGE_RTOL, err, n) ||
        hb_range_error("atol", atol, &HB_RANGE_ATOL, err, n))
        return 0;
    /* Groups.to_kernel and the Stepper's arrays */
    double *p = s->p;
    if (!keep) {
        p[HBK_P_RHO] = g[0];
        p[HBK_P_XI] = g[1];
        p[HBK_P_ETA] = g[2];
        p[HBK_P_A] = g[3];
        p[HBK_P_B] = g[4];
        p[HBK_P_R] = g[5];
        p[HBK_P_MU] = g[6];
        p[HBK_P_GAMMA] = g[7];
        p[HBK_P_KC] = g[8];
        p[HBK_P_N] = g[9];
        p[HBK_P_LAM] = g[10];
        p[HBK_P_PHI] = g[11];
        p[HBK_P_FEXT] = 0.0;
        p[HBK_P_CONTACT] = (isfinite(g[5]) && g[8] > 0.0) ? 1.0 : 0.0;
        memset(s->y, 0, sizeof s->y);
        memset(s->ist, 0, sizeof s->ist);
        memset(s->fst, 0, sizeof s->fst);
        memcpy(s->y, y0, sizeof y0);
    }
    double period = TWO_PI / g[2];
    if (!keep) s->fst[HBK_F_H] = fmin(0.01 * period, HB_SOLVER_MAX_STEP);
    double *o = s->opts;
    memset(o, 0, sizeof s->opts);
    o[HBK_O_RTOL] = tol;
    o[HBK_O_ATOL] = atol;
    o[HBK_O_HMAX] = HB_SOLVER_MAX_STEP;
    o[HBK_O_HFIXED] = 0.0;
    o[HBK_O_EVCAP] = HB_SOLVER_MAX_EVENTS_PER_PERIOD;
    o[HBK_O_BISECT] = HB_SOLVER_BISECTION_TOL;
    o[HBK_O_MAXSTEPS] = HB_SOLVER_MAX_STEPS;
    o[HBK_O_POIN_T0] = 0.0;
    o[HBK_O_POIN_DT] = period;
    o[HBK_O_GRAZE] = HB_SOLVER_GRAZE_TOL;
    o[HBK_O_STEPCAP] = HB_SOLVER_MAX_STEPS_PER_PERIOD;
    if (!keep) hb_init_modes(s->y, s->ist, s->p);
    s->x0 = x0;
    s->v0 = x0 * Om;
    s->F0 = F0;
    s->omega = Om;
    s->x3_start = y0[2];
    memcpy(s->committed, v, sizeof s->committed);
    s->committed_impact = impact;
    s->dirty = 0;
    s->has_commit = 1;
    s->applied_preload = s->applied_force = NAN;
    return 1;
}

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
    model *m = calloc(1, sizeof *m);
    if (!m || !(m->name = strdup(name))) {
        free(m);
        return NULL;
    }
    m->cb = *cb;
    set_start_values(&m->s);
    return m;
}

static void n_free_instance(fmi2Component c) {
    model *m = c;
    if (!m) return;
    free(m->name);
    free(m);
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

void hb_apply_inputs(model_state *s) {
    double preload = s->value[HBS_preload], fh = s->value[HBS_harmonic_force];
    if (preload != s->applied_preload || fh != s->applied_force) {
        s->p[HBK_P_B] = preload / s->F0;   /* exactly as RigParameters.to_groups() */
        s->p[HBK_P_FEXT] = fh / s->F0;
        s->applied_preload = preload;
        s->applied_force = fh;
    }
}

static fmi2Status n_do_step(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    model *m = c;
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
    int64_t status = hb_advance(s->y, s->ist, s->fst, (t + h - s->t_start) * s->omega, s->p, s->opts);
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
    s->t = t + h;
    return fmi2OK;
}

/* ------------------------------------------------------------------------------------------ */
/* The backend table for front.c                                                                */
/* ------------------------------------------------------------------------------------------ */
hb_wrapper hb_W;

int hb_backend_load(char *err, size_t n) {
    (void)err, (void)n;
    if (hb_W.Instantiate) return 1;
    hb_W.FreeInstance = n_free_instance;
    hb_W.SetupExperiment = n_setup_experiment;
    hb_W.EnterInitializationMode = n_enter_init;
    hb_W.ExitInitializationMode = n_exit_init;
    hb_W.Terminate = n_terminate;
    hb_W.Reset = n_reset;
    hb_values_fill(&hb_W);
    hb_state_fill(&hb_W);
    hb_W.DoStep = n_do_step;
    hb_me_fill(&hb_W);
    hb_W.Instantiate = n_instantiate;
    return 1;
}

/* The native model backend of the Drillstring FMU: the string's co-simulation slave in C around
 * the library's compiled step kernels (string_api.h; no Python in the process).
 *
 * front.c keeps the FMI state machine, the checks of value references and settability, the
 * resource URI, the logging rules and the FMU-state header; this file does what the Python slave
 * (hammerbit.model.string_slave) does per call, with the same messages:
 *   - parameters checked at fmi2ExitInitializationMode as a whole;
 *   - fmi2DoStep: the inputs checked, one call of the compiled exchange_step and held_force;
 *   - outputs from the state (the output rows of the string side);
 *   - FMU states: the whole model state as plain data, the string's state vector included.
 * The exact step's matrices of each form and communication step size the FMU was built for are
 * read from resources/string_native.bin (written by hammerbit.fmu.native_string), with each
 * form's generator: a step of another length gets its exponentials from the compiled kernels
 * (find_block).  The eigendecomposition is done at build time, so the parameters the matrices
 * depend on (damping_ratio, and the auto-driller's gains) keep their build values here. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"
#include "model_string.h"
#include "string_api.h"

static size_t state_size(const table *t) { return sizeof(sstate) + 2 * (size_t)t->nmax * sizeof(double); }

static void set_start_values(model *m) {
    sstate *s = m->s;
    memset(s, 0, m->size);
    s->magic = STATE_MAGIC;
    s->size = (uint32_t)m->size;
    s->damping_ratio = HS_START_damping_ratio;
    s->wob = HS_START_wob;
    s->at_rest = HS_START_hammer_position_at_rest;
    s->feed_velocity = HS_START_feed_velocity;
    s->kp = HS_START_proportional_gain;
    s->kig = HS_START_integral_gain;
    s->extrapolation = HS_START_extrapolation;
    s->top_condition = HS_START_top_condition;
    s->x_in = s->at_rest;
    s->interface_force = s->held = HS_START_wob;
    s->hook_load = HS_START_hook_load;
    s->top_position = s->top_velocity = 0.0;
    snprintf(s->error, sizeof s->error, "not initialised (fmi2ExitInitializationMode)");
}

/* ------------------------------------------------------------------------------------------ */
/* Parameters                                                                                  */
/* ------------------------------------------------------------------------------------------ */
static int in_range(double v, double lo, double hi, int hi_open) {
    return isfinite(v) && lo <= v && (hi_open ? v < hi : v <= hi);
}

/* the first bad parameter as the Python slave words it (then the native flavour's own refusal
 * of a value the build's matrices do not cover); 1 if all are fine */
static int check_parameters(const sstate *s, char *out, size_t n) {
    char r[40], r2[40];
    const struct { const char *name; double v, lo, hi; int open; const char *text; } checks[] = {
        {"damping_ratio", s->damping_ratio, 0.0, 1.0, 1, "[0, 1)"},
        {"wob", s->wob, 0.0, HS_BUOYED_WEIGHT * (1.0 + 1e-12), 0, HS_WOB_RANGE_TEXT},
        {"hammer_position_at_rest", s->at_rest, -HS_INPUT_LIMIT, HS_INPUT_LIMIT, 0, HS_POSITION_RANGE_TEXT},
    };
    for (size_t i = 0; i < sizeof checks / sizeof checks[0]; i++)
        if (!in_range(checks[i].v, checks[i].lo, checks[i].hi, checks[i].open)) {
            hb_repr(checks[i].v, r, sizeof r);
            snprintf(out, n, "parameter '%s' = %s is out of range: allowed %s", checks[i].name, r,
                     checks[i].text);
            return 0;
        }
    if (s->extrapolation < 0 || s->extrapolation > 2) {
        snprintf(out, n, "parameter 'extrapolation' = %d is out of range: allowed 0, 1, 2", s->extrapolation);
        return 0;
    }
    if (s->top_condition < 0 || s->top_condition >= HB_N_TOP_CONDITIONS) {
        snprintf(out, n, "parameter 'top_condition' = %d is out of range: allowed " HB_TOP_CONDITIONS_TEXT,
                 s->top_condition);
        return 0;
    }
    hb_repr(s->feed_velocity, r, sizeof r);
    if (!(isfinite(s->feed_velocity) && fabs(s->feed_velocity) <= HS_MAX_FEED)) {
        snprintf(out, n, "parameter 'feed_velocity' = %s is out of range: allowed %s", r, HS_FEED_RANGE_TEXT);
        return 0;
    }
    if (s->feed_velocity != 0.0 && !HB_TOP_TAKES_FEED[s->top_condition]) {
        snprintf(out, n, "parameter 'feed_velocity' = %s: only top_condition = " HB_TOP_FEED_TEXT " takes "
                 "a feed velocity; allowed 0 with top_condition = %d", r, s->top_condition);
        return 0;
    }
    const char *gn[2] = {"proportional_gain", "integral_gain"};
    double gv[2] = {s->kp, s->kig}, gb[2] = {HS_BUILD_proportional_gain, HS_BUILD_integral_gain};
    for (int i = 0; i < 2; i++)
        if (!(isfinite(gv[i]) && 0.0 <= gv[i] && gv[i] <= HS_MAX_GAIN)) {
            hb_repr(gv[i], r, sizeof r);
            snprintf(out, n, "parameter '%s' = %s is out of range: allowed [0, %g]", gn[i], r, HS_MAX_GAIN);
            return 0;
        }
    if (HB_TOP_FORM[s->top_condition] == HB_FORM_AUTO && !HS_HAS_AUTO) {
        snprintf(out, n, "parameter 'top_condition' = %d: this string has no auto-driller (%s); allowed "
                 HB_TOP_NOT_AUTO_TEXT, s->top_condition, HS_AUTO_REFUSED);
        return 0;
    }
    /* the native flavour: the matrices are those of the build's values */
    if (s->damping_ratio != HS_BUILD_damping_ratio) {
        hb_repr(s->damping_ratio, r, sizeof r);
        hb_repr(HS_BUILD_damping_ratio, r2, sizeof r2);
        snprintf(out, n, "parameter 'damping_ratio' = %s: the native Drillstring FMU carries the string's "
                 "matrices at its build value only; allowed %s (rebuild the FMU with that damping ratio "
                 "in the string's file, or use the Python flavour, which recomputes them)", r, r2);
        return 0;
    }
    for (int i = 0; HB_TOP_FORM[s->top_condition] == HB_FORM_AUTO && i < 2; i++)
        if (gv[i] != gb[i]) {
            hb_repr(gv[i], r, sizeof r);
            hb_repr(gb[i], r2, sizeof r2);
            snprintf(out, n, "parameter '%s' = %s: the native Drillstring FMU carries the auto-driller's "
                     "matrices at its build gains only; allowed %s (rebuild the FMU with --top "
                     "auto-driller and these gains, or use the Python flavour)", gn[i], r, r2);
            return 0;
        }
    return 1;
}

/* ------------------------------------------------------------------------------------------ */
/* Outputs                                                                                     */
/* ------------------------------------------------------------------------------------------ */
/* The exponentials of a step h: a built step's within HS_BUILT_STEP_MATCH (relative), else those
 * computed for h by the compiled kernels (hammerbit.model.string_exponentials), kept in a cache of
 * HS_STEP_CACHE step lengths; NULL (with the reason in err) only when memory runs out or a kernel
 * raised. */
static const block *find_block(model *m, int64_t form, double h, char *err, size_t en) {
    const table *t = &m->tab;
    for (int64_t i = 0; i < t->nblocks; i++)
        if (t->b[i].form == form && fabs(h - t->b[i].h) <= HS_BUILT_STEP_MATCH * t->b[i].h) return &t->b[i];
    for (int i = 0; i < HS_STEP_CACHE; i++)
        if (m->cache[i].b.n && m->cache[i].b.form == form && m->cache[i].b.h == h) return &m->cache[i].b;
    const block *built = hs_any_block(t, form);
    const generator *g = &t->gen[form];
    if (!built || g->n <= 0 || (built->modal && g->m != built->n) || (!built->modal && g->n != built->n)) {
        snprintf(err, en, "the FMU's tables have no generator for this form");
        return NULL;
    }
    cached_step *c = &m->cache[m->next_slot];
    int64_t n = built->n, N = n + N_COEFFS + 1;
    size_t need = built->modal ? (size_t)(2 * n + 2 * n * N_COEFFS + 2 * n) : (size_t)((n + 1) * (n + N_COEFFS));
    if (need > c->cap) {
        double *mem = realloc(c->mem, need * sizeof(double));
        if (!mem) { snprintf(err, en, "out of memory"); return NULL; }
        c->mem = mem, c->cap = need;
    }
    if (!built->modal && !m->work) {
        m->work = malloc((size_t)HS_PADE_WORK * (size_t)(N * N) * sizeof(double));
        if (!m->work) { snprintf(err, en, "out of memory"); return NULL; }
    }
    block *b = &c->b;
    *b = *built;
    b->n = 0;                            /* empty until it is filled */
    double k2[2] = {HS_INTERFACE_STIFFNESS, HS_INTERFACE_DAMPING};
    hb_kernel_raised();
    if (built->modal) {
        b->d = (double _Complex *)c->mem;
        b->G = b->d + n;
        b->irow = b->G + n * N_COEFFS;
        hs_modal_exponentials(n, h, k2, g->lam, g->B, built->frow_c, b->d, b->G, b->irow, b->icol);
    } else {
        b->P = c->mem;
        hs_dense_exponential(n, h, k2, g->A1, g->E, g->frow, b->P, m->work);
    }
    if (hb_kernel_raised()) { snprintf(err, en, "a kernel raised an exception"); return NULL; }
    b->h = h;
    b->n = n;
    m->next_slot = (m->next_slot + 1) % HS_STEP_CACHE;
    return b;
}

static void set_outputs(model *m) {
    sstate *s = m->s;
    s->interface_force = s->out[0];
    s->held = s->F_held;
    double V = s->feed[0], t0 = s->feed[1];
    if (!s->started) {           /* the static equilibrium (a feed's block at its start) */
        s->hook_load = s->hook_eq;
        s->top_position = 0.0;
        s->top_velocity = V;
        return;
    }
    const block *b = hs_any_block(&m->tab, s->form);
    double o[N_ROWS] = {0};
    for (int r = ROW_HOOK; r < N_ROWS; r++) {
        double acc = 0.0;
        if (s->modal) {
            const double _Complex *eta = (const double _Complex *)s->v;
            double _Complex z = 0.0;
            for (int64_t i = 0; i < s->n; i++) z += b->rows_c[r * s->n + i] * eta[i];
            acc = creal(z);
        } else {
            for (int64_t i = 0; i < s->n; i++) acc += b->rows_r[r * s->n + i] * s->v[i];
        }
        o[r] = acc;
    }
    s->hook_load = o[ROW_HOOK] + s->hook_eq;
    s->top_position = o[ROW_TOP_U] + V * (s->t - t0);
    s->top_velocity = o[ROW_TOP_V] + V;
}

/* ------------------------------------------------------------------------------------------ */
/* Life cycle                                                                                  */
/* ------------------------------------------------------------------------------------------ */
static fmi2Component s_instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String uri,
                                   const fmi2CallbackFunctions *cb, fmi2Boolean visible,
                                   fmi2Boolean logging) {
    (void)type, (void)guid, (void)visible, (void)logging;
    model *m = hb_model_new(sizeof *m, name, cb);
    if (!m) return NULL;
    char err[4400];
    const char *dir = strncmp(uri, "file://", 7) == 0 ? uri + 7 : uri;   /* the front's plain path */
    if (!hs_load_table(dir, &m->tab, err, sizeof err)) {
        hs_log(m, fmi2Error, "fmi2Instantiate: the string's matrices: %s", err);
        hb_model_free(m);
        return NULL;
    }
    m->size = state_size(&m->tab);
    m->s = calloc(1, m->size);
    m->kept = malloc(m->size);
    m->buf = calloc((size_t)m->tab.nmax + N_COEFFS, sizeof(double));
    m->tmp = calloc((size_t)m->tab.nmax + 1, sizeof(double));
    if (!m->s || !m->kept || !m->buf || !m->tmp) {
        hs_log(m, fmi2Error, "fmi2Instantiate: out of memory");
        free(m->s), free(m->kept), free(m->buf), free(m->tmp), free(m->tab.b), free(m->tab.mem);
        hb_model_free(m);
        return NULL;
    }
    set_start_values(m);
    return m;
}

static void s_free_instance(fmi2Component c) {
    model *m = c;
    if (!m) return;
    for (int i = 0; i < HS_STEP_CACHE; i++) free(m->cache[i].mem);
    free(m->work);
    free(m->s), free(m->kept), free(m->buf), free(m->tmp), free(m->tab.b), free(m->tab.mem);
    hb_model_free(m);
}

static fmi2Status s_setup_experiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol,
                                     fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined, (void)tol, (void)stop_defined, (void)stop;
    sstate *s = ((model *)c)->s;
    if (isfinite(start)) s->t_start = s->t = start;
    return fmi2OK;
}

static fmi2Status s_exit_init(fmi2Component c) {
    model *m = c;
    sstate *s = m->s;
    char bad[1024];
    if (!check_parameters(s, bad, sizeof bad)) {
        s->ready = 0;
        snprintf(s->error, sizeof s->error, "initialisation failed: %s", bad);
        return FAIL(m, "%s", s->error);
    }
    s->form = HB_TOP_FORM[s->top_condition];
    const block *b = hs_any_block(&m->tab, s->form);
    s->n = b->n;
    s->modal = b->modal;
    s->W = s->wob;
    s->hook_eq = HS_BUOYED_WEIGHT - s->W;
    double feed = HB_TOP_TAKES_FEED[s->top_condition] ? s->feed_velocity : 0.0;
    s->feed[0] = feed;
    s->feed[1] = s->t_start;
    s->k3[0] = HS_INTERFACE_STIFFNESS;
    s->k3[1] = HS_INTERFACE_DAMPING;
    s->k3[2] = s->W;
    s->order = s->extrapolation;
    s->started = 0;
    memset(s->th, 0, sizeof s->th), memset(s->wh, 0, sizeof s->wh), memset(s->out, 0, sizeof s->out);
    memset(s->c, 0, sizeof s->c);
    memset(s->v, 0, 2 * (size_t)m->tab.nmax * sizeof(double));
    /* the string moves with a feed's block from the start, the hammer rests: the interface dashpot */
    double F0 = s->W + HS_INTERFACE_DAMPING * feed;
    for (int i = 0; i < 3; i++) s->Fh[i] = F0;
    s->out[0] = F0;
    s->F_held = F0;
    s->t = s->t_start;
    s->ready = 1;
    s->error[0] = '\0';
    set_outputs(m);
    return fmi2OK;
}

HB_MODEL_TERMINATE_RESET(((model *)c)->s)

/* ------------------------------------------------------------------------------------------ */
/* fmi2DoStep                                                                                   */
/* ------------------------------------------------------------------------------------------ */
static fmi2Status s_do_step(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)no_prior;
    model *m = c;
    sstate *s = m->s;
    char a[40];
    if (hb_model_step_check(m, s->ready ? NULL : s->error, s->t, t, h, HS_TIME_TOLERANCE) != fmi2OK)
        return fmi2Error;
    char why[256];
    const block *b = find_block(m, s->form, h, why, sizeof why);
    if (!b) {
        hb_repr(h, a, sizeof a);
        return FAIL(m, "fmi2DoStep failed: the exponentials of the step h = %s s: %s; step refused, state "
                    "unchanged", a, why);
    }
    /* kept to put back if the step fails or ends in a state fmi2SetFMUstate would refuse */
    sstate *kept = m->kept;
    memcpy(kept, s, m->size);
    double x = 0.0, v = 0.0;      /* the first step: the hammer at rest in the static equilibrium */
    if (s->started) {
        const char *names[2] = {"hammer_position", "hammer_velocity"}, *units[2] = {"m", "m/s"};
        double vals[2] = {s->x_in, s->v_in};
        for (int i = 0; i < 2; i++)
            if (!(isfinite(vals[i]) && fabs(vals[i]) <= HS_INPUT_LIMIT)) {
                hb_repr(vals[i], a, sizeof a);
                return FAIL(m, "input '%s' = %s is out of range: allowed [-%g, %g] %s; step refused, "
                            "state unchanged", names[i], a, HS_INPUT_LIMIT, HS_INPUT_LIMIT, units[i]);
            }
        x = s->x_in - s->at_rest;
        v = s->v_in;
    } else {
        s->th[0] = s->t_start, s->th[1] = s->t_start - h, s->th[2] = s->t_start - 2 * h;
        for (int i = 0; i < 3; i++) s->wh[2 * i] = x, s->wh[2 * i + 1] = v;
        s->started = 1;
    }
    s->wh[0] = x, s->wh[1] = v;
    /* input derivatives: the hammer's motion over the step is their Taylor polynomial */
    int64_t given = s->der_given;
    if (given) memcpy(s->c + 2, s->der_in, sizeof s->der_in);
    double *xi = s->modal ? m->buf : s->v;
    double _Complex *eta = s->modal ? (double _Complex *)s->v : NULL;
    hb_kernel_raised();
    s->F_held = hs_exchange(s->order, given, h, s->modal, s->n, b->P ? b->P : m->tmp, xi, m->buf, m->tmp,
                            b->frow_r ? b->frow_r : m->tmp, b->d, b->G, b->irow, (double *)b->icol, eta,
                            b->frow_c, s->k3, s->th, s->wh, s->Fh, s->out, s->F_held, s->c, s->feed);
    if (hb_kernel_raised()) return hb_model_step_put_back(m, s, kept, m->size, t, t + h, "a kernel raised an exception");
    s->der_given = 0;             /* input derivatives hold for one step */
    memset(s->der_in, 0, sizeof s->der_in);
    s->t = t + h;
    set_outputs(m);
    const char *refused = hs_state_invalid(m, s);
    if (refused) {
        char why[300];
        snprintf(why, sizeof why, "the state it ends in would leave the FMU's range (%s)", refused);
        return hb_model_step_put_back(m, s, kept, m->size, t, t + h, why);
    }
    return fmi2OK;
}
/* ------------------------------------------------------------------------------------------ */
/* The model's functions for the backend table (model.h)                                        */
/* ------------------------------------------------------------------------------------------ */
void hb_model_fill(hb_wrapper *w) {
    hb_model_fill_life_cycle(w, s_free_instance, s_setup_experiment, s_exit_init, s_terminate, s_reset);
    hs_access_fill(w);
    w->DoStep = s_do_step;
    w->Instantiate = s_instantiate;
}

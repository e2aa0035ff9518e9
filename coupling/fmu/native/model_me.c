/* Model Exchange of the native model backend: continuous states, derivatives, event indicators
 * and the mode switches, all from the library's compiled kernels.
 *
 * Continuous states (SI): x = [hammer position, hammer velocity, bit position, bit velocity];
 * the kernels work in the nondimensional y = [x1/x0, x2/v0, x3/x0, x4/v0] and tau = Omega
 * (t - t_start), so dx/dt = scale * Omega * dy/dtau of the current hybrid mode (hb_rhs).
 * Event indicators: one per event kind of the kernels (stick -> slip, slip -> stick, impact,
 * separation, clamp, unclamp, bounce, bounce end; the kernels' watch_value, signed so that the
 * event happens when it becomes > 0), -1 for a kind the current modes do not watch.
 * fmi2NewDiscreteStates applies the reset map (hb_apply_event) of one crossed indicator per
 * call and asks for another iteration until none is crossed. */
#include <math.h>
#include <string.h>

#include "kernel_api.h"
#include "model_native.h"

/* event iterations of one event instant before it counts as a storm (each applies one reset) */
#define MAX_EVENT_ITERATIONS (4 * HBK_N_EVENT_KINDS)
#define NX 4

static fmi2Status check_n(model *m, const char *fn, size_t n, size_t want, const void *ptr) {
    if (!ptr) return hb_fail(m, fmi2Error, "%s: the array is NULL", fn);
    if (n != want)
        return hb_fail(m, fmi2Error, "%s: %zu values given, the model has %zu", fn, n, want);
    return fmi2OK;
}

static void scales(const model_state *s, double sc[NX]) {
    sc[0] = s->x0;
    sc[1] = s->v0;
    sc[2] = s->x0;
    sc[3] = s->v0;
}

static fmi2Status me_enter_event(fmi2Component c) {
    model *m = c;
    m->s.last_status = fmi2OK;
    m->event_iterations = 0;
    hb_apply_inputs(&m->s);
    int64_t kinds[HBK_WATCH_SLOTS];
    int64_t n = hb_watched(m->s.ist, m->s.p, kinds);
    m->armed = m->fired = 0;
    for (int64_t i = 0; i < n; i++) m->armed |= 1u << kinds[i];
    return fmi2OK;
}

static fmi2Status me_enter_cont(fmi2Component c) {
    ((model *)c)->s.last_status = fmi2OK;
    return fmi2OK;
}

static fmi2Status me_new_discrete_states(fmi2Component c, fmi2EventInfo *info) {
    model *m = c;
    model_state *s = &m->s;
    s->last_status = fmi2OK;
    if (!info) return hb_fail(m, fmi2Error, "fmi2NewDiscreteStates: fmi2eventInfo is NULL");
    memset(info, 0, sizeof *info);
    hb_apply_inputs(s);
    int64_t kinds[HBK_WATCH_SLOTS];
    int64_t n = hb_watched(s->ist, s->p, kinds);
    int applied = 0;
    for (int64_t i = 0; i < n && !applied; i++) {
        /* crossed: > 0; the host's root finder may also stop exactly on 0 of an indicator that
         * was armed before this event (once; an indicator a reset just armed starts at 0) */
        unsigned bit = 1u << kinds[i];
        double w = hb_watch_value(kinds[i], s->y, s->p, s->ist[HBK_I_CONTACT]);
        if (w > 0.0 || (w == 0.0 && (m->armed & bit) && !(m->fired & bit))) {
            hb_apply_event(kinds[i], s->y, s->ist, s->fst, s->p);
            m->fired |= bit;
            applied = 1;
        }
    }
    if (hb_kernel_raised())
        return hb_fail(m, fmi2Error, "fmi2NewDiscreteStates: a kernel raised an exception at t = %.17g s",
                       s->t);
    if (applied && ++m->event_iterations > MAX_EVENT_ITERATIONS)
        return hb_fail(m, fmi2Error, "fmi2NewDiscreteStates: more than %d mode switches at t = %.17g s "
                       "(an event storm: e.g. a force at the friction threshold)",
                       MAX_EVENT_ITERATIONS, s->t);
    info->newDiscreteStatesNeeded = applied ? fmi2True : fmi2False;
    info->valuesOfContinuousStatesChanged = applied ? fmi2True : fmi2False;
    return fmi2OK;
}

static fmi2Status me_set_time(fmi2Component c, fmi2Real t) {
    model *m = c;
    if (!isfinite(t)) return hb_fail(m, fmi2Error, "fmi2SetTime: time = %g is not finite", t);
    m->s.t = t;
    /* the kernel's clock follows the host's, so that a state saved now is consistent (tau = omega (t - t_start)) */
    m->s.fst[HBK_F_T] = (t - m->s.t_start) * m->s.omega;
    return fmi2OK;
}

static fmi2Status me_set_x(fmi2Component c, const fmi2Real x[], size_t nx) {
    model *m = c;
    model_state *s = &m->s;
    fmi2Status st = check_n(m, "fmi2SetContinuousStates", nx, NX, x);
    if (st != fmi2OK) return st;
    for (size_t i = 0; i < NX; i++)
        if (!isfinite(x[i]))
            return hb_fail(m, fmi2Error, "fmi2SetContinuousStates: x[%zu] = %g is not finite; "
                           "nothing changed", i, x[i]);
    double sc[NX];
    scales(s, sc);
    for (size_t i = 0; i < NX; i++) s->y[i] = x[i] / sc[i];
    return fmi2OK;
}

static fmi2Status me_get_x(fmi2Component c, fmi2Real x[], size_t nx) {
    model *m = c;
    fmi2Status st = check_n(m, "fmi2GetContinuousStates", nx, NX, x);
    if (st != fmi2OK) return st;
    double sc[NX];
    scales(&m->s, sc);
    for (size_t i = 0; i < NX; i++) x[i] = m->s.y[i] * sc[i];
    return fmi2OK;
}

static fmi2Status me_nominals(fmi2Component c, fmi2Real x[], size_t nx) {
    model *m = c;
    fmi2Status st = check_n(m, "fmi2GetNominalsOfContinuousStates", nx, NX, x);
    if (st != fmi2OK) return st;
    scales(&m->s, x);
    return fmi2OK;
}

static fmi2Status me_get_dx(fmi2Component c, fmi2Real dx[], size_t nx) {
    model *m = c;
    model_state *s = &m->s;
    fmi2Status st = check_n(m, "fmi2GetDerivatives", nx, NX, dx);
    if (st != fmi2OK) return st;
    hb_apply_inputs(s);
    double dy[NX], sc[NX];
    hb_rhs((s->t - s->t_start) * s->omega, s->y, s->p, s->ist[HBK_I_STICK], s->ist[HBK_I_CONTACT], dy);
    if (hb_kernel_raised())
        return hb_fail(m, fmi2Error, "fmi2GetDerivatives: a kernel raised an exception at t = %.17g s",
                       s->t);
    scales(s, sc);
    for (size_t i = 0; i < NX; i++) dx[i] = dy[i] * sc[i] * s->omega;
    return fmi2OK;
}

double hb_derivative(model *m, int i) {
    double dx[NX];
    return me_get_dx(m, dx, NX) == fmi2OK ? dx[i] : NAN;
}

static fmi2Status me_get_z(fmi2Component c, fmi2Real z[], size_t nz) {
    model *m = c;
    model_state *s = &m->s;
    fmi2Status st = check_n(m, "fmi2GetEventIndicators", nz, HBK_N_EVENT_KINDS, z);
    if (st != fmi2OK) return st;
    hb_apply_inputs(s);
    for (size_t i = 0; i < HBK_N_EVENT_KINDS; i++) z[i] = -1.0;
    int64_t kinds[HBK_WATCH_SLOTS];
    int64_t n = hb_watched(s->ist, s->p, kinds);
    for (int64_t i = 0; i < n; i++)
        z[kinds[i]] = hb_watch_value(kinds[i], s->y, s->p, s->ist[HBK_I_CONTACT]);
    return fmi2OK;
}

static fmi2Status me_completed(fmi2Component c, fmi2Boolean no_prior, fmi2Boolean *enter_event,
                               fmi2Boolean *terminate) {
    (void)c, (void)no_prior;
    if (enter_event) *enter_event = fmi2False;
    if (terminate) *terminate = fmi2False;
    return fmi2OK;
}

void hb_me_fill(hb_wrapper *w) {
    w->EnterEventMode = me_enter_event;
    w->EnterContinuousTimeMode = me_enter_cont;
    w->NewDiscreteStates = me_new_discrete_states;
    w->SetTime = me_set_time;
    w->SetContinuousStates = me_set_x;
    w->GetContinuousStates = me_get_x;
    w->GetNominalsOfContinuousStates = me_nominals;
    w->GetDerivatives = me_get_dx;
    w->GetEventIndicators = me_get_z;
    w->CompletedIntegratorStep = me_completed;
}

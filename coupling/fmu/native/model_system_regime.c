/* The causal runaway and stall verdicts of DrillingSystem's regime output: the co-simulation's rules
 * (hammerbit.cosim.config.cosim_regime, docs/model.md) applied at every communication point to what
 * the run has shown so far, from a small memory that is part of the FMU state.
 *
 * runaway: the bit has not stuck for RUNAWAY_WINDOWS windows of at least MIN_WINDOW forcing periods,
 *   the mean bit velocity over those equal windows (since the last stick, to now) grows strictly with
 *   the last growth at least half the first, and the mean WOB over the last window is above the
 *   friction floor.  The bit positions come from samples at communication points since the last
 *   stick (a ring thinned by half when full), interpolated at the window edges.
 * stall: the bit is stuck and has been for STALL_PERIODS forcing periods, while the mean WOB since
 *   its stick is at least STALL_WOB_FRACTION of the set point.
 * (The scenes' runaway certificate assumes the hammer driven by b + a sin; here the string drives
 * it, so, as in the co-simulation, the fallback rule serves.) */
#include <stdio.h>
#include <string.h>

#include "model_system.h"

#define REGIME_VERDICTS (HB_REGIME_RUNAWAY | HB_REGIME_STALL)

void sys_regime_start(sysstate *s) {
    sysregime *r = &s->rg;
    memset(r, 0, sizeof *r);
    r->stall_since = r->ring_since = s->fst[HSYS_F_T_STICK];
}

/* a sample's value at tau by linear interpolation (tau within the samples) */
static double at(const sysregime *r, const double *v, double tau) {
    int64_t k = 1;
    while (k < r->n - 1 && r->tau[k] < tau) k++;
    double w = (tau - r->tau[k - 1]) / (r->tau[k] - r->tau[k - 1]);
    return v[k - 1] + w * (v[k] - v[k - 1]);
}

/* the samples from index k on cleared (an unused sample is zero: the state check relies on it) */
static void forget_from(sysregime *r, int64_t k) {
    size_t bytes = sizeof(double) * (size_t)(SYS_RING - k);
    memset(r->tau + k, 0, bytes), memset(r->x + k, 0, bytes), memset(r->imp + k, 0, bytes);
    r->n = k;
}

static void keep_sample(sysregime *r, double tau, double x) {
    if (r->n > 0 && tau - r->tau[r->n - 1] < r->gap) return;
    if (r->n == SYS_RING) {               /* thin by half: every other sample, the first kept */
        for (int64_t k = 1; k < SYS_RING / 2; k++) {
            r->tau[k] = r->tau[2 * k], r->x[k] = r->x[2 * k], r->imp[k] = r->imp[2 * k];
        }
        r->n = SYS_RING / 2;
        forget_from(r, r->n);
        r->gap *= 2.0;
    }
    r->tau[r->n] = tau, r->x[r->n] = x, r->imp[r->n] = r->impulse;
    r->n++;
}

static int runs_away(const sysregime *r, double tau, double since, double period) {
    const int nw = HSYS_RUNAWAY_WINDOWS;
    if (r->n < 2 || tau - since < nw * HSYS_MIN_WINDOW * period) return 0;
    double t0 = r->tau[0], span = r->tau[r->n - 1] - t0, v[HSYS_RUNAWAY_WINDOWS];
    for (int k = 0; k < nw; k++)
        v[k] = (at(r, r->x, t0 + (k + 1) * span / nw) - at(r, r->x, t0 + k * span / nw)) / (span / nw);
    double first = v[1] - v[0], last = v[nw - 1] - v[nw - 2];
    for (int k = 1; k < nw; k++)
        if (!(v[k] - v[k - 1] > 0.0)) return 0;
    if (!(last >= 0.5 * first)) return 0;
    double mean_wob = (at(r, r->imp, t0 + span) - at(r, r->imp, t0 + (nw - 1) * span / nw)) / (span / nw);
    return mean_wob > HSYS_FRICTION_FLOOR;
}

void sys_regime_step(model *m, double step_impulse, double dtau) {
    sysstate *s = &m->s;
    sysregime *r = &s->rg;
    double tau = s->fst[HSYS_F_T], period = HB_TWO_PI / s->p[HSYS_P_ETA];
    double stick = s->fst[HSYS_F_T_STICK], since = stick >= 0.0 ? stick : HSYS_OMEGA * s->t_start;
    int stuck = s->ist[HSYS_I_STICK] == HSYS_STICK;
    r->impulse += step_impulse;
    int64_t verdict = 0;
    if (stuck) {
        if (stick != r->stall_since) {    /* a new stick phase: its share of this step's impulse */
            r->stall_since = stick;
            r->stall_impulse = step_impulse * fmin(1.0, (tau - stick) / dtau);
        } else {
            r->stall_impulse += step_impulse;
        }
        double held = tau - since;
        if (held >= HSYS_STALL_PERIODS * period &&
            r->stall_impulse / held * HSYS_F0 >= HSYS_STALL_WOB_FRACTION * s->applied[IN_WOB_SET_POINT])
            verdict |= HB_REGIME_STALL;
        forget_from(r, 0);
    } else {
        if (stick != r->ring_since || r->n == 0) {   /* samples since this slip phase only */
            r->ring_since = stick;
            forget_from(r, 0);
            r->gap = period / 8.0;
        }
        keep_sample(r, tau, s->y[HSYS_X_BIT]);
        if (runs_away(r, tau, since, period)) verdict |= HB_REGIME_RUNAWAY;
    }
    if (verdict != r->verdict) {
        char t[40];
        hb_repr(s->t, t, sizeof t);
        hb_model_log(m, fmi2OK, "regime at t = %s s: runaway %s, stall %s", t,
                     verdict & HB_REGIME_RUNAWAY ? "yes" : "no", verdict & HB_REGIME_STALL ? "yes" : "no");
        r->verdict = verdict;
    }
}

const char *sys_regime_invalid(const sysstate *s) {
    const sysregime *r = &s->rg;
    if (r->n < 0 || r->n > SYS_RING) return "its regime samples are out of range";
    if (r->verdict & ~(int64_t)REGIME_VERDICTS) return "its regime verdict is out of range";
    double head[] = {r->impulse, r->stall_since, r->stall_impulse, r->ring_since, r->gap};
    for (size_t i = 0; i < sizeof head / sizeof head[0]; i++)
        if (!isfinite(head[i])) return "its regime memory holds a non-finite number";
    if (r->n > 0 && !(r->gap > 0.0)) return "its regime sample spacing is not positive";
    for (int64_t k = 0; k < r->n; k++) {
        if (!(isfinite(r->tau[k]) && isfinite(r->x[k]) && isfinite(r->imp[k])))
            return "its regime memory holds a non-finite number";
        if (k > 0 && !(r->tau[k] > r->tau[k - 1])) return "its regime samples are not in time order";
    }
    for (int64_t k = r->n; k < SYS_RING; k++)
        if (r->tau[k] != 0.0 || r->x[k] != 0.0 || r->imp[k] != 0.0 || signbit(r->tau[k]) || signbit(r->x[k]) ||
            signbit(r->imp[k]))
            return "its unused regime samples are not clear";
    return NULL;
}

/* Parameters of the native model backend -> the kernel's arrays: validated as the Python slave
 * does (RigParameters, Groups, the Stepper's options), then SI -> the paper's groups -> the
 * kernel's parameter vector, exactly as RigParameters.to_groups and Groups.to_kernel compute it
 * (same operations in the same order). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "kernel_api.h"
#include "model_native.h"

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
    double si[HB_N_SI];   /* the rig parameters of the formulas (hb_description.h) */
    for (size_t i = 0; i < HB_N_SI; i++) {
        int k = HB_RIG_ORDER[i];
        si[i] = k == HBS_gap ? gap : k < 0 ? 0.0 : v[k];   /* k < 0: preload (an input, 0 here) */
        const hb_range *r = k < 0 ? &HB_RANGE_PRELOAD : &HB_STORED[k].range;
        if (hb_range_error(k < 0 ? "preload" : HB_STORED[k].name, si[i], r, err, n)) return 0;
    }
    if (v[HBS_mu_kinetic] > v[HBS_mu_static]) {
        char rv[40], ms[40];
        hb_repr(v[HBS_mu_kinetic], rv, sizeof rv);
        snprintf(ms, sizeof ms, "%g", v[HBS_mu_static]);
        snprintf(err, n, "parameter 'mu_kinetic' = %s is out of range: allowed (0, mu_static = %s]: "
                 "kinetic friction above static", rv, ms);
        return 0;
    }
    /* Scales and RigParameters.to_groups: the description's formulas */
    double sc[HB_N_SCALES], g[HB_NGROUPS];
    hb_si_to_groups(si, sc, g);
    double F0 = sc[HB_SC_F0], Om = sc[HB_SC_Omega], x0 = sc[HB_SC_x0];
    for (int i = 0; i < HB_NGROUPS; i++)
        if (hb_range_error(HB_GROUPS[i].name, g[i], &HB_GROUPS[i].range, err, n)) return 0;
    if (s->t_start != 0.0) {
        /* absolute-time forcing on the kernel's clock tau = Omega (t - t_start) */
        double omega_f = HB_TWO_PI * v[HBS_frequency];
        g[HB_G_phi] = fmod(v[HBS_phase] + omega_f * s->t_start, HB_TWO_PI);
        if (hb_range_error("phi", g[HB_G_phi], &HB_GROUPS[HB_G_phi].range, err, n)) return 0;
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
        for (int i = 0; i < HB_NGROUPS; i++) p[HB_GROUP_SLOT[i]] = g[i];
        p[HBK_P_FEXT] = 0.0;
        p[HBK_P_CONTACT] = (isfinite(g[HB_G_r]) && g[HB_G_kc] > 0.0) ? 1.0 : 0.0;
        memset(s->y, 0, sizeof s->y);
        memset(s->ist, 0, sizeof s->ist);
        memset(s->fst, 0, sizeof s->fst);
        memcpy(s->y, y0, sizeof y0);
    }
    double period = HB_TWO_PI / g[HB_G_eta];
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
    hb_oscillator_l1(g[HB_G_rho], g[HB_G_xi], s->l1);
    s->regime_seen = hb_regime_now(s);
    return 1;
}


int32_t hb_regime_now(model_state *s) {
    double cert[HBK_N_CERT];
    return (int32_t)hb_regime(s->y, s->ist, s->fst, s->p, s->l1, cert);
}


void hb_regime_names(int32_t regime, char *out, size_t n) {
    size_t used = 0;
    out[0] = '\0';
    for (int i = 0; i < HB_N_REGIME_BITS; i++) {
        if (!(regime & HB_REGIME_BIT[i])) continue;
        int k = snprintf(out + used, n - used, "%s%s", used ? ", " : "", HB_REGIME_NAME[i]);
        if (k < 0 || (size_t)k >= n - used) break;
        used += (size_t)k;
    }
    if (!used) snprintf(out, n, "none");
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

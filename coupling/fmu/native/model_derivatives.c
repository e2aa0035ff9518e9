/* Output derivatives of the native HammerBitRock model (fmi2GetRealOutputDerivatives,
 * fmi3GetOutputDerivatives): the first and second time derivatives of its Real outputs at the
 * current time, exact, from the vector field of the current hybrid mode.
 *
 * With y the nondimensional state, f = dy/dtau the vector field of the hybrid mode (hb_rhs, the
 * kernels' own) and g = d2y/dtau2 = df/dtau along the solution, differentiated here in closed form
 * (the chain rule through the spring-damper, the Hunt-Crossley contact force, the velocity-
 * weakening friction and the harmonic forcing; the inputs held, as fmi2DoStep holds them):
 *   positions:  order 1 = f, order 2 = g (x1'' = f2, x3'' = f4);
 *   velocities: order 1 = f, order 2 = g;
 *   forces:     the force law differentiated once and twice along (f, g);
 *   rate of penetration R = (x3 - x3(t0)) / (t - t0): R' = (x3' - R) / (t - t0),
 *               R'' = (x3'' - 2 R') / (t - t0); 0 at t = t0, as R itself.
 * In stick the bit's derivatives are 0 and the friction force is the static reaction (the force on
 * the bit), differentiated as such; the contact force and its derivatives are those of the CONTACT
 * mode (0 while free or clamped).  These are one-sided derivatives: at a communication point on an
 * event they belong to the mode the state is in after the event's reset.  The Integer and Boolean
 * outputs (modes, counters) are piecewise constant: their derivatives are 0, and FMI asks for
 * derivatives of Real outputs only. */
#include <math.h>

#include "kernel_api.h"
#include "model_native.h"

#define MAX_ORDER 2

/* the nondimensional state's first and second derivatives and the forces' (index: 0 spring-damper,
 * 1 contact, 2 force on the bit, 3 friction), d/dtau and d2/dtau2 */
typedef struct {
    double f[4], g[4];
    double force1[4], force2[4];
} jets;

/* the Hunt-Crossley force kc D(d) (1 + lam d') differentiated along d(tau): out = [F', F''] */
static void contact_jets(const double *p, double d, double d1, double d2, double r, double r1, double r2,
                         double out[2]) {
    double n = p[HBK_P_N], kc = p[HBK_P_KC], lam = p[HBK_P_LAM];
    double ad = fabs(d), sg = d < 0.0 ? -1.0 : 1.0;
    /* D = sign(d) |d|^n and its derivatives (the kernel's odd extension); at d = 0 (the instant
       of an impact) a power with no finite limit there (D' for n < 1, D'' for n < 2) gives 0 */
    double D = ad > 0.0 ? sg * pow(ad, n) : 0.0;
    double D1 = ad > 0.0 ? n * pow(ad, n - 1.0) : (n == 1.0 ? 1.0 : 0.0);
    double D2 = ad > 0.0 ? sg * n * (n - 1.0) * pow(ad, n - 2.0) : 0.0;
    double damp = 1.0 + lam * r;
    out[0] = kc * (D1 * d1 * damp + D * lam * r1);
    out[1] = kc * (D2 * d1 * d1 * damp + D1 * d2 * damp + 2.0 * D1 * d1 * lam * r1 + D * lam * r2);
}

/* the jets of the state y in the modes (ms, mc) at tau (inputs as applied to p) */
static void compute_jets(const double *y, double *p, int64_t ms, int64_t mc, double tau, jets *J) {
    double *f = J->f, *g = J->g;
    hb_rhs(tau, (double *)y, p, ms, mc, f);
    double xi = p[HBK_P_XI], rho = p[HBK_P_RHO];
    int slip = ms == HBK_SLIP;
    /* overlap d = x1 - x3 - r and relative velocity r = x2 - x4, with their rates */
    double d = y[0] - y[2] - p[HBK_P_R], r = y[1] - y[3];
    double d1 = f[0] - f[2], r1 = f[1] - f[3];
    double spring1 = d1 + 2.0 * xi * r1;
    double c[2] = {0.0, 0.0};
    if (mc == HBK_CONTACT) contact_jets(p, d, d1, 0.0, r, r1, 0.0, c);   /* c[0] is F_c' */
    double phase = p[HBK_P_ETA] * tau + p[HBK_P_PHI];
    double forcing1 = p[HBK_P_A] * p[HBK_P_ETA] * cos(phase);
    /* friction K(v) = mu + (1 - mu) exp(-gamma v): in slip v = x4 >= 0 at a state the solver
       accepted, where the kernel's law is this exponential */
    double mu = p[HBK_P_MU], gam = p[HBK_P_GAMMA];
    double e = slip ? exp(-gam * y[3]) : 0.0;
    double K1 = -(1.0 - mu) * gam * e, K2 = (1.0 - mu) * gam * gam * e;
    g[0] = f[1];
    g[1] = forcing1 - spring1 - c[0];
    g[2] = slip ? f[3] : 0.0;
    g[3] = slip ? (spring1 + c[0] - K1 * f[3]) / rho : 0.0;
    double d2 = g[0] - g[2], r2 = g[1] - g[3];
    if (mc == HBK_CONTACT) contact_jets(p, d, d1, d2, r, r1, r2, c);
    J->force1[0] = spring1;
    J->force2[0] = d2 + 2.0 * xi * r2;
    J->force1[1] = c[0];
    J->force2[1] = c[1];
    J->force1[2] = J->force1[0] + c[0];
    J->force2[2] = J->force2[0] + c[1];
    J->force1[3] = slip ? K1 * f[3] : J->force1[2];
    J->force2[3] = slip ? K2 * f[3] * f[3] + K1 * g[3] : J->force2[2];
}

static int is_real_output(fmi2ValueReference vr) {
    switch (vr) {
    case HB_VR_hammer_position: case HB_VR_hammer_velocity: case HB_VR_bit_position:
    case HB_VR_bit_velocity: case HB_VR_spring_force: case HB_VR_contact_force: case HB_VR_rock_force:
    case HB_VR_friction_force: case HB_VR_rate_of_penetration: return 1;
    default: return 0;
    }
}

/* derivative `order` (1 or 2) of the Real output vr [SI] from the jets; 0 if vr is no Real output */
static int output_derivative(const model_state *s, const jets *J, fmi2ValueReference vr, int order,
                             double *out) {
    double w = s->omega, wk = order == 1 ? w : w * w;
    const double *y1 = order == 1 ? J->f : J->g;
    const double *F = order == 1 ? J->force1 : J->force2;
    switch (vr) {
    case HB_VR_hammer_position: *out = y1[0] * s->x0 * wk; return 1;
    case HB_VR_hammer_velocity: *out = y1[1] * s->v0 * wk; return 1;
    case HB_VR_bit_position: *out = y1[2] * s->x0 * wk; return 1;
    case HB_VR_bit_velocity: *out = y1[3] * s->v0 * wk; return 1;
    case HB_VR_spring_force: *out = F[0] * s->F0 * wk; return 1;
    case HB_VR_contact_force: *out = F[1] * s->F0 * wk; return 1;
    case HB_VR_rock_force: *out = F[2] * s->F0 * wk; return 1;
    case HB_VR_friction_force: *out = F[3] * s->F0 * wk; return 1;
    case HB_VR_rate_of_penetration: {
        double T = s->t - s->t_start;
        if (T <= 0.0) {
            *out = 0.0;
            return 1;
        }
        double R = (s->y[2] - s->x3_start) * s->x0 / T;
        double R1 = (J->f[2] * s->x0 * w - R) / T;
        *out = order == 1 ? R1 : (J->g[2] * s->x0 * w * w - 2.0 * R1) / T;
        return 1;
    }
    default: return 0;
    }
}

static fmi2Status n_get_output_derivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                           const fmi2Integer order[], fmi2Real value[]) {
    model *m = c;
    model_state *s = &m->s;
    s->last_status = fmi2OK;
    if (nvr == 0) return fmi2OK;
    if (!vr || !order || !value)
        return hb_fail(m, fmi2Error, "fmi2GetRealOutputDerivatives: an array is NULL");
    for (size_t i = 0; i < nvr; i++) {
        if (order[i] < 1 || order[i] > MAX_ORDER)
            return hb_fail(m, fmi2Error, "fmi2GetRealOutputDerivatives: order[%zu] = %d is out of range: "
                           "allowed 1, 2 (maxOutputDerivativeOrder = %d)", i, (int)order[i], MAX_ORDER);
        if (!is_real_output(vr[i]))
            return hb_fail(m, fmi2Error, "fmi2GetRealOutputDerivatives: value reference %u is not a Real "
                           "output (derivatives are given of the Real outputs only)", vr[i]);
    }
    hb_apply_inputs(s);
    jets J;
    compute_jets(s->y, s->p, s->ist[HBK_I_STICK], s->ist[HBK_I_CONTACT], (s->t - s->t_start) * s->omega, &J);
    if (hb_kernel_raised())
        return hb_fail(m, fmi2Error, "fmi2GetRealOutputDerivatives: a kernel raised an exception at "
                       "t = %.17g s", s->t);
    for (size_t i = 0; i < nvr; i++) output_derivative(s, &J, vr[i], order[i], &value[i]);
    return fmi2OK;
}

void hb_derivatives_fill(hb_wrapper *w) {
    w->GetRealOutputDerivatives = n_get_output_derivatives;
}

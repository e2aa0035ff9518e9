/* FMU states of the native model backend: the whole model_state as plain data (a copy per
 * fmi2GetFMUstate; serialized as its bytes, behind the front's header with magic and GUID).
 * A state read back is checked field by field before it is used. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kernel_api.h"
#include "model_native.h"

/* ------------------------------------------------------------------------------------------ */
static fmi2Status n_get_state(fmi2Component c, fmi2FMUstate *state) {
    model *m = c;
    model_state *copy = malloc(sizeof *copy);
    if (!copy) return hb_fail(m, fmi2Error, "fmi2GetFMUstate: out of memory");
    m->s.last_status = fmi2OK;
    *copy = m->s;
    *state = copy;
    return fmi2OK;
}

/* the kernel's clock tau = omega (t - t_start) may differ from the communication time's by this
 * much, relative to max(1, |tau|) (the driver ends a step at its end time to the last bits) */
#define TAU_REL_TOL 1e-9
/* the largest count an integer state entry may hold (exact in a double, as the Python flavour's) */
#define MAX_COUNT 9007199254740992.0

static int in_time_range(double t) { return fabs(t) <= HB_STATE_TIME_LIMIT; }   /* also NaN */

/* the integer state: modes among their values, record indexes 0 (the FMU records nothing: its
 * record buffers are empty, so another index would write outside them), windows >= -1, counts
 * >= 0 */
static const char *ist_invalid(const int64_t *ist) {
    if (ist[HBK_I_STICK] < 0 || ist[HBK_I_STICK] > 1 || ist[HBK_I_CONTACT] < 0 ||
        ist[HBK_I_CONTACT] > 2 || ist[HBK_I_BOUNCE] < 0 || ist[HBK_I_BOUNCE] > 1)
        return "its hybrid mode is out of range";
    if (ist[HBK_I_POIN_NEXT] != 0 || ist[HBK_I_SAMP_NEXT] != 0 || ist[HBK_I_NLOG] != 0)
        return "a record index is not 0 (the FMU's record buffers are empty)";
    for (int i = 0; i < HBK_N_ISTATE; i++) {
        int64_t lowest = (i == HBK_I_WIN || i == HBK_I_SWIN) ? -1 : 0;
        if (ist[i] < lowest || (double)ist[i] >= MAX_COUNT) return "a counter is out of range";
    }
    for (int i = HBK_I_COUNT0; i < HBK_I_COUNT0 + HBK_N_EVENT_KINDS; i++)   /* 32-bit Integer outputs */
        if (ist[i] > INT32_MAX) return "an event counter is above 2**31 - 1";
    return NULL;
}

/* the arrays the parameters in use give (hb_commit of the committed values at the state's start
 * time), bit for bit; the inputs in p within their limits */
static const char *derived_invalid(const model_state *s) {
    model_state trial = *s;
    char err[512];
    if (!hb_commit(&trial, s->committed, s->committed_impact, 0, err, sizeof err))
        return "its parameters in use are invalid";
    for (int i = 0; i < HBK_N_P; i++) {
        if (i == HBK_P_B || i == HBK_P_FEXT) continue;
        if (memcmp(&s->p[i], &trial.p[i], sizeof(double)) != 0)
            return "its kernel parameters are not those of its parameters in use";
    }
    if (!(fabs(s->p[HBK_P_B]) <= HB_INPUT_LIMIT_F0_preload * (1.0 + 1e-12)) ||
        !(fabs(s->p[HBK_P_FEXT]) <= HB_INPUT_LIMIT_F0_harmonic_force * (1.0 + 1e-12)))
        return "an input held in its kernel parameters is out of range";
    if (memcmp(s->opts, trial.opts, sizeof s->opts) != 0 || s->x0 != trial.x0 || s->v0 != trial.v0 ||
        s->F0 != trial.F0 || s->omega != trial.omega || s->x3_start != trial.x3_start)
        return "its solver options or scales are not those of its parameters in use";
    if (memcmp(s->l1, trial.l1, sizeof s->l1) != 0)
        return "its regime certificate's numbers are not those of its parameters in use";
    for (int k = HBS_preload; s->ready && k <= HBS_harmonic_force; k++)
        if (!hb_input_ok(s, k, s->value[k])) return "an input is out of range";
    double tau = (s->t - s->t_start) * s->omega;
    if (!(fabs(s->fst[HBK_F_T] - tau) <= TAU_REL_TOL * fmax(1.0, fabs(tau))))
        return "its solver time is not omega (t - t_start)";
    return NULL;
}

/* the hybrid mode fits the positions: the forces of the state finite (contact marked without an
 * impact device, whose gap is infinite, gives an infinite contact force) */
static const char *forces_invalid(const model_state *s) {
    double y[4], p[HBK_N_P], f[4];
    int64_t ist[HBK_N_ISTATE];
    memcpy(y, s->y, sizeof y);
    memcpy(p, s->p, sizeof p);
    memcpy(ist, s->ist, sizeof ist);
    hb_forces(y, ist, p, f);
    for (int i = 0; i < 4; i++)
        if (!isfinite(f[i])) return "its hybrid mode does not fit its positions (a force is not finite)";
    return NULL;
}

/* NULL if `s` can be a state of this build, checked in full; else the reason */
static const char *state_invalid(const model_state *s) {
    if (s->magic != MODEL_STATE_MAGIC || s->size != sizeof *s) return "it is not a state of this build";
    if ((s->ready | s->terminated | s->dirty | s->stale | s->has_commit | s->impact_enabled |
         s->committed_impact) & ~1)
        return "a flag is neither 0 nor 1";
    if (!s->has_commit) return "it holds no parameters in use";
    if (s->last_status < fmi2OK || s->last_status > fmi2Pending) return "its last status is not a status";
    if (!memchr(s->error, '\0', sizeof s->error)) return "its error message is not terminated";
    if (!in_time_range(s->t) || !in_time_range(s->t_start) || s->t < s->t_start)
        return "its times are out of range or t < t_start";
    /* the values as set: a parameter's is checked where it is used (fmi2ExitInitializationMode,
     * the tolerance's at the next step), an input's at the step (below for a ready state) */
    for (int i = 0; i < HB_NSTORED; i++)
        if (isnan(s->value[i])) return "a variable's value is NaN";
    for (int i = 0; i < 4; i++)
        if (!hb_contains(&HB_RANGE_STATE_POSITION, s->y[i]))
            return "its state holds a position or velocity out of range";
    for (int i = 0; i < HBK_N_FSTATE; i++)
        if (isnan(s->fst[i])) return "its solver state holds NaN";
    if (!isfinite(s->fst[HBK_F_T]) || !(s->fst[HBK_F_H] > 0.0 && isfinite(s->fst[HBK_F_H])))
        return "its solver time or step proposal is not finite and positive";
    const char *why = ist_invalid(s->ist);
    if (!why) why = derived_invalid(s);
    return why ? why : forces_invalid(s);
}

static fmi2Status n_set_state(fmi2Component c, fmi2FMUstate state) {
    model *m = c;
    const model_state *s = state;
    const char *why = state_invalid(s);
    if (why) return hb_fail(m, fmi2Error, "fmi2SetFMUstate: %s; state unchanged", why);
    m->s = *s;
    m->s.last_status = fmi2OK;
    return fmi2OK;
}

static fmi2Status n_free_state(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

static fmi2Status n_state_size(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)c, (void)state;
    *size = sizeof(model_state);
    return fmi2OK;
}

static fmi2Status n_serialize(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size) {
    if (size != sizeof(model_state))
        return hb_fail(c, fmi2Error, "fmi2SerializeFMUstate: size = %zu, the state needs %zu bytes", size,
                    sizeof(model_state));
    memcpy(out, state, sizeof(model_state));
    return fmi2OK;
}

static fmi2Status n_deserialize(fmi2Component c, const fmi2Byte in[], size_t size,
                                fmi2FMUstate *state) {
    model *m = c;
    m->s.last_status = fmi2OK;
    if (size != sizeof(model_state))
        return hb_fail(m, fmi2Error, "fmi2DeSerializeFMUstate: %zu bytes, but a state of this build has "
                    "%zu; state unchanged", size, sizeof(model_state));
    model_state *copy = malloc(sizeof *copy);
    if (!copy) return hb_fail(m, fmi2Error, "fmi2DeSerializeFMUstate: out of memory");
    memcpy(copy, in, sizeof *copy);
    const char *why = state_invalid(copy);
    if (why) {
        free(copy);
        return hb_fail(m, fmi2Error, "fmi2DeSerializeFMUstate: the bytes are corrupt (%s); state "
                    "unchanged", why);
    }
    *state = copy;
    return fmi2OK;
}


void hb_state_fill(hb_wrapper *w) {
    w->GetFMUstate = n_get_state;
    w->SetFMUstate = n_set_state;
    w->FreeFMUstate = n_free_state;
    w->SerializedFMUstateSize = n_state_size;
    w->SerializeFMUstate = n_serialize;
    w->DeSerializeFMUstate = n_deserialize;
}

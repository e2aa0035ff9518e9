/* The model layer behind the FMI fronts (the role of model.h in the Reference-FMUs).
 *
 * A model (model_native.c: HammerBitRock; model_string.c: Drillstring) provides hb_model_fill,
 * which puts its functions into the backend table the fronts call (hb_wrapper, front.h: life
 * cycle, values, FMU states, fmi2DoStep and, where the model has them, the Model Exchange
 * functions).  model_backend.c holds the table and fills it once; model_common.c holds what every
 * model's instance shares (its name and the front's callbacks, the logger) and what the models' FMI
 * functions share (filling the table, fmi2DoStep's checks of t and h, a plain state's
 * deserialization, the Integer getter's loop). */
#ifndef HAMMERBIT_MODEL_H
#define HAMMERBIT_MODEL_H

#include <stddef.h>
#include <stdio.h>

#include "front.h"

/* the model's functions into w; Instantiate last (a non-NULL Instantiate: the table is ready) */
void hb_model_fill(hb_wrapper *w);

/* what every model instance starts with (its first member) */
typedef struct {
    char *name;                  /* the instance name of fmi2Instantiate */
    fmi2CallbackFunctions cb;    /* the front's callbacks */
} hb_model_base;

/* a zeroed instance of `size` bytes, a struct whose first member is an hb_model_base, holding
 * name and cb; NULL when out of memory */
void *hb_model_new(size_t size, const char *name, const fmi2CallbackFunctions *cb);
/* free an instance of hb_model_new (its own buffers are the model's to free first) */
void hb_model_free(void *m);
/* a message with a status through the front's logger of the instance m (an hb_model_base first),
 * under the category of its status; the message is passed on as the format (the front escapes
 * its '%') */
void hb_model_log(const void *m, fmi2Status st, const char *fmt, ...);

/* fmi2Get/SetBoolean and fmi2Get/SetString of a model with no variable of either type: an error
 * naming the type when asked for any */
void hb_model_no_booleans_strings(hb_wrapper *w);
/* fmi2FreeFMUstate of a state that is one malloc'd block */
fmi2Status hb_model_free_state(fmi2Component c, fmi2FMUstate *state);
/* a life-cycle call with nothing to do (fmi2EnterInitializationMode) */
fmi2Status hb_model_no_op(fmi2Component c);

/* the life-cycle functions into w (fmi2EnterInitializationMode: nothing to do) */
void hb_model_fill_life_cycle(hb_wrapper *w, fmi2FreeInstanceFn free_instance, fmi2SetupExperimentFn setup,
                              fmi2ComponentFn exit_init, fmi2ComponentFn terminate, fmi2ComponentFn reset);
/* the Real and Integer functions into w, and those of a model with no Boolean or String variable */
void hb_model_fill_values(hb_wrapper *w, fmi2GetRealFn get_real, fmi2SetRealFn set_real,
                          fmi2GetIntegerFn get_integer, fmi2SetIntegerFn set_integer);
/* the FMU-state functions into w, of a state that is one malloc'd block (hb_model_free_state) */
void hb_model_fill_states(hb_wrapper *w, fmi2GetFMUstateFn get, fmi2SetFMUstateFn set,
                          fmi2SerializedFMUstateSizeFn size, fmi2SerializeFMUstateFn serialize,
                          fmi2DeSerializeFMUstateFn deserialize);

/* fmi2OK if fmi2DoStep(t, h) may start: refusal is NULL (else why the instance refuses to step), h is
 * positive and finite and t is the instance's time t_now within tolerance * max(|t_now|, h); else
 * fmi2Error with a message, through the logger of the instance m */
fmi2Status hb_model_step_check(const void *m, const char *refusal, double t_now, double t, double h,
                               double tolerance);
/* a refused fmi2DoStep from t_from to t_to: `kept` (the state of the step's start, `size` bytes, the
 * model's own copy) copied back over `state`, and `why` logged as the refusal (fmi2Error) */
fmi2Status hb_model_step_put_back(const void *m, void *state, const void *kept, size_t size, double t_from,
                                  double t_to, const char *why);
/* the FMU state of `size` bytes in `in` as a new malloc'd block in *state, if size is `expected` and
 * invalid(m, block) is NULL (else its reason); else fmi2Error with a message and *state unchanged */
fmi2Status hb_model_deserialize(const void *m, const fmi2Byte in[], size_t size, size_t expected,
                                const char *(*invalid)(const void *m, const void *state), fmi2FMUstate *state);

/* the typed value functions' FMI signatures, for a model's own (static) functions */
#define HB_GET_REAL(name) \
    static fmi2Status name(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
#define HB_SET_REAL(name) \
    static fmi2Status name(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
#define HB_GET_INTEGER(name) \
    static fmi2Status name(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
#define HB_SET_INTEGER(name) \
    static fmi2Status name(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
/* fmi2GetInteger of a model whose Integer variable vr reads as value(m, vr, &out), 0 if vr is unknown:
 * an error naming the first unknown value reference */
fmi2Status hb_model_get_integers(const void *m, const fmi2ValueReference vr[], size_t nvr, fmi2Integer out[],
                                 int (*value)(const void *m, fmi2ValueReference vr, fmi2Integer *out));

/* fmi2Terminate and fmi2Reset (s_terminate, s_reset) of a model whose state STATE (an expression of
 * the instance c) has ready, terminated and error[], and whose set_start_values(c) starts it anew */
#define HB_MODEL_TERMINATE_RESET(STATE)                                                    \
    static fmi2Status s_terminate(fmi2Component c) {                                       \
        (STATE)->ready = 0;                                                                \
        (STATE)->terminated = 1;                                                           \
        snprintf((STATE)->error, sizeof (STATE)->error, "terminated (fmi2Terminate)");     \
        return fmi2OK;                                                                     \
    }                                                                                      \
    static fmi2Status s_reset(fmi2Component c) {                                           \
        set_start_values(c);                                                               \
        return fmi2OK;                                                                     \
    }

#endif

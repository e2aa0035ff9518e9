/* The model layer behind the FMI fronts (the role of model.h in the Reference-FMUs).
 *
 * A model (model_native.c: HammerBitRock; model_string.c: Drillstring) provides hb_model_fill,
 * which puts its functions into the backend table the fronts call (hb_wrapper, front.h: life
 * cycle, values, FMU states, fmi2DoStep and, where the model has them, the Model Exchange
 * functions).  model_backend.c holds the table and fills it once; model_common.c holds what every
 * model's instance shares (its name and the front's callbacks, the logger). */
#ifndef HAMMERBIT_MODEL_H
#define HAMMERBIT_MODEL_H

#include <stddef.h>

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

#endif

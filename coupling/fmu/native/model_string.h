/* The native Drillstring model: the exact step's tables, the model state and what its files
 * share:
 *   model_string.c         life cycle, parameters, fmi2DoStep, hb_model_fill (model.h)
 *   model_string_table.c   the tables read from the resources
 *   model_string_access.c  fmi2Get*, fmi2Set*, FMU states */
#ifndef HAMMERBIT_MODEL_STRING_H
#define HAMMERBIT_MODEL_STRING_H

#include <complex.h>
#include <stddef.h>
#include <stdint.h>

#include "front.h"
#include "model.h"
#include "hb_description.h"
#include "hs_string.h"

/* the exact step's sizes and output rows, from the Python side (hs_string.h) */
#define N_COEFFS HS_N_COEFFS
#define N_ROWS HS_N_ROWS
#define ROW_HOOK HS_ROW_HOOK_TENSION
#define ROW_TOP_U HS_ROW_TOP_POSITION
#define ROW_TOP_V HS_ROW_TOP_VELOCITY
#define STATE_MAGIC 0x48425332u  /* "HBS2": layout version of the string model state */
#define DATA_MAGIC HS_DATA_MAGIC
#define GENERATOR_KIND 2         /* a block of a form's generator (step blocks: 0 dense, 1 modal) */

/* ------------------------------------------------------------------------------------------ */
/* The exact step of one form over one step length, as read from the resources                 */
/* ------------------------------------------------------------------------------------------ */
typedef struct {
    int64_t form;                /* 0 fixed (and feed), 1 auto-driller */
    double h;                    /* the step length's key (12 significant digits) */
    int64_t modal, n;            /* modal: n kept modes; dense: n states */
    double *frow_r, *rows_r, *P; /* dense */
    double _Complex *frow_c, *rows_c, *d, *G, *irow;   /* modal */
    double icol[N_COEFFS];
} block;

/* what the exponentials of a step length the FMU was not built for are computed from */
typedef struct {
    int64_t n, m;                /* states; kept modes (0: a dense form) */
    double *A1, *E, *frow, *rows;
    double _Complex *lam, *B;    /* modal: the kept modes' eigenvalues and inputs V^-1 E */
} generator;

typedef struct {
    int64_t nblocks, nmax;       /* nmax: the longest state vector (in doubles: 2 nmax) */
    block *b;
    generator gen[2];            /* per form (n = 0: the form is absent) */
    double *mem;
} table;

/* the exponentials of a step length other than the built ones (a bounded cache of them) */
typedef struct {
    block b;                     /* b.n = 0: an empty slot */
    double *mem;
    size_t cap;
} cached_step;

/* ------------------------------------------------------------------------------------------ */
/* State                                                                                       */
/* ------------------------------------------------------------------------------------------ */
typedef struct {
    uint32_t magic, size;        /* size: of the whole state, its string vector included */
    /* parameters and inputs as set */
    double damping_ratio, wob, at_rest, feed_velocity, kp, kig, x_in, v_in;
    int32_t extrapolation, top_condition;
    /* outputs */
    double interface_force, held, hook_load, top_position, top_velocity;
    int32_t ready, terminated, started;
    int64_t form, order, n, modal;
    double W, hook_eq, t, t_start, F_held;
    double feed[2], k3[3], th[3], wh[6], Fh[3], out[4], c[N_COEFFS];
    /* the input derivatives for the next fmi2DoStep (fmi2SetRealInputDerivatives): x', v', x'',
     * v'' of the hammer at its start; given: any was set since the last step */
    double der_in[4];
    int32_t der_given;
    char error[512];
    double v[];                  /* the string's state: 2 n doubles (modal eta) or n (dense xi) */
} sstate;

typedef struct {
    hb_model_base base;          /* name, callbacks (model.h) */
    table tab;
    double *buf, *tmp;           /* scratch of the dense step */
    cached_step cache[HS_STEP_CACHE];
    int next_slot;               /* the slot a new step length takes (the oldest) */
    double *work;                /* scratch of the dense exponential (allocated at its first use) */
    size_t size;
    sstate *s;
    sstate *kept;                /* the state of a step's start, put back if the step is refused */
} model;

/* log a message with a status through the front's logger (model.h) */
#define hs_log hb_model_log
#define FAIL(m, ...) (hs_log((m), fmi2Error, __VA_ARGS__), fmi2Error)
/* model_string_table.c: the table from <resources>/string_native.bin; 1, or 0 with the reason
 * in err */
int hs_load_table(const char *dir, table *t, char *err, size_t en);
/* the first block of a form (its n and modal flag are those of every step size of the form) */
const block *hs_any_block(const table *t, int64_t form);

/* model_string_access.c: why a state is refused, checked in full (NULL: accepted).
 * fmi2SetFMUstate and fmi2DeSerializeFMUstate refuse such a state, and fmi2DoStep refuses a step
 * that would end in one, so that every state the FMU holds can be restored */
const char *hs_state_invalid(const model *m, const sstate *s);
/* model_string_access.c: fmi2Get*, fmi2Set* and the FMU-state functions of the backend table */
void hs_access_fill(hb_wrapper *w);

#endif

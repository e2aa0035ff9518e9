/* The native Drillstring backend (model_string.c, model_string_access.c): the exact step's
 * tables, the model state and what the two files share. */
#ifndef HAMMERBIT_MODEL_STRING_H
#define HAMMERBIT_MODEL_STRING_H

#include <complex.h>
#include <stddef.h>
#include <stdint.h>

#include "front.h"
#include "hs_string.h"

#define N_COEFFS 6
#define N_ROWS 5                 /* bottom u, v, top tension, top position, top velocity */
#define ROW_HOOK 2
#define ROW_TOP_U 3
#define ROW_TOP_V 4
#define TOP_FEED 1
#define TOP_AUTO 2
#define STATE_MAGIC 0x48425331u  /* "HBS1": layout version of the string model state */
#define DATA_MAGIC "HBSTRN01"

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

typedef struct {
    int64_t nblocks, nmax;       /* nmax: the longest state vector (in doubles: 2 nmax) */
    block *b;
    double *mem;
} table;

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
    char error[512];
    double v[];                  /* the string's state: 2 n doubles (modal eta) or n (dense xi) */
} sstate;

typedef struct {
    char *name;
    fmi2CallbackFunctions cb;
    table tab;
    double *buf, *tmp;           /* scratch of the dense step */
    size_t size;
    sstate *s;
} model;

/* log a message with a status through the front's logger */
void hs_log(model *m, fmi2Status st, const char *fmt, ...);
#define FAIL(m, ...) (hs_log((m), fmi2Error, __VA_ARGS__), fmi2Error)
/* the first block of a form (its n and modal flag are those of every step size of the form) */
const block *hs_any_block(const table *t, int64_t form);

/* 1 if the parameters of s are valid; else 0 and the first bad one named in out */
int hs_check_parameters(const sstate *s, char *out, size_t n);

/* model_string_access.c: fmi2Get*, fmi2Set* and the FMU-state functions of the backend table */
void hs_access_fill(hb_wrapper *w);

#endif

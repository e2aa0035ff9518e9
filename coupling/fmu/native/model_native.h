/* Types of the tables the build writes into hb_native.h for model_native.c (native flavour). */
#ifndef HAMMERBIT_MODEL_NATIVE_H
#define HAMMERBIT_MODEL_NATIVE_H

#include <stddef.h>

/* allowed values of one real number (hammerbit.model.validation.Range) */
typedef struct {
    double lo, hi;
    int lo_open, hi_open, allow_inf;
    const char *text;          /* Range.text(): "[lo, hi] unit" */
} hb_range;

enum { HB_INPUT, HB_FIXED, HB_TUNABLE };

/* a Real input or parameter the model stores */
typedef struct {
    unsigned vr;
    int kind;                  /* HB_INPUT, HB_FIXED, HB_TUNABLE */
    const char *name;
    double start;
    hb_range range;
} hb_stored;

typedef struct {
    const char *name;          /* the group's name, as a ParameterError names it */
    hb_range range;
} hb_group;

/* a float as Python's repr() writes it */
void hb_repr(double v, char *out, size_t n);

#endif

/* What the parts of the FMI 2.0 front share (front.c, front_core.c, front_state.c,
 * front_inquiry.c, front_me.c): the instance, the state machine's states and masks, the checks
 * and status rules every FMI function applies.  The model's tables come from hb_model.h,
 * generated from modelDescription.xml by hammerbit.fmu.native.build_front(). */
#ifndef HAMMERBIT_FRONT_INTERNAL_H
#define HAMMERBIT_FRONT_INTERNAL_H

#include <stddef.h>

#include "front.h"

enum { HB_REAL, HB_INTEGER, HB_BOOLEAN, HB_STRING };

/* states of an instance: bit masks, as in the FMI 2.0 co-simulation state machine */
enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_TERMINATED = 1 << 3,
    ST_ERROR = 1 << 4,
    ST_FATAL = 1 << 5,
    ST_EVENT = 1 << 6,   /* Model Exchange: Event Mode */
    ST_CONT = 1 << 7,    /* Model Exchange: Continuous-Time Mode */
};

typedef struct {
    int type;                 /* HB_REAL ... */
    fmi2ValueReference vr;
    int set_mask;             /* states in which fmi2Set* may write the variable */
    const char *name;
    const char *kind;         /* "causality, variability" for messages */
} hb_var;

#include "hb_model.h"

/* allowed states per function (FMI 2.0.4, section 4.2.4; Error: only inquiries and recovery) */
#define M_ME (ST_EVENT | ST_CONT)
#define M_ANY_LIVE (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE | ST_TERMINATED | ST_ERROR | M_ME)
#define M_GET (ST_INIT | ST_STEP_COMPLETE | ST_TERMINATED | ST_ERROR | M_ME)
#define M_SET (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE | M_ME)
#define M_STATUS (ST_STEP_COMPLETE | ST_TERMINATED)

/* ------------------------------------------------------------------------------------------ */
/* Instances                                                                                   */
/* ------------------------------------------------------------------------------------------ */
typedef struct {
    char *name;
    fmi2CallbackFunctions user;    /* the host's callbacks (copied) */
    fmi2CallbackFunctions inner;   /* ours, handed to pythonfmu (must outlive the instance) */
    fmi2Component w;               /* pythonfmu's instance */
    int state;
    int logging_on;
    size_t ncat;
    char **cats;
    fmi2Status call_max;           /* highest status pythonfmu logged during the current call */
    fmi2Status last_status;        /* what fmi2GetInteger reports for HB_STATUS_VR (see record) */
    double time;                   /* current communication point [s] */
    double last_successful;        /* fmi2LastSuccessfulTime [s] */
    int stop_defined;              /* fmi2SetupExperiment's stopTimeDefined */
    double stop_time;              /* its stopTime [s] */
    int me;                        /* instantiated for Model Exchange */
} hb_inst;

/* -- front_core.c -------------------------------------------------------------------------- */
/* log through the host's callbacks (a printf format; '%' escaped for the host's logger) */
void log_to(const fmi2CallbackFunctions *cb, const char *name, fmi2Status st, const char *fmt, ...);
#define LOG(I, st, ...) log_to(&(I)->user, (I)->name, (st), __VA_ARGS__)
/* the model logs through this: non-OK messages always reach the host, OK ones when enabled */
void inner_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat,
                  fmi2String message, ...);
/* 1 if the instance's state is in mask, else fmi2Error logged and the Error state */
int allowed(hb_inst *I, int mask, const char *fn);
/* status of a call: errors put the instance into the Error state, fatal into Fatal */
fmi2Status settle(hb_inst *I, fmi2Status st);
/* the calls whose status the model records: last_status becomes their status */
fmi2Status record(hb_inst *I, fmi2Status st);
/* the value references exist with this type (and may be set in the current state); else logged */
int check_vrs(hb_inst *I, const char *fn, int type, const fmi2ValueReference vr[], size_t nvr,
              const void *values, int setting);
/* the status the model says its last call should have had (variable HB_STATUS_VR) */
fmi2Status slave_status(hb_inst *I, fmi2Status st);
/* after a hot-path call: slave_status only when the call was not clean */
fmi2Status hot_status(hb_inst *I, fmi2Status st);
/* the tolerance of communication times near t [s] */
double time_tol(double t);
/* the shortest decimal text of x that reads back as x (as Python's repr) */
const char *fmt_real(char buf[32], double x);
void free_inst(hb_inst *I);


#define BEGIN(fn, mask)                           \
    hb_inst *I = (hb_inst *)c;                    \
    if (!I) return fmi2Error;                     \
    if (!allowed(I, (mask), fn)) return fmi2Error; \
    I->call_max = fmi2OK

#endif

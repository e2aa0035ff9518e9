/* Native front of a pythonfmu co-simulation FMU (FMI 2.0, Linux).
 *
 * binaries/linux64/<id>.so is this library; pythonfmu's export library sits next to it as
 * HB_WRAPPER_FILE and is opened with dlopen once Python is in the process.  The front
 *   1. brings Python into a native host: $HAMMERBIT_PYTHON, else python3 on PATH, is asked
 *      (once, in a child process) for its libpython, its home and its sys.path; libpython is
 *      opened RTLD_GLOBAL and initialised with that sys.path.  A host that already runs
 *      Python (fmpy, ...) is used as it is;
 *   2. turns any legal file URI (file:/x, file://localhost/x, file:///x, percent-encoding)
 *      into the plain path pythonfmu understands;
 *   3. checks the GUID and the FMU type;
 *   4. runs the FMI 2.0 co-simulation state machine and checks value references, types and
 *      settability against the model description, answering fmi2Error itself;
 *   5. returns the slave's real status, which pythonfmu cannot return (variable HB_STATUS_VR);
 *   6. logs errors even with loggingOn = false;
 *   7. releases pythonfmu's interpreter guard at exit in the right order (hb_at_exit in
 *      pythonfmu_wrapper.c).
 *
 * The model-specific tables come from hb_model.h, generated from modelDescription.xml by
 * hammerbit.fmu.native.build_front(); the other parts are listed in front.h. */
#define _GNU_SOURCE
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front.h"

/* ------------------------------------------------------------------------------------------ */
/* Model tables                                                                                */
/* ------------------------------------------------------------------------------------------ */
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

static const char *const TYPE_NAMES[] = {"Real", "Integer", "Boolean", "String"};

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;   /* backend load (Python start) */

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

/* an FMU state of the front: the front's own part, then pythonfmu's */
#define HB_STATE_MAGIC 0x48425354u /* "HBST" */
typedef struct {
    uint32_t magic;
    int state;
    double time;
    double last_successful;
    fmi2FMUstate inner;
} hb_fmustate;

typedef struct {   /* serialised header of an hb_fmustate (followed by pythonfmu's bytes) */
    char magic[8];
    char guid[64];
    int32_t state;
    int32_t pad;
    double time;
    double last_successful;
} hb_serial_header;

/* ------------------------------------------------------------------------------------------ */
/* Logging                                                                                     */
/* ------------------------------------------------------------------------------------------ */
/* The FMI logger takes a printf format: every '%' that does not start "%%" is doubled. */
static void escape_percent(const char *in, char *out, size_t n) {
    size_t j = 0;
    for (size_t i = 0; in[i] && j + 2 < n; i++) {
        if (in[i] == '%') {
            if (in[i + 1] == '%') {
                out[j++] = '%';
                out[j++] = '%';
                i++;
                continue;
            }
            out[j++] = '%';
            out[j++] = '%';
        } else {
            out[j++] = in[i];
        }
    }
    out[j] = '\0';
}

static void log_to(const fmi2CallbackFunctions *cb, const char *name, fmi2Status st, const char *fmt,
                   ...) {
    if (!cb || !cb->logger) return;
    char raw[4096], msg[8200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(raw, sizeof raw, fmt, ap);
    va_end(ap);
    escape_percent(raw, msg, sizeof msg);
    const char *cat = st == fmi2OK ? "logAll"
                      : st == fmi2Warning ? "logStatusWarning"
                      : st == fmi2Discard ? "logStatusDiscard"
                      : st == fmi2Error ? "logStatusError" : "logStatusFatal";
    cb->logger(cb->componentEnvironment, name ? name : "?", st, cat, msg);
}

#define LOG(I, st, ...) log_to(&(I)->user, (I)->name, (st), __VA_ARGS__)

static int category_enabled(const hb_inst *I, const char *cat) {
    if (!I->logging_on) return 0;
    if (I->ncat == 0) return 1;
    for (size_t i = 0; i < I->ncat; i++)
        if (cat && strcmp(I->cats[i], cat) == 0) return 1;
    return 0;
}

/* pythonfmu logs through this: non-OK messages always reach the host, OK ones when enabled */
static void inner_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st,
                         fmi2String cat, fmi2String message, ...) {
    hb_inst *I = (hb_inst *)env;
    if (!I) return;
    if (st > I->call_max) I->call_max = st;
    if (st == fmi2OK && !category_enabled(I, cat)) return;
    if (!I->user.logger) return;
    char msg[8200];
    escape_percent(message ? message : "", msg, sizeof msg);
    I->user.logger(I->user.componentEnvironment, name ? name : I->name, st, cat, msg);
}

/* ------------------------------------------------------------------------------------------ */
/* Helpers                                                                                     */
/* ------------------------------------------------------------------------------------------ */
static const char *state_name(int s) {
    switch (s) {
    case ST_INSTANTIATED: return "Instantiated";
    case ST_INIT: return "Initialization Mode";
    case ST_STEP_COMPLETE: return "Step Mode";
    case ST_TERMINATED: return "Terminated";
    case ST_ERROR: return "Error (after an fmi2Error: fmi2SetFMUstate or fmi2Reset recover)";
    case ST_FATAL: return "Fatal";
    case ST_EVENT: return "Event Mode";
    case ST_CONT: return "Continuous-Time Mode";
    default: return "?";
    }
}

static int allowed(hb_inst *I, int mask, const char *fn) {
    if (I->state & mask) return 1;
    LOG(I, fmi2Error, "%s: illegal call sequence, not allowed in state %s", fn,
        state_name(I->state));
    if (I->state != ST_FATAL) I->state = ST_ERROR;
    I->last_status = fmi2Error;
    return 0;
}

/* Status of a call: errors put the instance into the Error state, fatal into Fatal.  An error of
 * any call, found here or by the slave, is also what the host then reads from last_status. */
static fmi2Status settle(hb_inst *I, fmi2Status st) {
    if (st >= fmi2Error) I->last_status = st;
    if (st == fmi2Fatal)
        I->state = ST_FATAL;
    else if (st == fmi2Error)
        I->state = ST_ERROR;
    return st;
}

/* The calls whose status the slave records (exit of initialisation, steps, setters, state
 * restore, setup): last_status becomes their status, whatever it is. */
static fmi2Status record(hb_inst *I, fmi2Status st) {
    I->last_status = st;
    return settle(I, st);
}

static const hb_var *find_var(int type, fmi2ValueReference vr) {
#if HB_VR_INDEX_LEN
    if (vr >= HB_VR_INDEX_LEN) return NULL;
    int row = HB_VAR_INDEX[type][vr];
    return row < 0 ? NULL : &HB_VARS[row];
#else
    size_t lo = 0, hi = HB_NVARS;
    while (lo < hi) {   /* HB_VARS is sorted by (type, vr) */
        size_t mid = (lo + hi) / 2;
        const hb_var *v = &HB_VARS[mid];
        if (v->type < type || (v->type == type && v->vr < vr))
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < HB_NVARS && HB_VARS[lo].type == type && HB_VARS[lo].vr == vr) return &HB_VARS[lo];
    return NULL;
#endif
}

static const char *var_name_any_type(fmi2ValueReference vr, int *type) {
    for (size_t i = 0; i < HB_NVARS; i++)
        if (HB_VARS[i].vr == vr) {
            *type = HB_VARS[i].type;
            return HB_VARS[i].name;
        }
    return NULL;
}

static int check_vrs(hb_inst *I, const char *fn, int type, const fmi2ValueReference vr[], size_t nvr,
                     const void *values, int setting) {
    if (nvr == 0) return 1;
    if (!vr || !values) {
        LOG(I, fmi2Error, "%s: %s is NULL with nvr = %zu", fn, !vr ? "vr" : "value", nvr);
        return 0;
    }
    for (size_t i = 0; i < nvr; i++) {
        const hb_var *v = find_var(type, vr[i]);
        if (!v) {
            int other = -1;
            const char *name = var_name_any_type(vr[i], &other);
            if (name)
                LOG(I, fmi2Error, "%s: value reference %u is %s, a %s variable, not a %s", fn,
                    vr[i], name, TYPE_NAMES[other], TYPE_NAMES[type]);
            else
                LOG(I, fmi2Error, "%s: unknown value reference %u (no %s variable has it)", fn,
                    vr[i], TYPE_NAMES[type]);
            return 0;
        }
        /* Model Exchange's Event and Continuous-Time Modes set what Step Mode sets */
        int as = I->state & M_ME ? ST_STEP_COMPLETE : I->state;
        if (setting && !(v->set_mask & as)) {
            LOG(I, fmi2Error, "%s: %s (value reference %u; %s) cannot be set in state %s", fn,
                v->name, vr[i], v->kind, state_name(I->state));
            return 0;
        }
    }
    return 1;
}

/* The status the slave says its last call should have had (variable HB_STATUS_VR). */
static fmi2Status slave_status(hb_inst *I, fmi2Status st) {
#if HB_HAS_STATUS_VR
    if (st >= fmi2Error) return st;
    fmi2ValueReference vr = HB_STATUS_VR;
    fmi2Integer v = 0;
    fmi2Status gs = hb_W.GetInteger(I->w, &vr, 1, &v);
    if (gs >= fmi2Error) return gs;
    if (v < fmi2OK || v > fmi2Fatal) {
        LOG(I, fmi2Error, "the slave reported the invalid status %d", v);
        return fmi2Error;
    }
    if ((fmi2Status)v > st) st = (fmi2Status)v;
#else
    (void)I;
#endif
    return st;
}

/* After a hot-path call (fmi2DoStep, fmi2Set*): the slave's status is read only when the call
 * was not clean (pythonfmu returned non-OK, or the slave logged a warning or worse): the slave
 * logs whenever it reports a status other than OK. */
static fmi2Status hot_status(hb_inst *I, fmi2Status st) {
    if (st == fmi2OK && I->call_max == fmi2OK) return fmi2OK;
    return slave_status(I, st);
}

/* Communication times are compared with an absolute tolerance: 1 ns, or a few units in the
 * last place where t is so large that its doubles lie farther apart (beyond about 1e6 s) -- a
 * master computing t0 + n h is within that, and a step never skips a stretch of time. */
#define HB_TIME_ABS_TOL 1e-9
#define HB_TIME_ULPS 4.0
static double time_tol(double t) {
    /* the spacing of the doubles above |t|, from its bits: the front links no libm */
    union { double d; uint64_t u; } next;
    next.d = t < 0 ? -t : t;
    double a = next.d;
    if (!isfinite(a)) return HB_TIME_ABS_TOL;
    next.u += 1;
    double tol = HB_TIME_ULPS * (next.d - a);
    return tol > HB_TIME_ABS_TOL ? tol : HB_TIME_ABS_TOL;
}

/* The shortest decimal text of x that reads back as x (as Python's repr). */
static const char *fmt_real(char buf[32], double x) {
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, 32, "%.*g", prec, x);
        if (!isfinite(x) || strtod(buf, NULL) == x) break;
    }
    return buf;
}

#define BEGIN(fn, mask)                           \
    hb_inst *I = (hb_inst *)c;                    \
    if (!I) return fmi2Error;                     \
    if (!allowed(I, (mask), fn)) return fmi2Error; \
    I->call_max = fmi2OK

/* ------------------------------------------------------------------------------------------ */
/* FMI 2.0 functions                                                                           */
/* ------------------------------------------------------------------------------------------ */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

static void free_inst(hb_inst *I) {
    if (!I) return;
    for (size_t i = 0; i < I->ncat; i++) free(I->cats[i]);
    free(I->cats);
    free(I->name);
    free(I);
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation,
                                     const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                     fmi2Boolean loggingOn) {
    if (!functions || !functions->logger) return NULL;
    const char *name = instanceName ? instanceName : "?";
    if (!instanceName || !*instanceName) {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation && !(HB_HAS_ME && fmuType == fmi2ModelExchange)) {
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: %s supports only %s (fmuType = %d requested)", HB_MODEL_IDENTIFIER,
               HB_HAS_ME ? "fmi2ModelExchange and fmi2CoSimulation" : "fmi2CoSimulation",
               (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, HB_GUID) != 0) {
        log_to(functions, name, fmi2Error,
               "fmi2Instantiate: GUID '%s' does not match this FMU's GUID '%s' (the model "
               "description and the binary come from different builds)",
               fmuGUID ? fmuGUID : "(null)", HB_GUID);
        return NULL;
    }
    if (!fmuResourceLocation) {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: fmuResourceLocation is NULL");
        return NULL;
    }
    char path[PATH_MAX], err[4096];
    if (!hb_uri_to_path(fmuResourceLocation, path, sizeof path, err, sizeof err)) {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: %s", err);
        return NULL;
    }
    pthread_mutex_lock(&g_lock);
    int ok = hb_backend_load(err, sizeof err);
    pthread_mutex_unlock(&g_lock);
    if (!ok) {
        log_to(functions, name, fmi2Error, "fmi2Instantiate: %s", err);
        return NULL;
    }
    hb_inst *I = calloc(1, sizeof *I);
    if (!I || !(I->name = strdup(instanceName))) {
        free(I);
        log_to(functions, name, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    I->user = *functions;
    I->inner.logger = inner_logger;
    I->inner.allocateMemory = calloc;
    I->inner.freeMemory = free;
    I->inner.stepFinished = NULL;
    I->inner.componentEnvironment = I;
    I->logging_on = loggingOn != fmi2False;
    I->state = ST_INSTANTIATED;
    char uri[PATH_MAX + 16];
    snprintf(uri, sizeof uri, "file://%s", path);   /* what pythonfmu strips: plain path */
    I->me = fmuType == fmi2ModelExchange;
    I->w = hb_W.Instantiate(instanceName, fmuType, fmuGUID, uri, &I->inner, visible, fmi2True);
    if (!I->w) {
        LOG(I, fmi2Error, "fmi2Instantiate: the model could not be created (see the messages "
                          "above)");
        free_inst(I);
        return NULL;
    }
    return I;
}

EXPORT void fmi2FreeInstance(fmi2Component c) {
    hb_inst *I = (hb_inst *)c;
    if (!I) return;
    /* after fmi2Fatal pythonfmu has already released the Python objects of the instance:
     * freeing it again would release them twice */
    if (I->state != ST_FATAL && I->w) hb_W.FreeInstance(I->w);
    free_inst(I);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                      const fmi2String categories[]) {
    BEGIN("fmi2SetDebugLogging", M_ANY_LIVE);
    if (nCategories > 0 && !categories) {
        LOG(I, fmi2Error, "fmi2SetDebugLogging: categories is NULL with nCategories = %zu",
            nCategories);
        return settle(I, fmi2Error);
    }
    for (size_t i = 0; i < nCategories; i++) {
        int known = 0;
        for (size_t k = 0; k < HB_NCATEGORIES; k++)
            if (categories[i] && strcmp(categories[i], HB_CATEGORIES[k]) == 0) known = 1;
        if (!known) {
            LOG(I, fmi2Error, "fmi2SetDebugLogging: unknown log category '%s'",
                categories[i] ? categories[i] : "(null)");
            return settle(I, fmi2Error);
        }
    }
    char **cats = nCategories ? calloc(nCategories, sizeof *cats) : NULL;
    if (nCategories && !cats) return settle(I, fmi2Error);
    for (size_t i = 0; i < nCategories; i++) cats[i] = strdup(categories[i]);
    for (size_t i = 0; i < I->ncat; i++) free(I->cats[i]);
    free(I->cats);
    I->cats = cats;
    I->ncat = nCategories;
    I->logging_on = loggingOn != fmi2False;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                      fmi2Real tolerance, fmi2Real startTime,
                                      fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN("fmi2SetupExperiment", ST_INSTANTIATED);
    char a[32], b[32];
    /* the FMU's clock is declared within +-HB_TIME_LIMIT: far outside it a double's resolution
     * (1e-7 s at 1e9 s, 1e129 s at -6e144 s) is no clock the model's steps can run on */
    if (!(fabs(startTime) <= HB_TIME_LIMIT)) {   /* also NaN */
        LOG(I, fmi2Error, "fmi2SetupExperiment: startTime = %s s is out of range: allowed [-%g, %g] s; "
                          "refused", fmt_real(a, startTime), HB_TIME_LIMIT, HB_TIME_LIMIT);
        return settle(I, fmi2Error);
    }
    if (stopTimeDefined && !(stopTime >= startTime && stopTime <= HB_TIME_LIMIT)) {
        LOG(I, fmi2Error, "fmi2SetupExperiment: stopTime = %s s is out of range: allowed [startTime = "
                          "%s, %g] s; refused", fmt_real(a, stopTime), fmt_real(b, startTime),
            HB_TIME_LIMIT);
        return settle(I, fmi2Error);
    }
    fmi2Status st = hb_W.SetupExperiment(I->w, toleranceDefined, tolerance, startTime, stopTimeDefined,
                                      stopTime);
    st = slave_status(I, st);
    if (st <= fmi2Warning) {
        I->time = I->last_successful = startTime;
        I->stop_defined = stopTimeDefined != fmi2False;
        I->stop_time = stopTime;
    }
    return record(I, st);
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    BEGIN("fmi2EnterInitializationMode", ST_INSTANTIATED);
    fmi2Status st = hb_W.EnterInitializationMode(I->w);
    if (st <= fmi2Warning) I->state = ST_INIT;
    return settle(I, st);
}

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    BEGIN("fmi2ExitInitializationMode", ST_INIT);
    fmi2Status st = slave_status(I, hb_W.ExitInitializationMode(I->w));
    if (st == fmi2Discard) {
        LOG(I, fmi2Error, "fmi2ExitInitializationMode: the slave discarded the initialisation");
        st = fmi2Error;
    }
    if (st <= fmi2Warning) I->state = I->me ? ST_EVENT : ST_STEP_COMPLETE;
    return record(I, st);
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    BEGIN("fmi2Terminate", ST_STEP_COMPLETE | M_ME);
    fmi2Status st = hb_W.Terminate(I->w);
    if (st <= fmi2Warning) I->state = ST_TERMINATED;
    return settle(I, st);
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    BEGIN("fmi2Reset", M_ANY_LIVE);
    fmi2Status st = hb_W.Reset(I->w);
    if (st <= fmi2Warning) {
        I->state = ST_INSTANTIATED;
        I->time = I->last_successful = 0.0;
        I->stop_defined = 0;
        I->last_status = fmi2OK;
    }
    return settle(I, st);
}

#define GETTER(T, CT, TYPE)                                                                     \
    EXPORT fmi2Status fmi2Get##T(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,    \
                                 CT value[]) {                                                  \
        BEGIN("fmi2Get" #T, M_GET);                                                             \
        if (nvr == 0) return fmi2OK;                                                            \
        if (!check_vrs(I, "fmi2Get" #T, TYPE, vr, nvr, value, 0)) return settle(I, fmi2Error);  \
        return settle(I, hb_W.Get##T(I->w, vr, nvr, value));                                       \
    }
GETTER(Real, fmi2Real, HB_REAL)
/* fmi2GetInteger answers last_status itself: the status of the last call as the host saw it,
 * also when the front refused that call before it reached the slave */
EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                 fmi2Integer value[]) {
    BEGIN("fmi2GetInteger", M_GET);
    if (nvr == 0) return fmi2OK;
    if (!check_vrs(I, "fmi2GetInteger", HB_INTEGER, vr, nvr, value, 0)) return settle(I, fmi2Error);
    fmi2Status st = settle(I, hb_W.GetInteger(I->w, vr, nvr, value));
#if HB_HAS_STATUS_VR
    if (st <= fmi2Warning)
        for (size_t i = 0; i < nvr; i++)
            if (vr[i] == HB_STATUS_VR) value[i] = (fmi2Integer)I->last_status;
#endif
    return st;
}
GETTER(Boolean, fmi2Boolean, HB_BOOLEAN)
GETTER(String, fmi2String, HB_STRING)

#define SETTER(T, CT, TYPE)                                                                     \
    EXPORT fmi2Status fmi2Set##T(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,    \
                                 const CT value[]) {                                            \
        BEGIN("fmi2Set" #T, M_SET);                                                             \
        if (nvr == 0) return fmi2OK;                                                            \
        if (!check_vrs(I, "fmi2Set" #T, TYPE, vr, nvr, value, 1)) return settle(I, fmi2Error);  \
        return record(I, hot_status(I, hb_W.Set##T(I->w, vr, nvr, value)));                        \
    }
SETTER(Real, fmi2Real, HB_REAL)
SETTER(Integer, fmi2Integer, HB_INTEGER)
SETTER(Boolean, fmi2Boolean, HB_BOOLEAN)
SETTER(String, fmi2String, HB_STRING)

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                             fmi2Real communicationStepSize,
                             fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    BEGIN("fmi2DoStep", ST_STEP_COMPLETE);
    char a[32], b[32], c2[32];
    double off = currentCommunicationPoint - I->time, tol = time_tol(I->time);
    if (!(off <= tol && -off <= tol)) {   /* also NaN */
        LOG(I, fmi2Error, "fmi2DoStep: currentCommunicationPoint = %s s is not the current time of "
                          "the FMU, %s s (tolerance %g s); step refused, state unchanged",
            fmt_real(a, currentCommunicationPoint), fmt_real(b, I->time), tol);
        return settle(I, fmi2Error);
    }
    if (communicationStepSize > 0 && isfinite(communicationStepSize) &&
        !(currentCommunicationPoint + communicationStepSize <= HB_TIME_LIMIT)) {
        LOG(I, fmi2Error, "fmi2DoStep: at communication point %s s a step of %s s would end after %g s, "
                          "the end of the FMU's time range; step refused, state unchanged",
            fmt_real(a, currentCommunicationPoint), fmt_real(b, communicationStepSize), HB_TIME_LIMIT);
        return settle(I, fmi2Error);
    }
    if (I->stop_defined && communicationStepSize > 0 &&
        currentCommunicationPoint + communicationStepSize > I->stop_time + time_tol(I->stop_time)) {
        LOG(I, fmi2Error, "fmi2DoStep: at communication point %s s a step of %s s was requested, but "
                          "the stopTime of fmi2SetupExperiment is %s s; step refused, state unchanged",
            fmt_real(a, currentCommunicationPoint), fmt_real(b, communicationStepSize),
            fmt_real(c2, I->stop_time));
        return settle(I, fmi2Error);
    }
    fmi2Status st = hot_status(I, hb_W.DoStep(I->w, currentCommunicationPoint, communicationStepSize,
                                           noSetFMUStatePriorToCurrentPoint));
    if (st <= fmi2Warning) {
        I->time = currentCommunicationPoint + communicationStepSize;
        I->last_successful = I->time;
    } else if (st == fmi2Discard) {
        I->last_successful = I->time;   /* the slave refuses a step as a whole */
    }
    return record(I, st);
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    BEGIN("fmi2CancelStep", 0);   /* fmi2DoStep never returns fmi2Pending */
    return fmi2Error;
}

/* -- FMU state -------------------------------------------------------------------------------- */
/* an FMU whose model description declares no states (canGetAndSetFMUstate, canSerializeFMUstate
 * false) has a slave that cannot save its whole state: every such call is refused */
static int states_supported(hb_inst *I, const char *fn, int supported) {
    if (!supported)
        LOG(I, fmi2Error, "%s: this FMU does not support FMU states (%s is false in its model "
                          "description)", fn, HB_CAN_GET_SET_STATE ? "canSerializeFMUstate"
                                                                   : "canGetAndSetFMUstate");
    return supported;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN("fmi2GetFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2GetFMUstate", HB_CAN_GET_SET_STATE)) return settle(I, fmi2Error);
    if (!FMUstate) {
        LOG(I, fmi2Error, "fmi2GetFMUstate: FMUstate is NULL");
        return settle(I, fmi2Error);
    }
    hb_fmustate *s = (hb_fmustate *)*FMUstate;
    if (s && s->magic != HB_STATE_MAGIC) {
        LOG(I, fmi2Error, "fmi2GetFMUstate: *FMUstate is not a state of this FMU (pass NULL for a "
                          "new one)");
        return settle(I, fmi2Error);
    }
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return settle(I, fmi2Error);
    fmi2FMUstate old = s->inner;   /* a state given back to be overwritten: release its old part */
    s->inner = NULL;
    fmi2Status st = hb_W.GetFMUstate(I->w, &s->inner);
    if (old) hb_W.FreeFMUstate(I->w, &old);
    if (st > fmi2Warning) {
        if (fresh) free(s);
        return settle(I, st);
    }
    s->magic = HB_STATE_MAGIC;
    s->state = I->state;
    s->time = I->time;
    s->last_successful = I->last_successful;
    *FMUstate = s;
    return st;
}

static int check_state(hb_inst *I, const char *fn, fmi2FMUstate FMUstate) {
    const hb_fmustate *s = (const hb_fmustate *)FMUstate;
    if (!s || s->magic != HB_STATE_MAGIC || !s->inner) {
        LOG(I, fmi2Error, "%s: not an FMU state of this FMU%s", fn, s ? "" : " (NULL)");
        return 0;
    }
    return 1;
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    BEGIN("fmi2SetFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2SetFMUstate", HB_CAN_GET_SET_STATE)) return settle(I, fmi2Error);
    if (!check_state(I, "fmi2SetFMUstate", FMUstate)) return settle(I, fmi2Error);
    hb_fmustate *s = (hb_fmustate *)FMUstate;
    fmi2Status st = slave_status(I, hb_W.SetFMUstate(I->w, s->inner));
    if (st >= fmi2Error && I->call_max < fmi2Error)
        LOG(I, st, "fmi2SetFMUstate: the model refused the state; state unchanged");
    if (st <= fmi2Warning) {
        I->state = s->state;
        I->time = s->time;
        I->last_successful = s->last_successful;
    }
    return record(I, st);
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN("fmi2FreeFMUstate", M_ANY_LIVE);
    if (!FMUstate || !*FMUstate) return fmi2OK;
    hb_fmustate *s = (hb_fmustate *)*FMUstate;
    if (s->magic != HB_STATE_MAGIC) {
        LOG(I, fmi2Error, "fmi2FreeFMUstate: not an FMU state of this FMU");
        return settle(I, fmi2Error);
    }
    fmi2Status st = s->inner ? hb_W.FreeFMUstate(I->w, &s->inner) : fmi2OK;
    s->magic = 0;
    free(s);
    *FMUstate = NULL;
    return settle(I, st);
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    BEGIN("fmi2SerializedFMUstateSize", M_ANY_LIVE);
    if (!states_supported(I, "fmi2SerializedFMUstateSize", HB_CAN_SERIALIZE_STATE)) return settle(I, fmi2Error);
    if (!size || !check_state(I, "fmi2SerializedFMUstateSize", FMUstate)) {
        if (!size) LOG(I, fmi2Error, "fmi2SerializedFMUstateSize: size is NULL");
        return settle(I, fmi2Error);
    }
    size_t inner = 0;
    fmi2Status st = hb_W.SerializedFMUstateSize(I->w, ((hb_fmustate *)FMUstate)->inner, &inner);
    if (st > fmi2Warning) return settle(I, st);
    *size = sizeof(hb_serial_header) + inner;
    return st;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                        fmi2Byte serializedState[], size_t size) {
    BEGIN("fmi2SerializeFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2SerializeFMUstate", HB_CAN_SERIALIZE_STATE)) return settle(I, fmi2Error);
    if (!check_state(I, "fmi2SerializeFMUstate", FMUstate)) return settle(I, fmi2Error);
    hb_fmustate *s = (hb_fmustate *)FMUstate;
    size_t inner = 0;
    fmi2Status st = hb_W.SerializedFMUstateSize(I->w, s->inner, &inner);
    if (st > fmi2Warning) return settle(I, st);
    if (!serializedState || size != sizeof(hb_serial_header) + inner) {
        LOG(I, fmi2Error, "fmi2SerializeFMUstate: size = %zu, but the state needs %zu bytes", size,
            sizeof(hb_serial_header) + inner);
        return settle(I, fmi2Error);
    }
    hb_serial_header h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, "HBFMU01", 8);
    snprintf(h.guid, sizeof h.guid, "%s", HB_GUID);
    h.state = s->state;
    h.time = s->time;
    h.last_successful = s->last_successful;
    memcpy(serializedState, &h, sizeof h);
    return settle(I, hb_W.SerializeFMUstate(I->w, s->inner, serializedState + sizeof h, inner));
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                          size_t size, fmi2FMUstate *FMUstate) {
    BEGIN("fmi2DeSerializeFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2DeSerializeFMUstate", HB_CAN_SERIALIZE_STATE)) return settle(I, fmi2Error);
    hb_serial_header h;
    if (!FMUstate || !serializedState || size < sizeof h) {
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: %s", !FMUstate ? "FMUstate is NULL"
                                                         : !serializedState ? "serializedState is NULL"
                                                                            : "too few bytes for a state of this FMU");
        return settle(I, fmi2Error);
    }
    memcpy(&h, serializedState, sizeof h);
    char guid[sizeof h.guid + 1];
    memcpy(guid, h.guid, sizeof h.guid);
    guid[sizeof h.guid] = '\0';
    if (memcmp(h.magic, "HBFMU01", 8) != 0 || strcmp(guid, HB_GUID) != 0 ||
        !(h.state & M_ANY_LIVE) || (h.state & (h.state - 1))) {
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: the bytes are not a serialized state of this "
                          "FMU (GUID %s)", HB_GUID);
        return settle(I, fmi2Error);
    }
    if (!(fabs(h.time) <= HB_TIME_LIMIT) || !(fabs(h.last_successful) <= HB_TIME_LIMIT) ||
        h.last_successful > h.time) {
        char a[32], b[32];
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: the state's header holds the time %s s and the "
                          "last successful time %s s: both must be within the FMU's time range, "
                          "the second <= the first; refused", fmt_real(a, h.time), fmt_real(b, h.last_successful));
        return settle(I, fmi2Error);
    }
    hb_fmustate *s = (hb_fmustate *)*FMUstate;
    if (s && s->magic != HB_STATE_MAGIC) {
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: *FMUstate is not a state of this FMU");
        return settle(I, fmi2Error);
    }
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return settle(I, fmi2Error);
    fmi2FMUstate old = s->inner;
    s->inner = NULL;
    fmi2Status st = slave_status(
        I, hb_W.DeSerializeFMUstate(I->w, serializedState + sizeof h, size - sizeof h, &s->inner));
    if (old) hb_W.FreeFMUstate(I->w, &old);
    I->last_status = st;
    if (st >= fmi2Error && I->call_max < fmi2Error)
        LOG(I, st, "fmi2DeSerializeFMUstate: the state's body (%zu bytes after the header) is not "
                   "a valid state of this model; refused", size - sizeof h);
    if (st > fmi2Warning) {
        if (fresh) free(s);
        return settle(I, st);
    }
    s->magic = HB_STATE_MAGIC;
    s->state = h.state;
    s->time = h.time;
    s->last_successful = h.last_successful;
    *FMUstate = s;
    return st;
}

/* -- not supported (capability flags false) ------------------------------------------------- */
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[], size_t nz,
                                               const fmi2Real dv[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    BEGIN("fmi2GetDirectionalDerivative", M_GET);
    LOG(I, fmi2Error, "fmi2GetDirectionalDerivative is not supported "
                      "(providesDirectionalDerivative = false)");
    return settle(I, fmi2Error);
}

EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    BEGIN("fmi2SetRealInputDerivatives", M_SET);
    LOG(I, fmi2Error, "fmi2SetRealInputDerivatives is not supported (canInterpolateInputs = false)");
    return settle(I, fmi2Error);
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    BEGIN("fmi2GetRealOutputDerivatives", ST_STEP_COMPLETE | ST_TERMINATED | ST_ERROR);
    LOG(I, fmi2Error, "fmi2GetRealOutputDerivatives is not supported "
                      "(maxOutputDerivativeOrder = 0)");
    return settle(I, fmi2Error);
}

/* -- status inquiries ------------------------------------------------------------------------- */
static fmi2Status bad_kind(hb_inst *I, const char *fn, fmi2StatusKind s) {
    LOG(I, fmi2Discard, "%s: status kind %d is not provided (fmi2DoStep never returns fmi2Pending)",
        fn, (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)value;
    BEGIN("fmi2GetStatus", M_STATUS);
    return bad_kind(I, "fmi2GetStatus", s);
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    BEGIN("fmi2GetRealStatus", M_STATUS);
    if (s != fmi2LastSuccessfulTime) return bad_kind(I, "fmi2GetRealStatus", s);
    if (!value) {
        LOG(I, fmi2Error, "fmi2GetRealStatus: value is NULL");
        return settle(I, fmi2Error);
    }
    *value = I->last_successful;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)value;
    BEGIN("fmi2GetIntegerStatus", M_STATUS);
    return bad_kind(I, "fmi2GetIntegerStatus", s);
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    BEGIN("fmi2GetBooleanStatus", M_STATUS);
    if (s != fmi2Terminated) return bad_kind(I, "fmi2GetBooleanStatus", s);
    if (!value) {
        LOG(I, fmi2Error, "fmi2GetBooleanStatus: value is NULL");
        return settle(I, fmi2Error);
    }
    *value = I->state == ST_TERMINATED ? fmi2True : fmi2False;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)value;
    BEGIN("fmi2GetStringStatus", M_STATUS);
    return bad_kind(I, "fmi2GetStringStatus", s);
}

#if HB_HAS_ME
#include "front_me.h"
#endif

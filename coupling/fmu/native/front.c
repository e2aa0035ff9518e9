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
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front_internal.h"

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;   /* backend load (Python start) */

/* ------------------------------------------------------------------------------------------ */
/* FMI 2.0 functions                                                                           */
/* ------------------------------------------------------------------------------------------ */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

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
    return hb_front_step(c, currentCommunicationPoint, communicationStepSize,
                         noSetFMUStatePriorToCurrentPoint, 0);
}

fmi2Status hb_front_step(fmi2Component c, fmi2Real currentCommunicationPoint,
                         fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                         int to_event) {
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
    fmi2Real reached = currentCommunicationPoint + communicationStepSize;
    fmi2Status st = hot_status(I, to_event && hb_W.StepToEvent
                                      ? hb_W.StepToEvent(I->w, currentCommunicationPoint,
                                                         communicationStepSize, &reached)
                                      : hb_W.DoStep(I->w, currentCommunicationPoint,
                                                    communicationStepSize,
                                                    noSetFMUStatePriorToCurrentPoint));
    if (st <= fmi2Warning) {
        I->time = reached;
        I->last_successful = I->time;
    } else if (st == fmi2Discard) {
        I->last_successful = I->time;   /* the slave refuses a step as a whole */
    }
    return record(I, st);
}

fmi2Real hb_front_time(fmi2Component c) {
    return c ? ((hb_inst *)c)->time : NAN;
}

int hb_front_mode(fmi2Component c) {
    switch (c ? ((hb_inst *)c)->state : ST_ERROR) {
    case ST_INSTANTIATED: return HB_FRONT_INSTANTIATED;
    case ST_INIT: return HB_FRONT_INIT;
    case ST_STEP_COMPLETE: return HB_FRONT_STEP;
    case ST_EVENT: return HB_FRONT_EVENT;
    case ST_CONT: return HB_FRONT_CONT;
    case ST_TERMINATED: return HB_FRONT_TERMINATED;
    default: return HB_FRONT_ERROR;
    }
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    BEGIN("fmi2CancelStep", 0);   /* fmi2DoStep never returns fmi2Pending */
    return fmi2Error;
}


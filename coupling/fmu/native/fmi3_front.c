/* The FMI 3.0 front: life cycle, Co-Simulation and Model Exchange (fmi3_front.h says how it sits
 * on the FMI 2.0 front and the model layer).
 *
 * Co-Simulation (FMI 3.0, section 4.2.3; as the Reference-FMUs' fmi3DoStep):
 *   - earlyReturnAllowed: fmi3DoStep stops just after the first event inside the step (impact,
 *     separation, tensile clamp and its release, slip onset, slip going on, stick, bounce and its
 *     end), with earlyReturn and lastSuccessfulTime = the event's time.  An event at
 *     currentCommunicationPoint was reported by the step that ended there and is not returned
 *     again, so time always advances.  Without it, events are handled inside the step.
 *   - eventModeUsed: an early return also sets eventHandlingNeeded; the host enters Event Mode at
 *     lastSuccessfulTime.  The kernels apply an event's reset map at the event instant (it is
 *     part of locating it), so fmi3UpdateDiscreteStates has nothing left to update there.
 *   - neither: the FMI 2.0 step, the same calls and the same bits.
 * Model Exchange: the FMI 2.0 front's Model Exchange, the kernels' event indicators. */
#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_front.h"

static const char *const STATE_NAMES[] = {"Instantiated", "Initialization Mode", "Step Mode",
                                          "Event Mode", "Continuous-Time Mode", "Terminated",
                                          "Error"};

void hb3_log(hb3_inst *I, fmi3Status st, const char *fmt, ...) {
    if (!I || !I->log) return;
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    static const char *const CATS[] = {"logAll", "logStatusWarning", "logStatusDiscard",
                                       "logStatusError", "logStatusFatal"};
    I->log(I->env, st, CATS[st <= fmi3Fatal ? st : fmi3Fatal], buf);
}

/* FMI 2.0 names in the messages of the layers below, as an FMI 3.0 host calls them */
static const char *const FMI3_NAMES[][2] = {
    {"fmi2SetupExperiment", "fmi3EnterInitializationMode"},
    {"fmi2EnterInitializationMode", "fmi3EnterInitializationMode"},
    {"fmi2ExitInitializationMode", "fmi3ExitInitializationMode"},
    {"fmi2Terminate", "fmi3Terminate"}, {"fmi2Reset", "fmi3Reset"}, {"fmi2FreeInstance", "fmi3FreeInstance"},
    {"fmi2GetReal", "fmi3GetFloat64"}, {"fmi2SetReal", "fmi3SetFloat64"},
    {"fmi2GetInteger", "fmi3GetInt32"}, {"fmi2SetInteger", "fmi3SetInt32"},
    {"fmi2GetBoolean", "fmi3GetBoolean"}, {"fmi2SetBoolean", "fmi3SetBoolean"},
    {"fmi2GetString", "fmi3GetString"}, {"fmi2SetString", "fmi3SetString"},
    {"fmi2GetFMUstate", "fmi3GetFMUState"}, {"fmi2SetFMUstate", "fmi3SetFMUState"},
    {"fmi2FreeFMUstate", "fmi3FreeFMUState"}, {"fmi2SerializedFMUstateSize", "fmi3SerializedFMUStateSize"},
    {"fmi2SerializeFMUstate", "fmi3SerializeFMUState"}, {"fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState"},
    {"fmi2GetDirectionalDerivative", "fmi3GetDirectionalDerivative"},
    {"fmi2GetRealOutputDerivatives", "fmi3GetOutputDerivatives"}, {"fmi2DoStep", "fmi3DoStep"},
    {"fmi2SetTime", "fmi3SetTime"}, {"fmi2SetContinuousStates", "fmi3SetContinuousStates"},
    {"fmi2GetContinuousStates", "fmi3GetContinuousStates"},
    {"fmi2GetDerivatives", "fmi3GetContinuousStateDerivatives"},
    {"fmi2GetEventIndicators", "fmi3GetEventIndicators"},
    {"fmi2GetNominalsOfContinuousStates", "fmi3GetNominalsOfContinuousStates"},
    {"fmi2EnterEventMode", "fmi3EnterEventMode"}, {"fmi2NewDiscreteStates", "fmi3UpdateDiscreteStates"},
    {"fmi2EnterContinuousTimeMode", "fmi3EnterContinuousTimeMode"},
    {"fmi2CompletedIntegratorStep", "fmi3CompletedIntegratorStep"},
    {"fmi2OK", "fmi3OK"}, {"fmi2Warning", "fmi3Warning"}, {"fmi2Discard", "fmi3Discard"},
    {"fmi2Error", "fmi3Error"}, {"fmi2Fatal", "fmi3Fatal"},
};

/* ``in`` with each whole FMI 2.0 name of FMI3_NAMES replaced by its FMI 3.0 name, into ``out`` */
static void fmi3_wording(const char *in, char *out, size_t n) {
    size_t o = 0;
    while (*in && o + 1 < n) {
        const char *to = NULL;
        size_t len = 0;
        for (size_t k = 0; strncmp(in, "fmi2", 4) == 0 && k < sizeof FMI3_NAMES / sizeof FMI3_NAMES[0]; k++) {
            size_t l = strlen(FMI3_NAMES[k][0]);
            if (strncmp(in, FMI3_NAMES[k][0], l) == 0 && !isalnum((unsigned char)in[l])) {
                to = FMI3_NAMES[k][1];
                len = l;
                break;
            }
        }
        if (!to) {
            out[o++] = *in++;
            continue;
        }
        for (; *to && o + 1 < n; to++) out[o++] = *to;
        in += len;
    }
    out[o] = '\0';
}

/* the FMI 2.0 front's messages to the host: its format expanded (it escapes '%' for a printf-like
 * logger, which FMI 3.0's is not), in FMI 3.0's names */
static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat,
                    fmi2String message, ...) {
    (void)name;
    hb3_inst *I = env;
    if (!I || !I->log || !message) return;
    char buf[2048], worded[2048];
    va_list ap;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    fmi3_wording(buf, worded, sizeof worded);
    I->log(I->env, st <= fmi2Fatal ? (fmi3Status)st : fmi3Error, cat ? cat : "logAll", worded);
}

int hb3_allowed(hb3_inst *I, unsigned mask, const char *fn) {
    if (!I) return 0;
    if (HB3_M(I->state) & mask) return 1;
    hb3_log(I, fmi3Error, "%s: not allowed in %s", fn, STATE_NAMES[I->state]);
    if (I->state != F3_TERMINATED) I->state = F3_ERROR;
    return 0;
}

fmi3Status hb3_status(hb3_inst *I, fmi2Status st) {
    if (st >= fmi2Error && st != fmi2Pending) I->state = F3_ERROR;
    return st == fmi2Pending ? fmi3Error : (fmi3Status)st;
}

double hb3_time(const hb3_inst *I) {
    return hb_front_time(I->c2);
}

/* ------------------------------------------------------------------------------------------ */
/* Life cycle                                                                                  */
/* ------------------------------------------------------------------------------------------ */
FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

static hb3_inst *instantiate(fmi3String name, fmi3String token, fmi3String resources,
                             fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env,
                             fmi3LogMessageCallback log, int me) {
    hb3_inst *I = calloc(1, sizeof *I);
    if (!I) return NULL;
    I->env = env;
    I->log = log;
    I->me = me;
    I->cb = (fmi2CallbackFunctions){logger2, calloc, free, NULL, I};
    if (!resources) {
        hb3_log(I, fmi3Error, "fmi3Instantiate%s: resourcePath is NULL; this FMU needs its "
                "resources directory", me ? "ModelExchange" : "CoSimulation");
        free(I);
        return NULL;
    }
    I->c2 = fmi2Instantiate(name, me ? fmi2ModelExchange : fmi2CoSimulation, token, resources,
                            &I->cb, visible, logging);
    if (!I->c2) {
        free(I);
        return NULL;
    }
    I->state = F3_INSTANTIATED;
    return I;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage) {
    if (!HB3_HAS_ME) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3InstantiateModelExchange: this FMU has no Model Exchange interface");
        return NULL;
    }
    return instantiate(instanceName, instantiationToken, resourcePath, visible, loggingOn,
                       instanceEnvironment, logMessage, 1);
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)requiredIntermediateVariables, (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    hb3_inst *I = instantiate(instanceName, instantiationToken, resourcePath, visible, loggingOn,
                              instanceEnvironment, logMessage, 0);
    if (I) {
        I->event_mode_used = eventModeUsed != 0;
        I->early_return_allowed = earlyReturnAllowed != 0;
    }
    return I;
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU has no Scheduled Execution interface");
    return NULL;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) {
    hb3_inst *I = instance;
    if (!I) return;
    fmi2FreeInstance(I->c2);
    free(I);
}

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                                           size_t nCategories, const fmi3String categories[]) {
    BEGIN3("fmi3SetDebugLogging", HB3_M_LIVE);
    return hb3_status(I, fmi2SetDebugLogging(I->c2, loggingOn, nCategories, categories));
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                                   fmi3Float64 tolerance, fmi3Float64 startTime,
                                                   fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    BEGIN3("fmi3EnterInitializationMode", HB3_M(F3_INSTANTIATED));
    fmi3Status st = hb3_status(I, fmi2SetupExperiment(I->c2, toleranceDefined, tolerance, startTime,
                                                      stopTimeDefined, stopTime));
    if (st > fmi3Warning) return st;
    fmi3Status st2 = hb3_status(I, fmi2EnterInitializationMode(I->c2));
    if (st2 <= fmi3Warning) I->state = F3_INIT;
    return st2 > st ? st2 : st;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    BEGIN3("fmi3ExitInitializationMode", HB3_M(F3_INIT));
    fmi3Status st = hb3_status(I, fmi2ExitInitializationMode(I->c2));
    if (st <= fmi3Warning) I->state = I->me || I->event_mode_used ? F3_EVENT : F3_STEP;
    return st;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    BEGIN3("fmi3EnterEventMode", I->me ? HB3_M(F3_EVENT) | HB3_M(F3_CONT) : HB3_M(F3_STEP));
    if (!I->me && !I->event_mode_used) {
        hb3_log(I, fmi3Error, "fmi3EnterEventMode: the instance was created with eventModeUsed = false");
        I->state = F3_ERROR;
        return fmi3Error;
    }
    fmi3Status st = I->me ? hb3_status(I, HB3_ME(fmi2EnterEventMode(I->c2))) : fmi3OK;
    if (st <= fmi3Warning) I->state = F3_EVENT;
    return st;
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
    BEGIN3("fmi3Terminate", HB3_M(F3_STEP) | HB3_M(F3_EVENT) | HB3_M(F3_CONT) | HB3_M(F3_ERROR));
    fmi3Status st = hb3_status(I, fmi2Terminate(I->c2));
    if (st <= fmi3Warning) I->state = F3_TERMINATED;
    return st;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    BEGIN3("fmi3Reset", HB3_M_LIVE);
    fmi3Status st = hb3_status(I, fmi2Reset(I->c2));
    if (st <= fmi3Warning) I->state = F3_INSTANTIATED;
    return st;
}

/* ------------------------------------------------------------------------------------------ */
/* Co-Simulation                                                                                */
/* ------------------------------------------------------------------------------------------ */
FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize,
                                  fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                                  fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    BEGIN3("fmi3DoStep", I->me ? 0u : HB3_M(F3_STEP));
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        hb3_log(I, fmi3Error, "fmi3DoStep: eventHandlingNeeded, terminateSimulation, earlyReturn or "
                "lastSuccessfulTime is NULL");
        I->state = F3_ERROR;
        return fmi3Error;
    }
    fmi2Status st = hb_front_step(I->c2, currentCommunicationPoint, communicationStepSize,
                                  noSetFMUStatePriorToCurrentPoint, I->early_return_allowed);
    double reached = hb_front_time(I->c2);
    *earlyReturn = st <= fmi2Warning && I->early_return_allowed &&
                   reached < currentCommunicationPoint + communicationStepSize;
    *eventHandlingNeeded = *earlyReturn && I->event_mode_used;
    *terminateSimulation = fmi3False;
    *lastSuccessfulTime = reached;
    return hb3_status(I, st);
}

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    BEGIN3("fmi3EnterStepMode", I->me ? 0u : HB3_M(F3_EVENT));
    I->state = F3_STEP;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                                fmi3Boolean *terminateSimulation,
                                                fmi3Boolean *nominalsOfContinuousStatesChanged,
                                                fmi3Boolean *valuesOfContinuousStatesChanged,
                                                fmi3Boolean *nextEventTimeDefined,
                                                fmi3Float64 *nextEventTime) {
    BEGIN3("fmi3UpdateDiscreteStates", HB3_M(F3_EVENT));
    if (!discreteStatesNeedUpdate || !terminateSimulation || !nominalsOfContinuousStatesChanged ||
        !valuesOfContinuousStatesChanged || !nextEventTimeDefined || !nextEventTime) {
        hb3_log(I, fmi3Error, "fmi3UpdateDiscreteStates: an output argument is NULL");
        I->state = F3_ERROR;
        return fmi3Error;
    }
    fmi2EventInfo info = {0, 0, 0, 0, 0, 0.0};
    fmi3Status st = I->me ? hb3_status(I, HB3_ME(fmi2NewDiscreteStates(I->c2, &info))) : fmi3OK;
    *discreteStatesNeedUpdate = info.newDiscreteStatesNeeded != 0;
    *terminateSimulation = info.terminateSimulation != 0;
    *nominalsOfContinuousStatesChanged = info.nominalsOfContinuousStatesChanged != 0;
    *valuesOfContinuousStatesChanged = info.valuesOfContinuousStatesChanged != 0;
    *nextEventTimeDefined = info.nextEventTimeDefined != 0;
    *nextEventTime = info.nextEventTime;
    return st;
}

/* ------------------------------------------------------------------------------------------ */
/* Model Exchange                                                                               */
/* ------------------------------------------------------------------------------------------ */
#define ME_ONLY(fn, mask) BEGIN3(fn, I->me ? (mask) : 0u)

FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    ME_ONLY("fmi3EnterContinuousTimeMode", HB3_M(F3_EVENT));
    fmi3Status st = hb3_status(I, HB3_ME(fmi2EnterContinuousTimeMode(I->c2)));
    if (st <= fmi3Warning) I->state = F3_CONT;
    return st;
}

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                                   fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi3Boolean *enterEventMode,
                                                   fmi3Boolean *terminateSimulation) {
    ME_ONLY("fmi3CompletedIntegratorStep", HB3_M(F3_CONT));
    fmi2Boolean ev = 0, term = 0;
    fmi3Status st = hb3_status(I, HB3_ME(fmi2CompletedIntegratorStep(
                                      I->c2, noSetFMUStatePriorToCurrentPoint,
                                      enterEventMode ? &ev : NULL, terminateSimulation ? &term : NULL)));
    if (enterEventMode) *enterEventMode = ev != 0;
    if (terminateSimulation) *terminateSimulation = term != 0;
    return st;
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    ME_ONLY("fmi3SetTime", HB3_M(F3_EVENT) | HB3_M(F3_CONT));
    return hb3_status(I, HB3_ME(fmi2SetTime(I->c2, time)));
}

FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx) {
    ME_ONLY("fmi3SetContinuousStates", HB3_M(F3_CONT));
    return hb3_status(I, HB3_ME(fmi2SetContinuousStates(I->c2, x, nx)));
}

#define ME_VALUES (HB3_M(F3_INIT) | HB3_M(F3_EVENT) | HB3_M(F3_CONT) | HB3_M(F3_TERMINATED) | \
                   HB3_M(F3_ERROR))
#define ME_GETTER(NAME3, NAME2, MASK)                                                        \
    FMI3_Export fmi3Status NAME3(fmi3Instance instance, fmi3Float64 v[], size_t n) {          \
        ME_ONLY(#NAME3, MASK);                                                               \
        return hb3_status(I, HB3_ME(NAME2(I->c2, v, n)));                                            \
    }
ME_GETTER(fmi3GetContinuousStateDerivatives, fmi2GetDerivatives, ME_VALUES)
ME_GETTER(fmi3GetEventIndicators, fmi2GetEventIndicators, ME_VALUES)
ME_GETTER(fmi3GetContinuousStates, fmi2GetContinuousStates, ME_VALUES)
ME_GETTER(fmi3GetNominalsOfContinuousStates, fmi2GetNominalsOfContinuousStates,
          HB3_M(F3_INSTANTIATED) | ME_VALUES)

#define ME_COUNT(NAME, N)                                                                    \
    FMI3_Export fmi3Status NAME(fmi3Instance instance, size_t *n) {                          \
        BEGIN3(#NAME, HB3_M_LIVE);                                                           \
        if (!n) {                                                                            \
            hb3_log(I, fmi3Error, #NAME ": the output argument is NULL");                    \
            return fmi3Error;                                                                \
        }                                                                                    \
        *n = (N);                                                                            \
        return fmi3OK;                                                                       \
    }
ME_COUNT(fmi3GetNumberOfEventIndicators, HB3_NZ)
ME_COUNT(fmi3GetNumberOfContinuousStates, HB3_NX)

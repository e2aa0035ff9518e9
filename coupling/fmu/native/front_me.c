/* Model Exchange functions of the front (compiled when the model description
 * has a <ModelExchange> element, HB_HAS_ME: the native flavour).  Same rules as the co-simulation
 * functions: the FMI 2.0 state machine (Event Mode, Continuous-Time Mode), NULL and size checks,
 * errors logged, the backend's status recorded. */
#include "front_internal.h"

#if HB_HAS_ME

#define M_ME_VALUES (ST_INIT | ST_EVENT | ST_CONT | ST_TERMINATED | ST_ERROR)

/* BEGIN of a Model Exchange function: a Co-Simulation instance shares the Initialization,
 * Terminated and Error states with Model Exchange, but none of these functions is its to call */
#define BEGIN_ME(fn, mask)                                                                   \
    BEGIN(fn, mask);                                                                         \
    if (!I->me) {                                                                            \
        LOG(I, fmi2Error, "%s: a Model Exchange function, but this instance was instantiated " \
                          "for Co-Simulation; refused", fn);                                   \
        return settle(I, fmi2Error);                                                         \
    }

EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) {
    BEGIN_ME("fmi2EnterEventMode", ST_EVENT | ST_CONT);
    fmi2Status st = hb_W.EnterEventMode(I->w);
    if (st <= fmi2Warning) I->state = ST_EVENT;
    return record(I, st);
}

EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    BEGIN_ME("fmi2NewDiscreteStates", ST_EVENT);
    return record(I, hb_W.NewDiscreteStates(I->w, eventInfo));
}

EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    BEGIN_ME("fmi2EnterContinuousTimeMode", ST_EVENT);
    fmi2Status st = hb_W.EnterContinuousTimeMode(I->w);
    if (st <= fmi2Warning) I->state = ST_CONT;
    return record(I, st);
}

EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c,
                                              fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                              fmi2Boolean *enterEventMode,
                                              fmi2Boolean *terminateSimulation) {
    BEGIN_ME("fmi2CompletedIntegratorStep", ST_CONT);
    if (!enterEventMode || !terminateSimulation) {
        LOG(I, fmi2Error, "fmi2CompletedIntegratorStep: enterEventMode or terminateSimulation is NULL");
        return settle(I, fmi2Error);
    }
    return record(I, hb_W.CompletedIntegratorStep(I->w, noSetFMUStatePriorToCurrentPoint,
                                                  enterEventMode, terminateSimulation));
}

EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    BEGIN_ME("fmi2SetTime", ST_EVENT | ST_CONT);
    fmi2Status st = hb_W.SetTime(I->w, time);
    if (st <= fmi2Warning) I->time = time;   /* the instance's time, kept in its FMU states */
    return record(I, st);
}

EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    BEGIN_ME("fmi2SetContinuousStates", ST_CONT);
    return record(I, hb_W.SetContinuousStates(I->w, x, nx));
}

#define ME_GETTER(NAME, MASK)                                                               \
    EXPORT fmi2Status fmi2##NAME(fmi2Component c, fmi2Real v[], size_t n) {                 \
        BEGIN_ME("fmi2" #NAME, MASK);                                                          \
        return record(I, hb_W.NAME(I->w, v, n));                                           \
    }
ME_GETTER(GetDerivatives, M_ME_VALUES)
ME_GETTER(GetEventIndicators, M_ME_VALUES)
ME_GETTER(GetContinuousStates, M_ME_VALUES)
ME_GETTER(GetNominalsOfContinuousStates, ST_INSTANTIATED | M_ME_VALUES)

#endif

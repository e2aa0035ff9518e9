/* FMI 2.0 binary interface used by the native front (types, enums, callback struct and the
 * function-pointer types of the functions it forwards).  Written from the FMI 2.0.4 standard's
 * definitions; the layout is what every FMI 2.0 host and FMU on Linux x86-64 shares. */
#ifndef HAMMERBIT_FMI2_ABI_H
#define HAMMERBIT_FMI2_ABI_H

#include <stddef.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;

#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

/* function-pointer types of the wrapped (pythonfmu) library */
typedef fmi2Component (*fmi2InstantiateFn)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                           const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef void (*fmi2FreeInstanceFn)(fmi2Component);
typedef fmi2Status (*fmi2SetupExperimentFn)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real,
                                            fmi2Boolean, fmi2Real);
typedef fmi2Status (*fmi2ComponentFn)(fmi2Component);
typedef fmi2Status (*fmi2GetRealFn)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
typedef fmi2Status (*fmi2GetIntegerFn)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Integer *);
typedef fmi2Status (*fmi2GetBooleanFn)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Boolean *);
typedef fmi2Status (*fmi2GetStringFn)(fmi2Component, const fmi2ValueReference *, size_t, fmi2String *);
typedef fmi2Status (*fmi2SetRealFn)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *);
typedef fmi2Status (*fmi2SetIntegerFn)(fmi2Component, const fmi2ValueReference *, size_t,
                                       const fmi2Integer *);
typedef fmi2Status (*fmi2SetBooleanFn)(fmi2Component, const fmi2ValueReference *, size_t,
                                       const fmi2Boolean *);
typedef fmi2Status (*fmi2SetStringFn)(fmi2Component, const fmi2ValueReference *, size_t,
                                      const fmi2String *);
typedef fmi2Status (*fmi2GetFMUstateFn)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*fmi2SetFMUstateFn)(fmi2Component, fmi2FMUstate);
typedef fmi2Status (*fmi2FreeFMUstateFn)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*fmi2SerializedFMUstateSizeFn)(fmi2Component, fmi2FMUstate, size_t *);
typedef fmi2Status (*fmi2SerializeFMUstateFn)(fmi2Component, fmi2FMUstate, fmi2Byte *, size_t);
typedef fmi2Status (*fmi2DeSerializeFMUstateFn)(fmi2Component, const fmi2Byte *, size_t,
                                                fmi2FMUstate *);
typedef fmi2Status (*fmi2DoStepFn)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);

/* Model Exchange (the native backend only) */
typedef fmi2Status (*fmi2NewDiscreteStatesFn)(fmi2Component, fmi2EventInfo *);
typedef fmi2Status (*fmi2SetTimeFn)(fmi2Component, fmi2Real);
typedef fmi2Status (*fmi2StatesFn)(fmi2Component, fmi2Real *, size_t);
typedef fmi2Status (*fmi2SetStatesFn)(fmi2Component, const fmi2Real *, size_t);
typedef fmi2Status (*fmi2CompletedIntegratorStepFn)(fmi2Component, fmi2Boolean, fmi2Boolean *,
                                                    fmi2Boolean *);

#endif

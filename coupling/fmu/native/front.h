/* Internal interface between the FMI 2.0 front and what it calls (not installed with the FMU).
 *
 * The front (front_internal.h: what its parts share):
 *   front.c              life cycle, fmi2Get* and fmi2Set*, fmi2DoStep
 *   front_core.c         state machine, checks of value references, status mapping, logging
 *   front_state.c        FMU states (the front's header around the model's state)
 *   front_inquiry.c      status inquiries, the functions the capability flags leave out
 *   front_me.c           Model Exchange (when the model description has it)
 *   resource_uri.c       fmuResourceLocation -> directory path
 * Behind it, one backend fills the table hb_W:
 *   pythonfmu_wrapper.c  the Python flavour: pythonfmu's export library, loaded, its exit order
 *                        fixed (python_embed.c: Python in the process, found, loaded, checked)
 *   model_backend.c      the native flavour: the linked model fills it (model.h)
 */
#ifndef HAMMERBIT_FRONT_H
#define HAMMERBIT_FRONT_H

#include <limits.h>   /* and with it glibc's __GLIBC__ */
#include <stddef.h>

#include "fmi2_abi.h"

/* the FMI 3.0 binary compiles this front with EXPORT defined empty: its fmi2* functions are then
 * internal, called by the FMI 3.0 front (fmi3_front.h) and not exported */
#ifndef EXPORT
#if defined(_WIN32)
#define EXPORT __declspec(dllexport)
#else
#define EXPORT __attribute__((visibility("default")))
#endif
#endif

/* The dl* functions bound to their first version: a front built with glibc >= 2.34 (where they
 * moved into libc) still loads with an older glibc (where libdl holds them). */
#if defined(__GLIBC__) && defined(__x86_64__)
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");
#endif

/* The model backend behind the front: fills hb_W (below) with the model's functions; 1, or 0 with
 * the reason in err.  pythonfmu_wrapper.c: Python in the process and pythonfmu's library loaded
 * (the Python flavour); model_backend.c: the linked native model (model.h).
 * Not thread-safe: the caller serialises. */
int hb_backend_load(char *err, size_t n);

/* python_embed.c ------------------------------------------------------------------------------
 * Python in this process with the space-separated `modules` installed; 1, or 0 with the reason
 * in err.  A Python host's interpreter is used as it is; otherwise $HAMMERBIT_PYTHON, else
 * python3 on PATH, is asked about itself and its libpython is loaded and initialised.
 * Not thread-safe: the caller serialises. */
int hb_ensure_python(const char *modules, char *err, size_t n);
/* At exit: flush Python's output if this front initialised the interpreter. */
void hb_python_at_exit(void);

/* pythonfmu_wrapper.c -------------------------------------------------------------------------- */
typedef struct {
    void *h;
    fmi2InstantiateFn Instantiate;
    fmi2FreeInstanceFn FreeInstance;
    fmi2SetupExperimentFn SetupExperiment;
    fmi2ComponentFn EnterInitializationMode, ExitInitializationMode, Terminate, Reset;
    fmi2GetRealFn GetReal;
    fmi2GetIntegerFn GetInteger;
    fmi2GetBooleanFn GetBoolean;
    fmi2GetStringFn GetString;
    fmi2SetRealFn SetReal;
    fmi2SetIntegerFn SetInteger;
    fmi2SetBooleanFn SetBoolean;
    fmi2SetStringFn SetString;
    fmi2GetFMUstateFn GetFMUstate;
    fmi2SetFMUstateFn SetFMUstate;
    fmi2FreeFMUstateFn FreeFMUstate;
    fmi2SerializedFMUstateSizeFn SerializedFMUstateSize;
    fmi2SerializeFMUstateFn SerializeFMUstate;
    fmi2DeSerializeFMUstateFn DeSerializeFMUstate;
    fmi2DoStepFn DoStep;
    /* the step from t towards t + h, stopped just after the first event inside it (the event's
     * reset applied); *reached: the event time, or t + h (NULL in the Python flavour) */
    fmi2Status (*StepToEvent)(fmi2Component, fmi2Real t, fmi2Real h, fmi2Real *reached);
    void (*finalize)(void);
    /* fmi2GetRealOutputDerivatives and fmi2SetRealInputDerivatives of a model that declares them
     * (maxOutputDerivativeOrder > 0, canInterpolateInputs); NULL: the front refuses the call */
    fmi2Status (*GetRealOutputDerivatives)(fmi2Component, const fmi2ValueReference[], size_t,
                                           const fmi2Integer[], fmi2Real[]);
    fmi2Status (*SetRealInputDerivatives)(fmi2Component, const fmi2ValueReference[], size_t,
                                          const fmi2Integer[], const fmi2Real[]);
    /* Model Exchange (NULL in the Python flavour) */
    fmi2ComponentFn EnterEventMode, EnterContinuousTimeMode;
    fmi2NewDiscreteStatesFn NewDiscreteStates;
    fmi2SetTimeFn SetTime;
    fmi2SetStatesFn SetContinuousStates;
    fmi2StatesFn GetDerivatives, GetEventIndicators, GetContinuousStates,
        GetNominalsOfContinuousStates;
    fmi2CompletedIntegratorStepFn CompletedIntegratorStep;
} hb_wrapper;

/* front.c, for the FMI 3.0 front (fmi3_front.h) ------------------------------------------------
 * fmi2DoStep; to_event: stop just after the first event inside the step (StepToEvent of the
 * model), the instance's time then the event's (fmi2GetRealStatus(fmi2LastSuccessfulTime)) */
fmi2Status hb_front_step(fmi2Component c, fmi2Real currentCommunicationPoint,
                         fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                         int to_event);
/* the current time of an instance [s]: its communication point, or in Model Exchange the time of
 * fmi2SetTime (NaN for NULL) */
fmi2Real hb_front_time(fmi2Component c);
/* the FMI 2.0 front's state of an instance (HB_FRONT_ERROR for NULL or Fatal) */
enum { HB_FRONT_INSTANTIATED, HB_FRONT_INIT, HB_FRONT_STEP, HB_FRONT_EVENT, HB_FRONT_CONT, HB_FRONT_TERMINATED,
       HB_FRONT_ERROR };
int hb_front_mode(fmi2Component c);

/* the loaded library (all NULL before hb_load_wrapper succeeded) */
extern hb_wrapper hb_W;
/* Load `file` from the directory of this library (once); 1, or 0 with the reason in err.
 * Not thread-safe: the caller serialises. */
int hb_load_wrapper(const char *file, char *err, size_t n);

/* real_repr.c: v as Python's repr() writes it (shortest round-trip digits, exponent form below
 * 1e-4 and from 1e16 on, ".0" on integral values) */
void hb_repr(double v, char *out, size_t n);

/* resource_uri.c ------------------------------------------------------------------------------
 * file:/x, file://localhost/x, file:///x (percent-decoded) or an absolute path -> an existing
 * directory path in out; 1, or 0 with the reason in err. */
int hb_uri_to_path(const char *uri, char *out, size_t n, char *err, size_t en);

#endif

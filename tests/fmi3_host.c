/* A plain native FMI 3.0 Co-Simulation host for the tests: load the library, instantiate, step
 * at a fixed communication step, print Float64 outputs, terminate, free.  Built against the
 * standard FMI 3.0 headers (fmpy's copy), not against anything of the FMU; one source for Linux
 * x86-64, Linux AArch64 (cross-built, run under qemu-aarch64) and Windows (mingw-w64, wine).
 *
 *   fmi3_host LIBRARY RESOURCE_DIR TOKEN STEPS H VR[,VR...] [early=0|1]
 *
 * stdout: "log <status> <message>" per message, "value <%.17g>" per VR after the last step,
 * "returns <n>" (early returns taken).  Exit codes: 0 ok, 2 load, 3 missing symbol,
 * 10 instantiation failed, 11 a call failed. */
#if defined(_WIN32)
#include <windows.h>
#define LOAD(f) ((void *)LoadLibraryA(f))
#define SYM(h, n) ((void *)GetProcAddress((HMODULE)(h), (n)))
#else
#include <dlfcn.h>
#define LOAD(f) dlopen((f), RTLD_NOW | RTLD_LOCAL)
#define SYM(h, n) dlsym((h), (n))
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3FunctionTypes.h"

static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                        fmi3String message) {
    (void)env, (void)category;
    printf("log %d %s\n", (int)status, message);
}

#define GET(T, name)                                               \
    T *name = (T *)SYM(lib, #name);                                \
    if (!name) {                                                   \
        fprintf(stderr, "missing symbol %s\n", #name);             \
        return 3;                                                  \
    }
#define CALL(x)                                                    \
    if ((x) > fmi3Warning) {                                       \
        fprintf(stderr, "call failed: %s\n", #x);                  \
        return 11;                                                 \
    }

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: fmi3_host LIBRARY RESOURCE_DIR TOKEN STEPS H VR[,VR...] [early=0|1]\n");
        return 1;
    }
    void *lib = LOAD(argv[1]);
    if (!lib) return 2;
    GET(fmi3InstantiateCoSimulationTYPE, fmi3InstantiateCoSimulation)
    GET(fmi3EnterInitializationModeTYPE, fmi3EnterInitializationMode)
    GET(fmi3ExitInitializationModeTYPE, fmi3ExitInitializationMode)
    GET(fmi3DoStepTYPE, fmi3DoStep)
    GET(fmi3GetFloat64TYPE, fmi3GetFloat64)
    GET(fmi3TerminateTYPE, fmi3Terminate)
    GET(fmi3FreeInstanceTYPE, fmi3FreeInstance)
    long steps = atol(argv[4]);
    double h = atof(argv[5]);
    int early = argc > 7 && strcmp(argv[7], "early=1") == 0;
    fmi3ValueReference vr[64];
    size_t nvr = 0;
    for (char *p = argv[6]; *p && nvr < 64;) {
        vr[nvr++] = (fmi3ValueReference)strtoul(p, &p, 10);
        if (*p == ',') p++;
    }
    fmi3Instance inst = fmi3InstantiateCoSimulation("host", argv[3], argv[2], fmi3False, fmi3False,
                                                    fmi3False, early, NULL, 0, NULL, log_message, NULL);
    if (!inst) return 10;
    CALL(fmi3EnterInitializationMode(inst, fmi3False, 0.0, 0.0, fmi3False, 0.0))
    CALL(fmi3ExitInitializationMode(inst))
    double t = 0.0;
    long returns = 0;
    for (long k = 0; k < steps; k++) {
        double target = (double)(k + 1) * h;
        while (t < target) {
            fmi3Boolean need, term, ret;
            double last;
            CALL(fmi3DoStep(inst, t, target - t, fmi3True, &need, &term, &ret, &last))
            returns += ret;
            t = last;
        }
    }
    double v[64];
    CALL(fmi3GetFloat64(inst, vr, nvr, v, nvr))
    for (size_t i = 0; i < nvr; i++) printf("value %.17g\n", v[i]);
    printf("returns %ld\n", returns);
    CALL(fmi3Terminate(inst))
    fmi3FreeInstance(inst);
    return 0;
}

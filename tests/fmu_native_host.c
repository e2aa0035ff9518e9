/* A plain native FMI 2.0 co-simulation host for the tests: dlopen, instantiate, step, read one
 * Real output, terminate, free, exit.  Built against the standard FMI 2.0 headers (fmpy's copy),
 * not against anything of the FMU.
 *
 *   fmu_native_host SO URI GUID [type=1] [steps=10000] [h=1e-3] [out=VR] [logging=0]
 *
 * stdout: "log <status> <category> <message>" per logger call, "value <%.17g>" at the end.
 * Exit codes: 0 ok, 2 dlopen, 3 missing symbol, 10 fmi2Instantiate returned NULL, 11 a call
 * failed. */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env, (void)name;
    va_list ap;
    va_start(ap, message);
    printf("log %d %s ", (int)status, category ? category : "-");
    vprintf(message, ap);
    printf("\n");
    va_end(ap);
    fflush(stdout);
}

static const char *opt(int argc, char **argv, const char *key, const char *dflt) {
    size_t n = strlen(key);
    for (int i = 4; i < argc; i++)
        if (strncmp(argv[i], key, n) == 0 && argv[i][n] == '=') return argv[i] + n + 1;
    return dflt;
}

#define LOAD(T, var)                                                   \
    fmi2##T##TYPE *var = (fmi2##T##TYPE *)dlsym(h, "fmi2" #T);         \
    if (!var) {                                                        \
        printf("missing fmi2%s\n", #T);                                \
        return 3;                                                      \
    }
#define CHECK(call)                                                    \
    do {                                                               \
        fmi2Status s_ = (call);                                        \
        if (s_ > fmi2Warning) {                                        \
            printf("failed %s -> %d\n", #call, (int)s_);               \
            return 11;                                                 \
        }                                                              \
    } while (0)

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: %s SO URI GUID [key=value ...]\n", argv[0]);
        return 1;
    }
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        printf("dlopen %s\n", dlerror());
        return 2;
    }
    LOAD(Instantiate, instantiate)
    LOAD(SetupExperiment, setup)
    LOAD(EnterInitializationMode, enter)
    LOAD(ExitInitializationMode, exit_init)
    LOAD(DoStep, do_step)
    LOAD(GetReal, get_real)
    LOAD(Terminate, terminate)
    LOAD(FreeInstance, free_instance)

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    int type = atoi(opt(argc, argv, "type", "1"));
    int logging = atoi(opt(argc, argv, "logging", "0"));
    fmi2Component c = instantiate("host", (fmi2Type)type, argv[3], argv[2], &cb, fmi2False,
                                  logging ? fmi2True : fmi2False);
    if (!c) {
        printf("instantiate NULL\n");
        return 10;
    }
    long steps = atol(opt(argc, argv, "steps", "10000"));
    double hstep = atof(opt(argc, argv, "h", "1e-3"));
    fmi2ValueReference vr = (fmi2ValueReference)atol(opt(argc, argv, "out", "0"));
    CHECK(setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    CHECK(enter(c));
    CHECK(exit_init(c));
    for (long i = 0; i < steps; i++) CHECK(do_step(c, (double)i * hstep, hstep, fmi2True));
    double value = 0.0;
    CHECK(get_real(c, &vr, 1, &value));
    printf("value %.17g\n", value);
    CHECK(terminate(c));
    free_instance(c);
    return 0;
}

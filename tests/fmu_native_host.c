/* A plain native FMI 2.0 co-simulation host for the tests: dlopen, instantiate, step, read one
 * Real output, terminate, free, exit.  Built against the standard FMI 2.0 headers (fmpy's copy),
 * not against anything of the FMU.
 *
 *   fmu_native_host SO URI GUID [type=1] [steps=10000] [h=1e-3] [out=VR[,VR...]] [logging=0] [threads=1]
 *
 * Builds for Linux (dlopen) and, cross-compiled with mingw-w64, for Windows (LoadLibrary).
 *
 * drive=VRX:VRV:OFFSET:AMP:FREQ sets two Real inputs before every step: a periodic parabola
 * x = OFFSET + 4 AMP s (1 - s), s = frac(FREQ t), and its rate v = 4 AMP FREQ (1 - 2 s) (no libm:
 * any host computes the same bits).  int=VR:VALUE sets an Integer in Initialization Mode.
 *
 * threads=N runs N instances at once, each in its own thread, from instantiation to the end.
 * uri1=URI [uri2=URI ...] run one more instance after the first, one after the other, each with
 * its own resource URI (one process for several URI forms); each prints "result <i> <rc>", and
 * the exit code is the first non-zero one.
 * stdout: "log <status> <category> <message>" per logger call, "value <%.17g>" per instance.
 * Exit codes: 0 ok, 2 dlopen, 3 missing symbol, 10 fmi2Instantiate returned NULL, 11 a call
 * failed. */
#if defined(_WIN32)
#include <stdio.h>
#include <windows.h>
/* the few dl* calls of this host on the Windows API (cross-built with mingw-w64, run under wine) */
#define RTLD_NOW 0
#define RTLD_LOCAL 0
static void *dlopen(const char *file, int mode) {
    (void)mode;
    return (void *)LoadLibraryA(file);
}
static void *dlsym(void *h, const char *name) { return (void *)GetProcAddress((HMODULE)h, name); }
static const char *dlerror(void) {
    static char buf[64];
    snprintf(buf, sizeof buf, "LoadLibrary error %lu", (unsigned long)GetLastError());
    return buf;
}
#else
#include <dlfcn.h>
#endif
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
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

static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2DoStepTYPE *do_step;
    fmi2GetRealTYPE *get_real;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *free_instance;
} F;

static int g_argc;
static char **g_argv;
static pthread_mutex_t g_out = PTHREAD_MUTEX_INITIALIZER;

#define CHECK(call)                                                    \
    do {                                                               \
        fmi2Status s_ = (call);                                        \
        if (s_ > fmi2Warning) {                                        \
            printf("failed %s -> %d\n", #call, (int)s_);               \
            return 11;                                                 \
        }                                                              \
    } while (0)

/* one instance from fmi2Instantiate to fmi2FreeInstance; the exit code */
static int run(const char *name, const char *uri) {
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    int type = atoi(opt(g_argc, g_argv, "type", "1"));
    int logging = atoi(opt(g_argc, g_argv, "logging", "0"));
    fmi2Component c = F.instantiate(name, (fmi2Type)type, g_argv[3], uri, &cb, fmi2False,
                                    logging ? fmi2True : fmi2False);
    if (!c) {
        printf("instantiate NULL\n");
        return 10;
    }
    long steps = atol(opt(g_argc, g_argv, "steps", "10000"));
    double hstep = atof(opt(g_argc, g_argv, "h", "1e-3"));
    /* out=VR or out=VR1,VR2,...: one "value" line per reference, in that order */
    fmi2ValueReference vrs[32];
    size_t nvr = 0;
    for (const char *p = opt(g_argc, g_argv, "out", "0"); p && *p && nvr < 32;) {
        char *end;
        vrs[nvr++] = (fmi2ValueReference)strtoul(p, &end, 10);
        p = *end == ',' ? end + 1 : NULL;
    }
    CHECK(F.setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    CHECK(F.enter(c));
    const char *iv = opt(g_argc, g_argv, "int", NULL);
    if (iv) {
        fmi2ValueReference ivr = (fmi2ValueReference)strtoul(iv, NULL, 10);
        fmi2Integer ival = atoi(strchr(iv, ':') + 1);
        CHECK(F.set_integer(c, &ivr, 1, &ival));
    }
    CHECK(F.exit_init(c));
    const char *drive = opt(g_argc, g_argv, "drive", NULL);
    unsigned dx = 0, dv = 0;
    double off = 0.0, amp = 0.0, freq = 0.0;
    if (drive && sscanf(drive, "%u:%u:%lf:%lf:%lf", &dx, &dv, &off, &amp, &freq) != 5) {
        printf("bad drive=%s\n", drive);
        return 1;
    }
    for (long i = 0; i < steps; i++) {
        double t = (double)i * hstep;
        if (drive) {
            double u = freq * t, sph = u - (double)(long)u;
            fmi2ValueReference dvr[2] = {dx, dv};
            double val[2] = {off + 4.0 * amp * sph * (1.0 - sph), 4.0 * amp * freq * (1.0 - 2.0 * sph)};
            CHECK(F.set_real(c, dvr, 2, val));
        }
        CHECK(F.do_step(c, t, hstep, fmi2True));
    }
    double values[32];
    CHECK(F.get_real(c, vrs, nvr, values));
    pthread_mutex_lock(&g_out);
    for (size_t i = 0; i < nvr; i++) printf("value %.17g\n", values[i]);
    fflush(stdout);
    pthread_mutex_unlock(&g_out);
    CHECK(F.terminate(c));
    F.free_instance(c);
    return 0;
}

static void *run_thread(void *arg) {
    char name[32];
    snprintf(name, sizeof name, "host%ld", (long)(intptr_t)arg);
    return (void *)(intptr_t)run(name, g_argv[2]);
}

#define LOAD(T, var)                                                   \
    F.var = (fmi2##T##TYPE *)dlsym(h, "fmi2" #T);                      \
    if (!F.var) {                                                      \
        printf("missing fmi2%s\n", #T);                                \
        return 3;                                                      \
    }

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: %s SO URI GUID [key=value ...]\n", argv[0]);
        return 1;
    }
    g_argc = argc;
    g_argv = argv;
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
    LOAD(SetReal, set_real)
    LOAD(SetInteger, set_integer)
    LOAD(Terminate, terminate)
    LOAD(FreeInstance, free_instance)
    int threads = atoi(opt(argc, argv, "threads", "1"));
    if (opt(argc, argv, "uri1", NULL)) {
        int rc = 0;
        const char *uri = argv[2];
        for (int i = 0; uri; i++) {
            char name[32], key[16];
            snprintf(name, sizeof name, "host%d", i);
            int r = run(name, uri);
            printf("result %d %d\n", i, r);
            fflush(stdout);
            if (r && !rc) rc = r;
            snprintf(key, sizeof key, "uri%d", i + 1);
            uri = opt(argc, argv, key, NULL);
        }
        return rc;
    }
    if (threads <= 1) return run("host", argv[2]);
    pthread_t t[16];
    if (threads > 16) threads = 16;
    for (long i = 0; i < threads; i++) pthread_create(&t[i], NULL, run_thread, (void *)(intptr_t)i);
    int rc = 0;
    for (int i = 0; i < threads; i++) {
        void *r;
        pthread_join(t[i], &r);
        if ((intptr_t)r) rc = (int)(intptr_t)r;
    }
    return rc;
}

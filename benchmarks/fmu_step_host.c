/* A C timing host for FMI 2.0 co-simulation FMUs: the warm cost of one step as a C master
 * (libcosim, ecos, Simulink, Dymola) pays it, one fmi2SetReal of one input, one fmi2DoStep and one
 * fmi2GetReal of one output, with nothing of a Python wrapper around the calls.
 *
 *   fmu_step_host STEPS PAIRS H [preload=LIB] -- NAME SO URI GUID VRIN VALUE VROUT [VR=VALUE ...]
 *                                              -- NAME SO ...
 *
 * Every FMU after a "--" is loaded (dlopen RTLD_LOCAL), instantiated, set up at t = 0,
 * initialised (each VR=VALUE set as a Real in Initialization Mode), warmed up with one block,
 * then timed in PAIRS rounds of one block of STEPS steps each: the FMUs in the given order on
 * even rounds, in reverse order on odd ones (ABBA), so a slower moment of the machine falls on
 * both.  Each block is timed in the CPU time of the process and in wall-clock time
 * (clock_gettime); the time grid continues from block to block.  preload=LIB opens LIB with
 * RTLD_GLOBAL first: a pythonfmu FMU's library takes the Python C-API from the process.
 *
 * stdout: one JSON object {"steps_per_block", "pairs", "h", "warmup_steps", "fmus": [{"name",
 * "steps", "output", "cpu_s": [...], "wall_s": [...]}]}: per-step seconds of each timed block, the
 * steps taken in all and the output after the last one.  Exit codes: 0 ok, 1 usage, 2 dlopen, 3 missing symbol, 10 fmi2Instantiate
 * returned NULL, 11 a call failed. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h"

#define MAX_FMUS 4
#define MAX_INIT 64
#define WARMUP_STEPS 2000
#define NS_PER_S 1e9

typedef struct {
    const char *name, *so, *uri, *guid;
    fmi2ValueReference vr_in, vr_out;
    fmi2Real value;
    size_t ninit;
    fmi2ValueReference init_vr[MAX_INIT];
    fmi2Real init_value[MAX_INIT];
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2DoStepTYPE *do_step;
    fmi2TerminateTYPE *terminate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2Component c;
    long steps;          /* steps taken so far: the next communication point is steps * h */
    fmi2Real output;
    double *cpu, *wall;  /* per-step seconds of each timed block */
} fmu;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "log %s %d %s ", name ? name : "-", (int)status, category ? category : "-");
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static double now(clockid_t clk) {
    struct timespec ts;
    clock_gettime(clk, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec / NS_PER_S;
}

#define CHECK(f, call)                                                          \
    do {                                                                        \
        fmi2Status s_ = (call);                                                 \
        if (s_ > fmi2Warning) {                                                 \
            fprintf(stderr, "%s: %s -> %d\n", (f)->name, #call, (int)s_);       \
            return 11;                                                          \
        }                                                                       \
    } while (0)

#define LOAD(T, var)                                                            \
    fmi2##T##TYPE *var = (fmi2##T##TYPE *)dlsym(h, "fmi2" #T);                  \
    if (!var) {                                                                 \
        fprintf(stderr, "%s: missing fmi2%s\n", f->name, #T);                   \
        return 3;                                                               \
    }

/* load, instantiate and initialise f; 0 or an exit code */
static int open_fmu(fmu *f, fmi2CallbackFunctions *cb) {
    void *h = dlopen(f->so, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        fprintf(stderr, "%s: dlopen: %s\n", f->name, dlerror());
        return 2;
    }
    LOAD(Instantiate, instantiate)
    LOAD(SetupExperiment, setup)
    LOAD(EnterInitializationMode, enter)
    LOAD(ExitInitializationMode, exit_init)
    LOAD(SetReal, set_real)
    LOAD(GetReal, get_real)
    LOAD(DoStep, do_step)
    LOAD(Terminate, terminate)
    LOAD(FreeInstance, free_instance)
    f->set_real = set_real, f->get_real = get_real, f->do_step = do_step;
    f->terminate = terminate, f->free_instance = free_instance;
    f->c = instantiate(f->name, fmi2CoSimulation, f->guid, f->uri, cb, fmi2False, fmi2False);
    if (!f->c) {
        fprintf(stderr, "%s: fmi2Instantiate returned NULL\n", f->name);
        return 10;
    }
    CHECK(f, setup(f->c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    CHECK(f, enter(f->c));
    if (f->ninit) CHECK(f, set_real(f->c, f->init_vr, f->ninit, f->init_value));
    CHECK(f, exit_init(f->c));
    return 0;
}

/* m steps of set + doStep + get continuing f's time grid; per-step CPU and wall seconds */
static int run_block(fmu *f, long m, double h, double *cpu, double *wall) {
    const fmi2ValueReference vin = f->vr_in, vout = f->vr_out;
    const fmi2Real value = f->value;
    fmi2Real out = 0.0;
    double c0 = now(CLOCK_PROCESS_CPUTIME_ID), w0 = now(CLOCK_MONOTONIC);
    for (long k = f->steps; k < f->steps + m; k++) {
        CHECK(f, f->set_real(f->c, &vin, 1, &value));
        CHECK(f, f->do_step(f->c, (double)k * h, h, fmi2True));
        CHECK(f, f->get_real(f->c, &vout, 1, &out));
    }
    double w1 = now(CLOCK_MONOTONIC), c1 = now(CLOCK_PROCESS_CPUTIME_ID);
    f->steps += m;
    f->output = out;
    if (cpu) *cpu = (c1 - c0) / (double)m;
    if (wall) *wall = (w1 - w0) / (double)m;
    return 0;
}

/* NAME SO URI GUID VRIN VALUE VROUT [VR=VALUE ...] up to the next "--"; the arguments used */
static int parse_fmu(fmu *f, int argc, char **argv) {
    if (argc < 7) return -1;
    f->name = argv[0], f->so = argv[1], f->uri = argv[2], f->guid = argv[3];
    f->vr_in = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    f->value = strtod(argv[5], NULL);
    f->vr_out = (fmi2ValueReference)strtoul(argv[6], NULL, 10);
    int i = 7;
    for (; i < argc && strcmp(argv[i], "--") != 0; i++) {
        char *eq = strchr(argv[i], '=');
        if (!eq || f->ninit == MAX_INIT) return -1;
        f->init_vr[f->ninit] = (fmi2ValueReference)strtoul(argv[i], NULL, 10);
        f->init_value[f->ninit++] = strtod(eq + 1, NULL);
    }
    return i;
}

static void print_list(const double *x, long n) {
    putchar('[');
    for (long i = 0; i < n; i++) printf("%s%.6e", i ? ", " : "", x[i]);
    putchar(']');
}

int main(int argc, char **argv) {
    static const char usage[] =
        "usage: %s STEPS PAIRS H [preload=LIB] -- NAME SO URI GUID VRIN VALUE VROUT [VR=VALUE ...] "
        "[-- NAME ...]\n";
    if (argc < 5) {
        fprintf(stderr, usage, argv[0]);
        return 1;
    }
    long steps = atol(argv[1]), pairs = atol(argv[2]);
    double h = strtod(argv[3], NULL);
    if (steps < 1 || pairs < 1 || !(h > 0.0)) {
        fprintf(stderr, "STEPS and PAIRS must be >= 1 and H > 0, got %s %s %s\n", argv[1], argv[2],
                argv[3]);
        return 1;
    }
    int i = 4;
    if (strncmp(argv[i], "preload=", 8) == 0) {
        if (!dlopen(argv[i] + 8, RTLD_NOW | RTLD_GLOBAL)) {
            fprintf(stderr, "preload: dlopen: %s\n", dlerror());
            return 2;
        }
        i++;
    }
    static fmu fmus[MAX_FMUS];
    int n = 0;
    while (i < argc && strcmp(argv[i], "--") == 0) {
        if (n == MAX_FMUS) {
            fprintf(stderr, "at most %d FMUs\n", MAX_FMUS);
            return 1;
        }
        int used = parse_fmu(&fmus[n], argc - i - 1, argv + i + 1);
        if (used < 0) {
            fprintf(stderr, usage, argv[0]);
            return 1;
        }
        i += 1 + used;
        n++;
    }
    if (n == 0 || i != argc) {
        fprintf(stderr, usage, argv[0]);
        return 1;
    }
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    long warmup = steps < WARMUP_STEPS ? steps : WARMUP_STEPS;
    for (int k = 0; k < n; k++) {
        int rc = open_fmu(&fmus[k], &cb);
        if (rc) return rc;
        fmus[k].cpu = calloc((size_t)pairs, sizeof(double));
        fmus[k].wall = calloc((size_t)pairs, sizeof(double));
        if (!fmus[k].cpu || !fmus[k].wall) return 11;
        rc = run_block(&fmus[k], warmup, h, NULL, NULL);
        if (rc) return rc;
    }
    for (long p = 0; p < pairs; p++)
        for (int j = 0; j < n; j++) {
            fmu *f = &fmus[p % 2 == 0 ? j : n - 1 - j];
            int rc = run_block(f, steps, h, &f->cpu[p], &f->wall[p]);
            if (rc) return rc;
        }
    printf("{\"steps_per_block\": %ld, \"pairs\": %ld, \"h\": %.17g, \"warmup_steps\": %ld, \"fmus\": [",
           steps, pairs, h, warmup);
    for (int k = 0; k < n; k++) {
        fmu *f = &fmus[k];
        printf("%s{\"name\": \"%s\", \"steps\": %ld, \"output\": %.17g, \"cpu_s\": ", k ? ", " : "", f->name,
               f->steps, f->output);
        print_list(f->cpu, pairs);
        printf(", \"wall_s\": ");
        print_list(f->wall, pairs);
        putchar('}');
    }
    printf("]}\n");
    fflush(stdout);
    for (int k = 0; k < n; k++) {
        fmi2Status st = fmus[k].terminate(fmus[k].c);
        if (st > fmi2Warning) fprintf(stderr, "%s: fmi2Terminate -> %d\n", fmus[k].name, (int)st);
        fmus[k].free_instance(fmus[k].c);
    }
    return 0;
}

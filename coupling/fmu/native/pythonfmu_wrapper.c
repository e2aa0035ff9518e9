/* pythonfmu's export library, shipped next to the front and opened with dlopen. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front.h"
#include "hb_python.h"   /* HB_WRAPPER_FILE, HB_PYTHON_MODULES (written by build_front) */

hb_wrapper hb_W;
static int g_exit_registered;

/* At exit pythonfmu's export library releases its static std::shared_ptr<PyState> twice: the
 * C++ static destructor runs first and its __attribute__((destructor)) function then resets the
 * destroyed pointer again, a use after free of the control block that corrupts the heap (the
 * abort shows up later, e.g. in libgfortran's exit handler).  Resetting the pointer before
 * either runs makes both no-ops: this handler is registered right after the library is opened,
 * so it runs before the library's static destructors. */
static void hb_at_exit(void) {
    hb_python_at_exit();
    if (hb_W.finalize) hb_W.finalize();
}

int hb_load_wrapper(const char *file, char *err, size_t n) {
    if (hb_W.h) return 1;
    Dl_info info;
    if (!dladdr((void *)&hb_load_wrapper, &info) || !info.dli_fname) {
        snprintf(err, n, "cannot locate the FMU's binary directory");
        return 0;
    }
    char path[PATH_MAX];
    const char *slash = strrchr(info.dli_fname, '/');
    if (slash)
        snprintf(path, sizeof path, "%.*s/%s", (int)(slash - info.dli_fname), info.dli_fname,
                 file);
    else
        snprintf(path, sizeof path, "./%s", file);
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (!h) {
        snprintf(err, n, "cannot load the Python wrapper %s: %s", path, dlerror());
        return 0;
    }
#define WB(field)                                                                          \
    do {                                                                                   \
        *(void **)(&hb_W.field) = dlsym(h, "fmi2" #field);                                    \
        if (!hb_W.field) {                                                                    \
            snprintf(err, n, "the Python wrapper %s does not export fmi2" #field, path);   \
            return 0;                                                                      \
        }                                                                                  \
    } while (0)
    WB(Instantiate);
    WB(FreeInstance);
    WB(SetupExperiment);
    WB(EnterInitializationMode);
    WB(ExitInitializationMode);
    WB(Terminate);
    WB(Reset);
    WB(GetReal);
    WB(GetInteger);
    WB(GetBoolean);
    WB(GetString);
    WB(SetReal);
    WB(SetInteger);
    WB(SetBoolean);
    WB(SetString);
    WB(GetFMUstate);
    WB(SetFMUstate);
    WB(FreeFMUstate);
    WB(SerializedFMUstateSize);
    WB(SerializeFMUstate);
    WB(DeSerializeFMUstate);
    WB(DoStep);
#undef WB
    *(void **)(&hb_W.finalize) = dlsym(h, "finalizePythonInterpreter");
    hb_W.h = h;
    if (!g_exit_registered) {
        atexit(hb_at_exit);
        g_exit_registered = 1;
    }
    return 1;
}

/* Kept for hosts and slave code that look this symbol up in every library of the FMU. */
EXPORT void finalizePythonInterpreter(void) {
    if (hb_W.finalize) hb_W.finalize();
}

/* The Python flavour's backend: Python in the process, then pythonfmu's library (front.h). */
int hb_backend_load(char *err, size_t n) {
    return hb_ensure_python(HB_PYTHON_MODULES, err, n) && hb_load_wrapper(HB_WRAPPER_FILE, err, n);
}

/* Python in the process for the native front.
 *
 * A Python host's interpreter is used as it is.  Otherwise the interpreter $HAMMERBIT_PYTHON,
 * else python3 on PATH, is asked once, in a child process, for its version, libpython, home and
 * sys.path, and whether the needed modules are installed; its libpython is then loaded
 * RTLD_GLOBAL (C extensions such as numpy resolve the C-API from the global scope) and
 * initialised without signal handlers, in UTF-8 mode, with that sys.path.  The dozen C-API
 * functions used are bound at run time: no Python headers, any CPython 3 library. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "front.h"

/* ------------------------------------------------------------------------------------------ */
/* The C-API functions the front needs, bound at run time                                      */
/* ------------------------------------------------------------------------------------------ */
typedef struct {
    int (*IsInitialized)(void);
    void (*InitializeEx)(int);
    void *(*EvalSaveThread)(void);
    int (*GILEnsure)(void);
    void (*GILRelease)(int);
    void *(*DictNew)(void);
    int (*DictSetItemString)(void *, const char *, void *);
    void *(*DictGetItemString)(void *, const char *);
    void *(*UnicodeFromString)(const char *);
    const char *(*UnicodeAsUTF8)(void *);
    void *(*RunStringFlags)(const char *, int, void *, void *, void *);
    void (*DecRef)(void *);
    void (*ErrClear)(void);
    int *UTF8Mode;
} py_api;

#define PY_FILE_INPUT 257

static py_api g_py;
static int g_python_ready;      /* Python is in the process with the modules installed */
static int g_we_initialized;    /* this front initialised the interpreter */

static int bind_python(void *h, char *err, size_t n) {
#define BIND(field, sym)                                                             \
    do {                                                                             \
        *(void **)(&g_py.field) = dlsym(h, sym);                                     \
        if (!g_py.field) {                                                           \
            snprintf(err, n, "the Python library lacks the function %s", sym);     \
            return 0;                                                                \
        }                                                                            \
    } while (0)
    BIND(IsInitialized, "Py_IsInitialized");
    BIND(InitializeEx, "Py_InitializeEx");
    BIND(EvalSaveThread, "PyEval_SaveThread");
    BIND(GILEnsure, "PyGILState_Ensure");
    BIND(GILRelease, "PyGILState_Release");
    BIND(DictNew, "PyDict_New");
    BIND(DictSetItemString, "PyDict_SetItemString");
    BIND(DictGetItemString, "PyDict_GetItemString");
    BIND(UnicodeFromString, "PyUnicode_FromString");
    BIND(UnicodeAsUTF8, "PyUnicode_AsUTF8");
    BIND(RunStringFlags, "PyRun_StringFlags");
    BIND(DecRef, "Py_DecRef");
    BIND(ErrClear, "PyErr_Clear");
#undef BIND
    g_py.UTF8Mode = (int *)dlsym(h, "Py_UTF8Mode");
    return 1;
}

/* Run `code` (with the GIL held) in a fresh namespace holding the string items `names`;
 * copy the string `result` it leaves behind into out (empty if none). 0 if it raised. */
static int py_run(const char *code, const char *const *names, const char *const *values, char *out,
                  size_t n) {
    if (out && n) out[0] = '\0';
    void *d = g_py.DictNew();
    if (!d) return 0;
    for (int i = 0; names && names[i]; i++) {
        void *s = g_py.UnicodeFromString(values[i]);
        if (!s) {
            g_py.ErrClear();
            g_py.DecRef(d);
            return 0;
        }
        g_py.DictSetItemString(d, names[i], s);
        g_py.DecRef(s);
    }
    void *r = g_py.RunStringFlags(code, PY_FILE_INPUT, d, d, NULL);
    int ok = r != NULL;
    if (r)
        g_py.DecRef(r);
    else
        g_py.ErrClear();
    if (ok && out && n) {
        void *res = g_py.DictGetItemString(d, "result");   /* borrowed */
        const char *s = res ? g_py.UnicodeAsUTF8(res) : NULL;
        if (s)
            snprintf(out, n, "%s", s);
        else if (res)
            g_py.ErrClear();
    }
    g_py.DecRef(d);
    return ok;
}

/* Found, not imported: the slave configures numba (its CPU target) before the first import. */
static const char CHECK_CODE[] =
    "result = ''\n"
    "try:\n"
    "    import importlib.util\n"
    "    bad = []\n"
    "    for m in modules.split():\n"
    "        try:\n"
    "            if importlib.util.find_spec(m) is None:\n"
    "                bad.append('%s (not installed)' % m)\n"
    "        except BaseException as e:\n"
    "            bad.append('%s (%s: %s)' % (m, type(e).__name__, e))\n"
    "    result = '; '.join(bad)\n"
    "except BaseException as e:\n"
    "    result = 'the module check failed: %r' % (e,)\n";

static const char SETUP_CODE[] =
    "result = ''\n"
    "try:\n"
    "    import os, site, sys\n"
    "    def _d(s):\n"
    "        return [os.fsdecode(bytes.fromhex(h)) for h in s.split()]\n"
    "    want = _d(paths)\n"
    "    for d in _d(sites):\n"
    "        if os.path.isdir(d):\n"
    "            site.addsitedir(d)\n"
    "    sys.path[:] = want + [p for p in sys.path if p not in want]\n"
    "    sys.executable = _d(exe)[0]\n"
    "except BaseException as e:\n"
    "    result = 'setting up sys.path failed: %r' % (e,)\n";

/* At exit of a native host: only the output buffers.  Python's atexit hooks and finalizers are
 * not run: shared libraries loaded after this front (LLVM of numba, ...) have already run their
 * static destructors by then, and some finalizers would call into them. */
static const char EXIT_CODE[] =
    "try:\n"
    "    import sys\n"
    "    for s in (sys.stdout, sys.stderr):\n"
    "        try:\n"
    "            s.flush()\n"
    "        except Exception:\n"
    "            pass\n"
    "except BaseException:\n"
    "    pass\n";

/* ------------------------------------------------------------------------------------------ */
/* Finding Python: ask the interpreter ($HAMMERBIT_PYTHON or python3 on PATH) about itself     */
/* ------------------------------------------------------------------------------------------ */
static const char QUERY_CODE[] =
    "import importlib.util, os, site, sys, sysconfig\n"
    "def h(s):\n"
    "    return os.fsencode(s).hex()\n"
    "v = sysconfig.get_config_var\n"
    "ver = '%d.%d' % sys.version_info[:2]\n"
    "names = [v('INSTSONAME'), v('LDLIBRARY'), 'libpython%s%s.so.1.0' % (ver, sys.abiflags),\n"
    "         'libpython%s%s.so' % (ver, sys.abiflags)]\n"
    "dirs = [v('LIBDIR'), v('LIBPL'), os.path.join(v('LIBDIR') or '', v('MULTIARCH') or ''),\n"
    "        os.path.join(sys.base_prefix, 'lib')]\n"
    "lib = ''\n"
    "for n in names:\n"
    "    if n and '.so' in n and not lib:\n"
    "        for d in dirs:\n"
    "            if d and os.path.isfile(os.path.join(d, n)):\n"
    "                lib = os.path.join(d, n)\n"
    "                break\n"
    "print('hb:version=' + sys.version.split()[0])\n"
    "print('hb:exe=' + h(sys.executable))\n"
    "print('hb:lib=' + h(lib))\n"
    "print('hb:home=' + h(sys.base_prefix + ':' + sys.base_exec_prefix))\n"
    "for p in sys.path:\n"
    "    if p:\n"
    "        print('hb:path=' + h(p))\n"
    "sites = site.getsitepackages()\n"
    "if site.ENABLE_USER_SITE:\n"
    "    sites.append(site.getusersitepackages())\n"
    "for p in sites:\n"
    "    print('hb:site=' + h(p))\n"
    "print('hb:missing=' + ' '.join(m for m in sys.argv[1:] if importlib.util.find_spec(m) is None))\n";

typedef struct {
    char version[64];
    char exe[PATH_MAX];
    char lib[PATH_MAX];
    char home[2 * PATH_MAX + 2];
    char exe_hex[2 * PATH_MAX + 1];
    char *paths_hex;   /* space-separated */
    char *sites_hex;
    char missing[256];
} py_query;

static int hex_decode(const char *hex, char *out, size_t n) {
    size_t len = strlen(hex);
    if (len % 2 || len / 2 + 1 > n) return 0;
    for (size_t i = 0; i < len / 2; i++) {
        unsigned v;
        if (sscanf(hex + 2 * i, "%2x", &v) != 1) return 0;
        out[i] = (char)v;
    }
    out[len / 2] = '\0';
    return 1;
}

static int append_word(char **dst, const char *word) {
    size_t old = *dst ? strlen(*dst) : 0;
    char *p = realloc(*dst, old + strlen(word) + 2);
    if (!p) return 0;
    if (old) p[old++] = ' ';
    strcpy(p + old, word);
    *dst = p;
    return 1;
}

/* which interpreter, and how it was chosen (for messages) */
static const char *python_rule(char *how, size_t n) {
    const char *env = getenv("HAMMERBIT_PYTHON");
    if (env && *env) {
        snprintf(how, n, "HAMMERBIT_PYTHON=%s", env);
        return env;
    }
    snprintf(how, n, "python3 on PATH (PATH=%s)", getenv("PATH") ? getenv("PATH") : "");
    return "python3";
}

extern char **environ;

static int query_python(const char *python, const char *how, const char *modules, py_query *q,
                        char *err, size_t n) {
    memset(q, 0, sizeof *q);
    int fds[2];
    if (pipe(fds) != 0) {
        snprintf(err, n, "cannot create a pipe to ask %s about itself: %s", how, strerror(errno));
        return 0;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addclose(&fa, fds[0]);
    posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
    posix_spawn_file_actions_adddup2(&fa, fds[1], 2);
    posix_spawn_file_actions_addclose(&fa, fds[1]);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    char mods[512];
    snprintf(mods, sizeof mods, "%s", modules);
    char *argv[20] = {(char *)python, "-c", (char *)QUERY_CODE};
    int argc = 3;
    for (char *m = strtok(mods, " "); m && argc < 19; m = strtok(NULL, " ")) argv[argc++] = m;
    argv[argc] = NULL;
    pid_t pid;
    int rc = strchr(python, '/') ? posix_spawn(&pid, python, &fa, NULL, argv, environ)
                                 : posix_spawnp(&pid, python, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    close(fds[1]);
    if (rc != 0) {
        close(fds[0]);
        snprintf(err, n,
                 "no Python found: %s cannot be run (%s); install Python 3 with numpy and numba, "
                 "or set HAMMERBIT_PYTHON to the path of such a python executable",
                 how, strerror(rc));
        return 0;
    }
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    ssize_t k;
    while (buf && (k = read(fds[0], buf + len, cap - len - 1)) != 0) {
        if (k < 0) {
            if (errno == EINTR) continue;
            break;
        }
        len += (size_t)k;
        if (cap - len < 2) {
            char *nb = realloc(buf, cap *= 2);
            if (!nb) {
                free(buf);
                buf = NULL;
            } else
                buf = nb;
        }
    }
    close(fds[0]);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (!buf) {
        snprintf(err, n, "out of memory reading the answer of %s", how);
        return 0;
    }
    buf[len] = '\0';
    int have_exe = 0;
    char other[512] = "";
    for (char *line = strtok(buf, "\n"); line; line = strtok(NULL, "\n")) {
        if (strncmp(line, "hb:", 3) != 0) {
            if (strlen(other) + strlen(line) + 3 < sizeof other) {
                strcat(other, line);
                strcat(other, " | ");
            }
            continue;
        }
        char *key = line + 3, *eq = strchr(key, '=');
        if (!eq) continue;
        *eq = '\0';
        char *val = eq + 1;
        if (!strcmp(key, "version"))
            snprintf(q->version, sizeof q->version, "%s", val);
        else if (!strcmp(key, "exe")) {
            have_exe = hex_decode(val, q->exe, sizeof q->exe);
            snprintf(q->exe_hex, sizeof q->exe_hex, "%s", val);
        } else if (!strcmp(key, "lib"))
            hex_decode(val, q->lib, sizeof q->lib);
        else if (!strcmp(key, "home"))
            hex_decode(val, q->home, sizeof q->home);
        else if (!strcmp(key, "path"))
            append_word(&q->paths_hex, val);
        else if (!strcmp(key, "site"))
            append_word(&q->sites_hex, val);
        else if (!strcmp(key, "missing"))
            snprintf(q->missing, sizeof q->missing, "%s", val);
    }
    free(buf);
    if (!have_exe) {
        snprintf(err, n,
                 "%s did not answer like a Python 3 interpreter (exit status %d; output: %s); set "
                 "HAMMERBIT_PYTHON to the path of a python executable with numpy and numba",
                 how, WIFEXITED(status) ? WEXITSTATUS(status) : -1, other[0] ? other : "none");
        return 0;
    }
    return 1;
}

static void free_query(py_query *q) {
    free(q->paths_hex);
    free(q->sites_hex);
    q->paths_hex = q->sites_hex = NULL;
}

static int check_modules(const char *modules, char *err, size_t n) {
    char bad[2048];
    int g = g_py.GILEnsure();
    const char *names[] = {"modules", NULL};
    const char *values[] = {modules, NULL};
    int ok = py_run(CHECK_CODE, names, values, bad, sizeof bad);
    g_py.GILRelease(g);
    if (!ok) {
        snprintf(err, n, "the Python in this process cannot run the module check");
        return 0;
    }
    if (bad[0]) {
        snprintf(err, n, "the Python in this process lacks what the FMU needs: %s", bad);
        return 0;
    }
    return 1;
}

int hb_ensure_python(const char *modules, char *err, size_t n) {
    if (g_python_ready) return 1;
    void *sym = dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    if (sym && ((int (*)(void))sym)()) {   /* a Python host: use its interpreter as it is */
        if (!bind_python(RTLD_DEFAULT, err, n)) return 0;
        if (!check_modules(modules, err, n)) {
            char tmp[16384];
            snprintf(tmp, sizeof tmp, "%s; install them into %s", err,
                     g_we_initialized ? "the Python found for this FMU"
                                      : "the Python that runs this host");
            snprintf(err, n, "%s", tmp);
            return 0;
        }
        g_python_ready = 1;
        return 1;
    }
    char how[PATH_MAX + 64];
    const char *python = python_rule(how, sizeof how);
    py_query q;
    if (!query_python(python, how, modules, &q, err, n)) return 0;
    int ok = 0;
    if (q.missing[0]) {
        snprintf(err, n,
                 "Python %s at %s (%s) lacks the modules: %s; install them there (pip install %s) "
                 "or set HAMMERBIT_PYTHON to a python executable that has them",
                 q.version, q.exe, how, q.missing, q.missing);
        goto done;
    }
    if (!q.lib[0]) {
        snprintf(err, n,
                 "Python %s at %s (%s) has no shared library libpython%.4s*.so, which a native host "
                 "needs; use a Python built with --enable-shared (or install its libpython "
                 "package) and point HAMMERBIT_PYTHON to it",
                 q.version, q.exe, how, q.version);
        goto done;
    }
    void *h = dlopen(q.lib, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE);
    if (!h) {
        snprintf(err, n, "cannot load %s (the library of Python %s at %s): %s", q.lib, q.version,
                 q.exe, dlerror());
        goto done;
    }
    if (!bind_python(h, err, n)) goto done;
    if (!g_py.IsInitialized()) {
        /* PYTHONHOME only for the start of the interpreter (then the host's value comes back);
         * UTF-8 mode so non-ASCII paths work whatever the host's locale */
        const char *old = getenv("PYTHONHOME");
        char *saved = old ? strdup(old) : NULL;
        setenv("PYTHONHOME", q.home, 1);
        if (g_py.UTF8Mode) *g_py.UTF8Mode = 1;
        g_py.InitializeEx(0);   /* 0: the host keeps its signal handlers */
        if (saved) {
            setenv("PYTHONHOME", saved, 1);
            free(saved);
        } else {
            unsetenv("PYTHONHOME");
        }
        if (!g_py.IsInitialized()) {
            snprintf(err, n, "Python %s at %s did not start", q.version, q.exe);
            goto done;
        }
        g_we_initialized = 1;
        char res[2048];
        const char *names[] = {"paths", "sites", "exe", NULL};
        const char *values[] = {q.paths_hex ? q.paths_hex : "", q.sites_hex ? q.sites_hex : "",
                                q.exe_hex, NULL};
        int run_ok = py_run(SETUP_CODE, names, values, res, sizeof res);
        g_py.EvalSaveThread();   /* release the GIL: pythonfmu takes it per call */
        if (!run_ok || res[0]) {
            snprintf(err, n, "Python %s at %s: %s", q.version, q.exe,
                     res[0] ? res : "setting up sys.path failed");
            goto done;
        }
    }
    if (!check_modules(modules, err, n)) {
        char tmp[16384];
        snprintf(tmp, sizeof tmp, "%s (Python %s at %s, %s)", err, q.version, q.exe, how);
        snprintf(err, n, "%s", tmp);
        goto done;
    }
    g_python_ready = 1;
    ok = 1;
done:
    free_query(&q);
    return ok;
}

void hb_python_at_exit(void) {
    if (g_we_initialized && g_py.GILEnsure) {
        g_py.GILEnsure();   /* kept: no Python thread runs during the rest of the exit */
        py_run(EXIT_CODE, NULL, NULL, NULL, 0);
    }
}

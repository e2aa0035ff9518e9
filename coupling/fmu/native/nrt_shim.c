/* What the compiled numba kernels need from numba's runtime, without numba or Python.
 *
 * The kernel objects (hammerbit.fmu.native_kernels) reference
 *   - NRT allocation: the solver driver allocates its scratch arrays with np.empty at entry and
 *     releases them on return (NRT_MemInfo_alloc_aligned, NRT_MemInfo_call_dtor, NRT_Free);
 *     here they live on malloc/free (released blocks kept per thread for the next call), in
 *     numba's MemInfo layout (the kernels read its fields);
 *   - the error path of a numba cfunc: if a kernel raised (a ZeroDivisionError, ...), the cfunc
 *     takes the GIL and writes the exception to Python's "unraisable" hook.  There is no Python
 *     here: the stubs record that a kernel raised, and the model turns that into an FMI status
 *     (hb_kernel_raised).  None of them is reached on the normal path. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "kernel_api.h"

#if defined(_WIN32)
#define SHIM_EXPORT
#else
#define SHIM_EXPORT __attribute__((visibility("hidden")))
#endif

/* numba/core/runtime/nrt.cpp: struct MemInfo (the kernels decrement refct inline and read data) */
typedef void (*nrt_dtor)(void *ptr, size_t size, void *info);
typedef struct {
    size_t refct;
    nrt_dtor dtor;
    void *dtor_info;
    void *data;
    size_t size;
    void *external_allocator;
} nrt_meminfo;

static _Thread_local int g_raised;   /* a kernel raised on this thread since the last check */

int hb_kernel_raised(void) {
    int r = g_raised;
    g_raised = 0;
    return r;
}

/* A block: [capacity][meminfo][padding to `align`][data]; dtor_info holds the block.  The solver
 * driver allocates the same dozen small scratch arrays at every call (every fmi2DoStep), so
 * released blocks are kept per thread and handed out again instead of a malloc/free each. */
#define KEPT_BLOCKS 32
typedef struct {
    size_t capacity;           /* bytes of the whole block */
    nrt_meminfo mi;
} block_head;

static _Thread_local block_head *g_kept[KEPT_BLOCKS];
static _Thread_local int g_nkept;

static void release_block(void *ptr, size_t size, void *info) {
    (void)ptr, (void)size;
    if (g_nkept < KEPT_BLOCKS)
        g_kept[g_nkept++] = info;
    else
        free(info);
}

static block_head *take_block(size_t need) {
    for (int i = g_nkept - 1; i >= 0; i--) {
        block_head *b = g_kept[i];
        if (b->capacity >= need) {
            g_kept[i] = g_kept[--g_nkept];
            return b;
        }
    }
    block_head *b = malloc(need);
    if (b) b->capacity = need;
    return b;
}

SHIM_EXPORT void *NRT_MemInfo_alloc_aligned(size_t size, unsigned align) {
    if (align < sizeof(void *)) align = sizeof(void *);
    block_head *block = take_block(sizeof(block_head) + size + align);
    if (!block) return NULL;
    uintptr_t data = ((uintptr_t)(block + 1) + align - 1) & ~(uintptr_t)(align - 1);
    nrt_meminfo *mi = &block->mi;
    mi->refct = 1;
    mi->dtor = release_block;
    mi->dtor_info = block;
    mi->data = (void *)data;
    mi->size = size;
    mi->external_allocator = NULL;
    return mi;
}

SHIM_EXPORT void NRT_MemInfo_call_dtor(void *p) {
    nrt_meminfo *mi = p;
    if (mi && mi->dtor) mi->dtor(mi->data, mi->size, mi->dtor_info);
}

SHIM_EXPORT void NRT_Free(void *p) { free(p); }

/* -- the error path of a cfunc (Python C-API and numba helpers): record, never touch Python -- */
SHIM_EXPORT void *PyExc_RuntimeError = NULL;
SHIM_EXPORT void numba_gil_ensure(void *state) { (void)state; }
SHIM_EXPORT void numba_gil_release(void *state) { (void)state; }
SHIM_EXPORT void *numba_unpickle(const char *data, int n, const char *hash) {
    (void)data, (void)n, (void)hash;
    return NULL;
}
SHIM_EXPORT void numba_do_raise(void *excinfo) {
    (void)excinfo;
    g_raised = 1;
}
SHIM_EXPORT void *numba_runtime_build_excinfo_struct(void *a, void *b) {
    (void)a, (void)b;
    g_raised = 1;
    return NULL;
}
SHIM_EXPORT void *PyUnicode_FromString(const char *s) {
    (void)s;
    return NULL;
}
SHIM_EXPORT void *PyBytes_FromStringAndSize(const char *s, intptr_t n) {
    (void)s, (void)n;
    return NULL;
}
SHIM_EXPORT void PyErr_WriteUnraisable(void *obj) {
    (void)obj;
    g_raised = 1;
}
SHIM_EXPORT void PyErr_SetString(void *type, const char *msg) {
    (void)type, (void)msg;
    g_raised = 1;
}
SHIM_EXPORT void PyErr_Clear(void) {}
SHIM_EXPORT void Py_DecRef(void *obj) { (void)obj; }

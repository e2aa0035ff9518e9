/* What the compiled numba kernels need from numba's runtime, without numba or Python.
 *
 * The kernel objects (hammerbit.fmu.native_kernels) reference
 *   - NRT allocation: the solver driver allocates its scratch arrays with np.empty at entry and
 *     releases them on return (NRT_MemInfo_alloc_aligned, NRT_MemInfo_call_dtor, NRT_Free);
 *     here they are cut from a per-thread arena (malloc beyond it), in numba's MemInfo
 *     layout (the kernels read its fields);
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

/* The solver driver allocates the same dozen small scratch arrays at every call (every
 * fmi2DoStep) and releases them all before it returns.  They are cut from a per-thread arena:
 * taking one moves a pointer, releasing one counts down, and the arena is reused from its start
 * once nothing of it is held.  A request the arena cannot hold goes to malloc.  The arena is
 * thread-local storage, which the C runtime gives each thread that calls a kernel and takes
 * back when the thread ends.
 *
 * A block: [head][padding to `align`][data]; dtor_info holds the head. */
typedef struct thread_pool thread_pool;
typedef struct {
    thread_pool *owner;        /* the arena the block was cut from; NULL: from malloc */
    nrt_meminfo mi;
} block_head;

#define ARENA_BYTES 8192               /* the driver holds about 3 kB at once */
#define BLOCK_ALIGN 64                 /* blocks start on a cache line (and so on block_head's alignment) */

/* Everything a thread keeps in one variable: each access to thread-local storage from a shared
 * library is a call (__tls_get_addr), so an allocation makes one and a release none. */
struct thread_pool {
    _Alignas(BLOCK_ALIGN) unsigned char arena[ARENA_BYTES];
    size_t used;               /* bytes of the arena handed out since it was last empty */
    int live;                  /* blocks of the arena not released yet */
    int raised;                /* a kernel raised on this thread since the last check */
};

static _Thread_local thread_pool g_pool;

int hb_kernel_raised(void) {
    thread_pool *tp = &g_pool;
    int r = tp->raised;
    tp->raised = 0;
    return r;
}

static void release_block(void *ptr, size_t size, void *info) {
    (void)ptr, (void)size;
    block_head *b = info;
    thread_pool *tp = b->owner;
    if (!tp) {
        free(b);
        return;
    }
    if (--tp->live == 0) tp->used = 0;
}

static block_head *take_block(size_t need) {
    thread_pool *tp = &g_pool;
    need = (need + BLOCK_ALIGN - 1) & ~(size_t)(BLOCK_ALIGN - 1);
    if (need <= ARENA_BYTES - tp->used) {
        block_head *b = (block_head *)(tp->arena + tp->used);
        tp->used += need;
        tp->live++;
        b->owner = tp;
        return b;
    }
    block_head *b = malloc(need);
    if (b) b->owner = NULL;
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
    g_pool.raised = 1;
}
SHIM_EXPORT void *numba_runtime_build_excinfo_struct(void *a, void *b) {
    (void)a, (void)b;
    g_pool.raised = 1;
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
    g_pool.raised = 1;
}
SHIM_EXPORT void PyErr_SetString(void *type, const char *msg) {
    (void)type, (void)msg;
    g_pool.raised = 1;
}
SHIM_EXPORT void PyErr_Clear(void) {}
SHIM_EXPORT void Py_DecRef(void *obj) { (void)obj; }

"""The native FMU's runtime shim (coupling/fmu/native/nrt_shim.c) as an allocator, driven from C
with a random sequence of allocations and releases in any order, sizes below and beyond its
per-thread arena, on two threads: blocks alive at the same time never overlap (each keeps the
bytes written into it), data is aligned as asked, and the MemInfo fields are numba's."""
from __future__ import annotations

import subprocess
import textwrap

import pytest

from cached_compile import compile_c

from hammerbit.fmu.native import SOURCE_DIR, FrontBuildError, find_compiler

OPS = 200_000

_DRIVER = textwrap.dedent(r'''
    #include <pthread.h>
    #include <stdint.h>
    #include <stdio.h>
    #include <string.h>

    void *NRT_MemInfo_alloc_aligned(size_t size, unsigned align);
    void NRT_MemInfo_call_dtor(void *p);
    typedef struct { size_t refct; void *dtor; void *dtor_info; void *data; size_t size; void *ext; } mi_t;

    #define LIVE 64
    static const unsigned ALIGNS[] = {1, 8, 16, 32, 64};

    static void *run(void *arg) {
        uint64_t seed = (uint64_t)(uintptr_t)arg;
        long ops = OPS;
        mi_t *live[LIVE] = {0};
        unsigned char tag[LIVE] = {0};
        for (long k = 0; k < ops; k++) {
            seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
            unsigned r = (unsigned)(seed >> 33);
            int i = r % LIVE;
            if (live[i]) {                       /* release it, after checking its bytes */
                mi_t *m = live[i];
                for (size_t b = 0; b < m->size; b++)
                    if (((unsigned char *)m->data)[b] != tag[i]) {
                        printf("overwritten block of %zu bytes at op %ld\n", m->size, k);
                        return (void *)1;
                    }
                m->refct = 0;                    /* as numba's NRT_decref does before the dtor */
                NRT_MemInfo_call_dtor(m);
                live[i] = NULL;
                continue;
            }
            /* mostly small arrays as the solver driver takes, now and then larger than the arena */
            size_t size = (r >> 8) % 16 == 0 ? 4096 + (r >> 12) % 16384 : (r >> 8) % 700;
            unsigned align = ALIGNS[(r >> 20) % 5];
            mi_t *m = NRT_MemInfo_alloc_aligned(size, align);
            if (!m) { printf("NULL\n"); return (void *)1; }
            unsigned want = align < sizeof(void *) ? sizeof(void *) : align;
            if (m->refct != 1 || m->size != size || m->dtor == NULL || m->ext != NULL ||
                (uintptr_t)m->data % want != 0 || (char *)m->data < (char *)(m + 1)) {
                printf("bad meminfo: refct %zu size %zu/%zu align %u data %p\n", m->refct, m->size,
                       size, align, m->data);
                return (void *)1;
            }
            tag[i] = (unsigned char)(1 + k % 250);
            memset(m->data, tag[i], size);
            live[i] = m;
        }
        return NULL;
    }

    int main(void) {
        pthread_t t[2];
        for (long i = 0; i < 2; i++) pthread_create(&t[i], NULL, run, (void *)(uintptr_t)(i + 1));
        int rc = 0;
        for (int i = 0; i < 2; i++) {
            void *r;
            pthread_join(t[i], &r);
            if (r) rc = 1;
        }
        if (!rc) printf("ok\n");
        return rc;
    }
''').replace("OPS;", f"{OPS};")


def test_shim_blocks_never_overlap_and_are_aligned(tmp_path):
    try:
        cc = find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))
    src, exe = tmp_path / "driver.c", tmp_path / "driver"
    src.write_text(_DRIVER)
    compile_c([cc, "-O1", "-std=gnu11", "-I", str(SOURCE_DIR), "-o", str(exe), str(src),
               str(SOURCE_DIR / "nrt_shim.c"), "-lpthread"], exe, tmp_path)
    r = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stdout + r.stderr

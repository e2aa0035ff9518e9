/* The exact step's tables of the native Drillstring model, as the build wrote them into
 * resources/string_native.bin (hammerbit.fmu.native_string): read once per instance. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model_string.h"

static int read_doubles(FILE *f, double *p, size_t k) { return fread(p, sizeof(double), k, f) == k; }

/* the table from <resources>/string_native.bin; 1, or 0 with the reason in err */
int hs_load_table(const char *dir, table *t, char *err, size_t en) {
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, HS_DATA_FILE);
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, en, "cannot open %s", path);
        return 0;
    }
    char magic[8];
    int64_t hdr[2];
    memset(t, 0, sizeof *t);
    int ok = fread(magic, 1, 8, f) == 8 && memcmp(magic, DATA_MAGIC, 8) == 0 &&
             fread(hdr, sizeof(int64_t), 2, f) == 2 && hdr[0] > 0 && hdr[0] < 1000 && hdr[1] > 0;
    if (ok) {
        t->nblocks = hdr[0];
        size_t total = (size_t)hdr[1];
        t->b = calloc((size_t)t->nblocks, sizeof *t->b);
        t->mem = malloc(total * sizeof(double));
        ok = t->b && t->mem && read_doubles(f, t->mem, total);
        double *p = t->mem, *end = t->mem + total;
        for (int64_t i = 0; ok && i < t->nblocks; i++) {
            block *b = &t->b[i];
            if (end - p < 5) { ok = 0; break; }
            if (p[2] == GENERATOR_KIND) {            /* a form's generator, after its step blocks */
                int64_t form = (int64_t)p[0], n = (int64_t)p[3], km = (int64_t)p[4];
                p += 5;
                if (form < 0 || form > 1 || n <= 0 || km < 0 || km > n ||
                    (size_t)(end - p) < (size_t)(n * n + 2 * n + n + N_ROWS * n + 6 * km)) { ok = 0; break; }
                generator *g = &t->gen[form];
                g->n = n, g->m = km;
                g->A1 = p; p += n * n;
                g->E = p; p += 2 * n;
                g->frow = p; p += n;
                g->rows = p; p += N_ROWS * n;
                g->lam = (double _Complex *)p; p += 2 * km;
                g->B = (double _Complex *)p; p += 4 * km;
                b->form = -1;                        /* not a step block */
                continue;
            }
            b->form = (int64_t)p[0];
            b->h = p[1];
            b->modal = (int64_t)p[2];
            b->n = (int64_t)p[3];
            p += 4;
            int64_t n = b->n;
            size_t need = b->modal ? (size_t)(2 * n + 2 * N_ROWS * n + 2 * n + 2 * n * N_COEFFS + 2 * n +
                                              N_COEFFS)
                                   : (size_t)(n + N_ROWS * n + (n + 1) * (n + N_COEFFS));
            if (n <= 0 || (size_t)(end - p) < need) { ok = 0; break; }
            if (n > t->nmax) t->nmax = n;
            if (b->modal) {
                b->frow_c = (double _Complex *)p; p += 2 * n;
                b->rows_c = (double _Complex *)p; p += 2 * N_ROWS * n;
                b->d = (double _Complex *)p; p += 2 * n;
                b->G = (double _Complex *)p; p += 2 * n * N_COEFFS;
                b->irow = (double _Complex *)p; p += 2 * n;
                memcpy(b->icol, p, sizeof b->icol); p += N_COEFFS;
            } else {
                b->frow_r = p; p += n;
                b->rows_r = p; p += N_ROWS * n;
                b->P = p; p += (n + 1) * (n + N_COEFFS);
            }
        }
        ok = ok && p == end;
    }
    fclose(f);
    if (!ok) {
        free(t->b);
        free(t->mem);
        memset(t, 0, sizeof *t);
        snprintf(err, en, "%s is corrupt or of another build", path);
    }
    return ok;
}

const block *hs_any_block(const table *t, int64_t form) {
    for (int64_t i = 0; i < t->nblocks; i++)
        if (t->b[i].form == form) return &t->b[i];
    return NULL;
}

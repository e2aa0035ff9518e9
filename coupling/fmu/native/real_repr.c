/* A float as Python's repr() writes it: the native models' messages name values as the Python
 * slaves do. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front.h"

void hb_repr(double v, char *out, size_t n) {
    if (isnan(v)) {
        snprintf(out, n, "nan");
        return;
    }
    if (isinf(v)) {
        snprintf(out, n, v > 0 ? "inf" : "-inf");
        return;
    }
    char e[40];
    int prec = 1;
    for (; prec <= 17; prec++) {
        snprintf(e, sizeof e, "%.*e", prec - 1, v);
        if (strtod(e, NULL) == v) break;
    }
    int exp10 = atoi(strchr(e, 'e') + 1);
    if (v != 0.0 && (exp10 < -4 || exp10 >= 16)) {
        char mant[40];
        snprintf(mant, sizeof mant, "%.*s", (int)(strchr(e, 'e') - e), e);
        snprintf(out, n, "%se%c%02d", mant, exp10 < 0 ? '-' : '+', abs(exp10));
        return;
    }
    int decimals = prec - 1 - exp10;
    snprintf(out, n, "%.*f", decimals > 0 ? decimals : 0, v);
    if (!strchr(out, '.')) strncat(out, ".0", n - strlen(out) - 1);
}


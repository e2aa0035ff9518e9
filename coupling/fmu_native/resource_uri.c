/* fmuResourceLocation -> directory path.
 *
 * Accepted: file:/x, file://localhost/x, file:///x with percent-escapes (spaces, non-ASCII
 * bytes, '#', ...), and unencoded paths from hosts that write the path as it is; any other host
 * than localhost is refused.  pythonfmu itself only strips "file://" and decodes "%20". */
#define _GNU_SOURCE
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "front.h"

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static int is_dir(const char *p) {
    struct stat s;
    return stat(p, &s) == 0 && S_ISDIR(s.st_mode);
}

int hb_uri_to_path(const char *uri, char *out, size_t n, char *err, size_t en) {
    const char *p = uri;
    if (strncasecmp(p, "file:", 5) == 0) {
        p += 5;
        if (p[0] == '/' && p[1] == '/') {   /* authority */
            const char *auth = p + 2, *end = strchr(auth, '/');
            if (!end) {
                snprintf(err, en, "fmuResourceLocation '%s' has no path", uri);
                return 0;
            }
            size_t alen = (size_t)(end - auth);
            if (alen != 0 && !(alen == 9 && strncasecmp(auth, "localhost", 9) == 0)) {
                snprintf(err, en,
                         "fmuResourceLocation '%s' names the host '%.*s'; only local files "
                         "(file:///path or file://localhost/path) are supported",
                         uri, (int)alen, auth);
                return 0;
            }
            p = end;
        }
    }
    if (p[0] != '/') {
        snprintf(err, en, "fmuResourceLocation '%s' is not an absolute file URI", uri);
        return 0;
    }
    size_t j = 0;
    for (size_t i = 0; p[i]; i++) {
        char c = p[i];
        if (c == '%') {
            int hi = hexval(p[i + 1]), lo = hi >= 0 ? hexval(p[i + 2]) : -1;
            if (hi < 0 || lo < 0) {
                snprintf(err, en, "fmuResourceLocation '%s' has an invalid percent-escape", uri);
                return 0;
            }
            c = (char)(hi * 16 + lo);
            i += 2;
            if (c == '\0') {
                snprintf(err, en, "fmuResourceLocation '%s' encodes a NUL byte", uri);
                return 0;
            }
        }
        if (j + 1 >= n) {
            snprintf(err, en, "fmuResourceLocation '%s' is too long", uri);
            return 0;
        }
        out[j++] = c;
    }
    out[j] = '\0';
    while (j > 1 && out[j - 1] == '/') out[--j] = '\0';
    if (!is_dir(out)) {
        /* a host that wrote the path into the URI without encoding it */
        char raw[PATH_MAX];
        snprintf(raw, sizeof raw, "%s", p);
        size_t k = strlen(raw);
        while (k > 1 && raw[k - 1] == '/') raw[--k] = '\0';
        if (is_dir(raw) && k < n) {
            memcpy(out, raw, k + 1);
            return 1;
        }
        snprintf(err, en, "fmuResourceLocation '%s': the directory '%s' does not exist", uri, out);
        return 0;
    }
    return 1;
}
/* fmuResourceLocation -> directory path.
 *
 * Accepted: file:/x, file://localhost/x, file:///x with percent-escapes (spaces, non-ASCII
 * bytes, '#', ...), and unencoded paths from hosts that write the path as it is; any other host
 * than localhost is refused.  pythonfmu itself only strips "file://" and decodes "%20". */
#define _GNU_SOURCE
#include <ctype.h>
#include <dirent.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "front.h"

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static int is_dir(const char *p) {   /* opendir, not stat: stat needs glibc >= 2.33 */
    DIR *d = opendir(p);
    if (d) closedir(d);
    return d != NULL;
}

static void strip_slashes(char *path) {
    size_t j = strlen(path);
    while (j > 1 && path[j - 1] == '/') path[--j] = '\0';
}

/* %XX escapes of p -> bytes in out; NULL, or what is wrong */
static const char *percent_decode(const char *p, char *out, size_t n) {
    size_t j = 0;
    for (size_t i = 0; p[i]; i++) {
        char c = p[i];
        if (c == '%') {
            int hi = hexval(p[i + 1]), lo = hi >= 0 ? hexval(p[i + 2]) : -1;
            if (hi < 0 || lo < 0) return "has an invalid percent-escape";
            c = (char)(hi * 16 + lo);
            i += 2;
            if (c == '\0') return "encodes a NUL byte";
        }
        if (j + 1 >= n) return "is too long";
        out[j++] = c;
    }
    out[j] = '\0';
    strip_slashes(out);
    return NULL;
}

#if defined(_WIN32)
/* "/C:/x" (the path of file:///C:/x) -> "C:/x" */
static void drop_slash_before_drive(char *path) {
    if (path[0] == '/' && isalpha((unsigned char)path[1]) && path[2] == ':')
        memmove(path, path + 1, strlen(path));
}
#define IS_ABSOLUTE(p) ((p)[0] == '/' || (p)[0] == '\\' || (isalpha((unsigned char)(p)[0]) && (p)[1] == ':'))
#else
#define drop_slash_before_drive(path) ((void)(path))
#define IS_ABSOLUTE(p) ((p)[0] == '/')
#endif

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
    if (!IS_ABSOLUTE(p)) {
        snprintf(err, en, "fmuResourceLocation '%s' is not an absolute file URI", uri);
        return 0;
    }
    const char *why = percent_decode(p, out, n);
    if (!why) drop_slash_before_drive(out);
    if (!why && is_dir(out)) return 1;
    /* a host that wrote the path into the URI without encoding it */
    if (strlen(p) < n) {
        strcpy(out, p);
        strip_slashes(out);
        drop_slash_before_drive(out);
        if (is_dir(out)) return 1;
    }
    if (why)
        snprintf(err, en, "fmuResourceLocation '%s' %s", uri, why);
    else
        snprintf(err, en, "fmuResourceLocation '%s': no such directory", uri);
    return 0;
}

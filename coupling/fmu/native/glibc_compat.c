/* The glibc baseline of the Linux binaries (x86-64 and AArch64): glibc 2.17 (manylinux2014).
 *
 * glibc 2.27 and 2.29 gave exp, log, pow, exp2 and log2 (and their float forms) new symbol
 * versions; a binary linked on a newer system binds to those and no longer loads on glibc
 * 2.17-2.28 (CentOS 7, RHEL 8, Debian 10, Ubuntu 18.04, Amazon Linux 2).  The link
 * (native_build.link_binary) passes -Wl,--wrap=<name> for each of them: every reference, the C
 * files' and the compiled kernels' alike, goes to __wrap_<name> below, which calls the oldest
 * version of the function, the one glibc 2.17 has.  A newer glibc keeps that version as a
 * compatibility symbol whose result is its current implementation's (it adds only the old errno
 * handling), so a result here can differ from an old glibc's only in the last bit.
 *
 * Only for x86-64 and AArch64 Linux with glibc; elsewhere (mingw-w64) this file is empty. */
#include <math.h>   /* first: it defines __GLIBC__ */

#if defined(__linux__) && defined(__GLIBC__) && (defined(__x86_64__) || defined(__aarch64__))

/* the first version of each function on the target: glibc's first release for it */
#if defined(__x86_64__)
#define HB_FIRST_VERSION "GLIBC_2.2.5"
#else
#define HB_FIRST_VERSION "GLIBC_2.17"
#endif
#define HB_OLD_VERSION(name) __asm__(".symver " #name "," #name "@" HB_FIRST_VERSION)
HB_OLD_VERSION(exp);
HB_OLD_VERSION(log);
HB_OLD_VERSION(pow);
HB_OLD_VERSION(exp2);
HB_OLD_VERSION(log2);
HB_OLD_VERSION(expf);
HB_OLD_VERSION(logf);
HB_OLD_VERSION(powf);
HB_OLD_VERSION(exp2f);
HB_OLD_VERSION(log2f);
#undef HB_OLD_VERSION

double __wrap_exp(double x) { return exp(x); }
double __wrap_log(double x) { return log(x); }
double __wrap_pow(double x, double y) { return pow(x, y); }
double __wrap_exp2(double x) { return exp2(x); }
double __wrap_log2(double x) { return log2(x); }
float __wrap_expf(float x) { return expf(x); }
float __wrap_logf(float x) { return logf(x); }
float __wrap_powf(float x, float y) { return powf(x, y); }
float __wrap_exp2f(float x) { return exp2f(x); }
float __wrap_log2f(float x) { return log2f(x); }
#else
typedef int hb_glibc_compat_unused;   /* ISO C: a translation unit is not empty */
#endif

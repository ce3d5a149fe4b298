/* Pieces every bench program shares: the machine line printed with each table (the CPU model from
 * /proc/cpuinfo, the core count, the load average), medians and percentiles of a sample, the exit
 * on a fatal error and the --methods list (name[:key=value...] specs).
 *
 * Header-only on purpose: CMake builds every .c file of bench/ as a program of its own, so the shared code
 * lives here as static inline functions, written once. */
#ifndef SL_BENCH_COMMON_H
#define SL_BENCH_COMMON_H

#include "sightline/cull.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The "model name" of the first processor in /proc/cpuinfo, or "unknown CPU". */
static inline void bench_cpu_model(char *out, size_t size)
{
    snprintf(out, size, "unknown CPU");
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f)
        return;
    char line[512];
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "model name", 10)) {
            char *p = strchr(line, ':');
            if (p) {
                p++;
                while (*p == ' ' || *p == '\t')
                    p++;
                p[strcspn(p, "\n")] = 0;
                snprintf(out, size, "%s", p);
            }
            break;
        }
    fclose(f);
}

/* "N cores (nproc), MODEL, load average A B C" (load -1 where getloadavg fails). */
static inline void bench_machine(char *out, size_t size)
{
    char model[160];
    bench_cpu_model(model, sizeof model);
    double load[3] = {0, 0, 0};
    if (getloadavg(load, 3) < 0)
        load[0] = load[1] = load[2] = -1;
    snprintf(out, size, "%ld cores (nproc), %s, load average %.2f %.2f %.2f", sysconf(_SC_NPROCESSORS_ONLN), model,
             load[0], load[1], load[2]);
}

static inline int bench_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The p-quantile (0..1, nearest rank) of v[0..n); sorts v. 0 for an empty sample. */
static inline double bench_percentile(double *v, size_t n, double p)
{
    if (n == 0)
        return 0;
    qsort(v, n, sizeof *v, bench_cmp_double);
    size_t k = (size_t)ceil(p * (double)n);
    return v[k ? k - 1 : 0];
}

/* The median of v[0..n) (the mean of the middle two for even n); sorts v. 0 for an empty sample. */
static inline double bench_median(double *v, size_t n)
{
    if (!n)
        return 0;
    qsort(v, n, sizeof *v, bench_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* "PROG: WHAT[: the error's message]" on stderr, exit status 2. */
static inline void bench_die(const char *prog, const char *what, const sl_error *err)
{
    fprintf(stderr, "%s: %s%s%s\n", prog, what, err ? ": " : "", err ? err->message : "");
    exit(2);
}

/* One method of a --methods list. */
typedef struct bench_method_spec {
    char spec[256];  /* as given */
    char name[64];   /* the registry name */
    char opts[320];  /* key=value,... for sl_culler_create */
    bool threaded;   /* takes threads= (and got threads=T unless the spec set its own) */
} bench_method_spec;

/* "name[:key=value[:key=value...]]" (the list itself is comma-separated, so options are separated
 * by colons here) into m; with threads > 0 the options get threads=T where the method takes it.
 * edit (may be NULL) rewrites the options (comma-separated, in place) before they are checked.
 * Options the method refuses: bench_die. */
static inline void bench_method_parse(const char *prog, const char *spec, uint32_t threads, void (*edit)(char *opts),
                                      bench_method_spec *m)
{
    memset(m, 0, sizeof *m);
    snprintf(m->spec, sizeof m->spec, "%s", spec);
    const char *colon = strchr(spec, ':');
    size_t nl = colon ? (size_t)(colon - spec) : strlen(spec);
    snprintf(m->name, sizeof m->name, "%.*s", (int)nl, spec);
    char ob[256];
    snprintf(ob, sizeof ob, "%s", colon ? colon + 1 : "");
    for (char *c = ob; *c; c++)
        if (*c == ':')
            *c = ',';
    if (edit)
        edit(ob);
    char probe[290];
    if (strstr(ob, "threads=") || threads == 0)
        snprintf(probe, sizeof probe, "%s", ob); /* the spec sets its own thread count */
    else
        snprintf(probe, sizeof probe, "threads=%u%s%s", threads, *ob ? "," : "", ob);
    sl_error err;
    m->threaded = sl_cull_method_check_options(m->name, probe, &err) == SL_OK;
    snprintf(m->opts, sizeof m->opts, "%s", m->threaded ? probe : ob);
    if (!m->threaded && sl_cull_method_check_options(m->name, m->opts, &err) != SL_OK)
        bench_die(prog, spec, &err);
}

/* The comma-separated list (NULL: the nd defaults) into out[0..max); returns how many. */
static inline uint32_t bench_methods_parse(const char *prog, const char *list, const char *const *defaults, size_t nd,
                                           uint32_t threads, void (*edit)(char *opts), bench_method_spec *out,
                                           uint32_t max)
{
    uint32_t n = 0;
    if (list) {
        char buf[1024];
        snprintf(buf, sizeof buf, "%s", list);
        for (char *t = strtok(buf, ","); t && n < max; t = strtok(NULL, ","))
            bench_method_parse(prog, t, threads, edit, &out[n++]);
    } else {
        for (size_t i = 0; i < nd && n < max; i++)
            bench_method_parse(prog, defaults[i], threads, edit, &out[n++]);
    }
    return n;
}

#endif

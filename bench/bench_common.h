/* Pieces every bench program shares: the machine line printed with each table (the CPU model from
 * /proc/cpuinfo, the core count, the load average) and medians and percentiles of a sample.
 *
 * Header-only on purpose: CMake builds every .c file of bench/ as a program of its own, so the shared code
 * lives here as static inline functions, written once. */
#ifndef SL_BENCH_COMMON_H
#define SL_BENCH_COMMON_H

#include <math.h>
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

#endif

/* Occlusion rasterizer throughput at 1920x1080 on one thread, per instruction-set path, against the
 * figures of Intel's Masked Occlusion Culling (AVX2) measured on this machine type (issue 4, 3):
 *   - random equal-size triangles whose bounding squares are 10..500 pixels, submitted back to
 *     front so that every one passes the depth test, none clipped: million triangles per second;
 *   - clearing the buffer: milliseconds;
 *   - rectangle queries of 9x5 .. 480x270 pixels behind a full-screen occluder (every answer is
 *     OCCLUDED, so every pixel is read: the worst case): nanoseconds per query.
 * Each figure is the median of several runs. Prints the machine and a Markdown table per path,
 * with ratio = Sightline / MOC for throughput, MOC / Sightline for times (above 1 = faster).
 *
 * usage: bench_raster_throughput [--runs N] [--quick] [--threads N] [--isa NAME]...
 *   --runs N     runs per figure (default 7); --quick: 3 runs, fewer triangles
 *   --threads N  also report triangle throughput with the built-in pool of N threads (AVX2/best)
 *   --isa NAME   only this path (scalar, sse41, avx2, avx512); may repeat
 *   --size N     only the triangle figure for bounding squares of N pixels (one of the sizes
 *                above), no clear or query figures: for profiling one size */
#include "core/sl_core.h"
#include "sightline/raster.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "bench_common.h"

#define W 1920
#define H 1080

static const int sizes[] = {10, 25, 50, 100, 250, 500};
/* MOC, AVX2, on this machine type (issue 4): ranges; the ratio uses the better end */
static const double moc_mtri_lo[] = {20, 15, 7, 3.7, 1.2, 0.43};
static const double moc_mtri_hi[] = {23, 16, 9, 3.7, 1.4, 0.58};
static const double moc_clear_ms = 0.071;
static const int qsizes[][2] = {{9, 5}, {48, 27}, {192, 108}, {480, 270}};
static const double moc_query_ns[] = {23, 33, 110, 526};

/* Single-thread figures use the thread's CPU time: on a shared machine, time spent descheduled
 * is not the rasterizer's. The pool's figures are wall time (what a caller waits), and the
 * process CPU time shows how much work the threads did in all. */
enum { CLOCK_THREAD, CLOCK_WALL, CLOCK_PROCESS };
static int which_clock = CLOCK_THREAD;

static double now(void)
{
    if (which_clock == CLOCK_WALL)
        return sl_now();
    struct timespec ts;
    clock_gettime(which_clock == CLOCK_PROCESS ? CLOCK_PROCESS_CPUTIME_ID : CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void perspective(float m[16], double fovy, double aspect, double n, double f)
{
    memset(m, 0, sizeof(float) * 16);
    double t = 1.0 / tan(0.5 * fovy);
    m[0] = (float)(t / aspect);
    m[5] = (float)t;
    m[10] = (float)((f + n) / (n - f));
    m[11] = -1.0f;
    m[14] = (float)(2.0 * f * n / (n - f));
}

/* Eye-space position of pixel (px, py) at distance dist for projection P. */
static void unproject(const float P[16], double px, double py, double dist, float out[3])
{
    double nx = px / (W / 2.0) - 1.0, ny = 1.0 - py / (H / 2.0);
    out[0] = (float)(nx * dist / P[0]);
    out[1] = (float)(ny * dist / P[5]);
    out[2] = (float)-dist;
}

/* n triangles with S x S bounding squares, random positions, farthest first. */
static void make_stream(const float P[16], int S, uint32_t n, uint64_t seed, float *v, uint32_t *ix)
{
    sl_rng rng;
    sl_rng_seed(&rng, seed, (uint64_t)S);
    for (uint32_t t = 0; t < n; t++) {
        double x0 = sl_rng_range(&rng, 0, (float)(W - S)), y0 = sl_rng_range(&rng, 0, (float)(H - S));
        double u = sl_rng_float(&rng), w = sl_rng_float(&rng);
        double dist = 900.0 - 890.0 * (double)t / (double)n; /* nearer and nearer */
        unproject(P, x0, y0, dist, v + 9 * t);
        unproject(P, x0 + S, y0 + u * S, dist, v + 9 * t + 3);
        unproject(P, x0 + w * S, y0 + S, dist, v + 9 * t + 6);
        for (int k = 0; k < 3; k++)
            ix[3 * t + k] = 3 * t + (uint32_t)k;
    }
}

static sl_raster *make(sl_raster_isa isa, uint32_t threads)
{
    sl_raster_options o = sl_raster_default_options(W, H);
    o.isa = isa;
    o.threads = threads;
    sl_raster *r = NULL;
    sl_error err;
    if (sl_raster_create(&o, NULL, &r, &err) != SL_OK) {
        fprintf(stderr, "bench_raster_throughput: %s\n", err.message);
        exit(1);
    }
    return r;
}

static uint32_t stream_len(int S, bool quick)
{
    double n = 4e8 / ((double)S * S);
    n = n < 2000 ? 2000 : (n > 400000 ? 400000 : n);
    return (uint32_t)(quick ? n / 4 : n);
}

/* Median Mtri/s of rendering the stream for size S. */
static double throughput(sl_raster *r, const float P[16], int S, int runs, bool quick)
{
    uint32_t n = stream_len(S, quick);
    float *v = malloc(sizeof(float) * 9 * n);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * n);
    if (!v || !ix) {
        fprintf(stderr, "bench_raster_throughput: out of memory\n");
        exit(1);
    }
    make_stream(P, S, n, 1234, v, ix);
    double t[64];
    for (int i = 0; i < runs; i++) {
        sl_raster_clear(r);
        double t0 = now();
        sl_raster_render_triangles(r, v, 3 * n, ix, n, 12, P, SL_RASTER_CULL_NONE, NULL);
        t[i] = (double)n / (now() - t0) * 1e-6;
    }
    sl_raster_stats st;
    sl_raster_get_stats(r, &st);
    if (st.clipped || st.triangles_rasterized != n) {
        fprintf(stderr, "bench_raster_throughput: stream %d: %llu of %u rasterized, %llu clipped\n", S,
                (unsigned long long)st.triangles_rasterized, n, (unsigned long long)st.clipped);
        exit(1);
    }
    free(v);
    free(ix);
    return bench_median(t, runs);
}

static double clear_ms(sl_raster *r, int runs)
{
    double t[64];
    const int reps = 2000;
    for (int i = 0; i < runs; i++) {
        double t0 = now();
        for (int k = 0; k < reps; k++)
            sl_raster_clear(r);
        t[i] = (now() - t0) / reps * 1e3;
    }
    return bench_median(t, runs);
}

/* Median ns per rectangle query behind a full-screen occluder; every answer must be OCCLUDED. */
static double query_ns(sl_raster *r, const float P[16], int qw, int qh, int runs)
{
    sl_raster_clear(r);
    float wall[12];
    unproject(P, -10, -10, 10, wall);
    unproject(P, W + 10, -10, 10, wall + 3);
    unproject(P, W + 10, H + 10, 10, wall + 6);
    unproject(P, -10, H + 10, 10, wall + 9);
    uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
    sl_raster_render_triangles(r, wall, 4, ix, 2, 12, P, SL_RASTER_CULL_NONE, NULL);
    enum { NQ = 1024 };
    int32_t qx[NQ], qy[NQ];
    sl_rng rng;
    sl_rng_seed(&rng, 99, (uint64_t)qw);
    for (int i = 0; i < NQ; i++) {
        qx[i] = (int32_t)sl_rng_below(&rng, (uint32_t)(W - qw));
        qy[i] = (int32_t)sl_rng_below(&rng, (uint32_t)(H - qh));
    }
    const float depth = 1.0f / 20.0f; /* behind the wall at distance 10 */
    int reps = qw * qh > 20000 ? 20 : 200;
    double t[64];
    unsigned occluded = 0;
    for (int i = 0; i < runs; i++) {
        occluded = 0;
        double t0 = now();
        for (int k = 0; k < reps; k++)
            for (int q = 0; q < NQ; q++)
                occluded += sl_raster_test_rect(r, qx[q], qy[q], qx[q] + qw, qy[q] + qh, depth) == SL_RASTER_OCCLUDED;
        t[i] = (now() - t0) / ((double)reps * NQ) * 1e9;
    }
    if (occluded != (unsigned)(reps * NQ)) {
        fprintf(stderr, "bench_raster_throughput: %ux%u query: %u of %d occluded (not tight)\n", qw, qh, occluded,
                reps * NQ);
        exit(1);
    }
    return bench_median(t, runs);
}

int main(int argc, char **argv)
{
    int runs = 7;
    bool quick = false;
    uint32_t threads = 0;
    sl_raster_isa only[8];
    int nonly = 0, only_size = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--runs") && i + 1 < argc) {
            runs = atoi(argv[++i]);
            if (runs < 1 || runs > 64) {
                fprintf(stderr, "bench_raster_throughput: --runs must be 1..64\n");
                return 2;
            }
        } else if (!strcmp(argv[i], "--quick")) {
            quick = true;
            runs = 3;
        } else if (!strcmp(argv[i], "--threads") && i + 1 < argc) {
            threads = (uint32_t)atoi(argv[++i]);
        } else if (!strcmp(argv[i], "--size") && i + 1 < argc) {
            only_size = atoi(argv[++i]);
            bool known = false;
            for (size_t s = 0; s < SL_COUNTOF(sizes); s++)
                known |= sizes[s] == only_size;
            if (!known) {
                fprintf(stderr, "bench_raster_throughput: --size must be 10, 25, 50, 100, 250 or 500\n");
                return 2;
            }
        } else if (!strcmp(argv[i], "--isa") && i + 1 < argc && nonly < 8) {
            const char *n = argv[++i];
            sl_raster_isa isa = !strcmp(n, "scalar") ? SL_RASTER_ISA_SCALAR
                                : !strcmp(n, "sse41") ? SL_RASTER_ISA_SSE41
                                : !strcmp(n, "avx2")  ? SL_RASTER_ISA_AVX2
                                : !strcmp(n, "avx512") ? SL_RASTER_ISA_AVX512
                                                      : SL_RASTER_ISA_AUTO;
            if (isa == SL_RASTER_ISA_AUTO) {
                fprintf(stderr, "bench_raster_throughput: unknown path %s\n", n);
                return 2;
            }
            only[nonly++] = isa;
        } else {
            fprintf(stderr, "usage: %s [--runs N] [--quick] [--threads N] [--isa scalar|sse41|avx2|avx512]... [--size N]\n",
                    argv[0]);
            return 2;
        }
    }
    char cpu[256];
    bench_cpu_model(cpu, sizeof cpu);
    printf("# Occlusion rasterizer, %dx%d, one thread\n\n", W, H);
    printf("machine: nproc %ld, CPU %s; median of %d runs; single-thread times are thread CPU time\n\n",
           sysconf(_SC_NPROCESSORS_ONLN), cpu, runs);

    float P[16];
    perspective(P, 1.0, (double)W / H, 0.5, 1000);
    sl_raster_isa paths[] = {SL_RASTER_ISA_SCALAR, SL_RASTER_ISA_SSE41, SL_RASTER_ISA_AVX2, SL_RASTER_ISA_AVX512};
    sl_raster_isa best = SL_RASTER_ISA_SCALAR;
    for (size_t p = 0; p < SL_COUNTOF(paths); p++) {
        sl_raster_isa isa = paths[p];
        bool wanted = nonly == 0;
        for (int i = 0; i < nonly; i++)
            wanted |= only[i] == isa;
        if (!wanted)
            continue;
        if (!sl_raster_isa_available(isa)) {
            printf("## %s: not available on this CPU\n\n", sl_raster_isa_name(isa));
            continue;
        }
        best = isa;
        sl_raster *r = make(isa, 1);
        printf("## %s\n\n", sl_raster_isa_name(isa));
        printf("| figure | Sightline | MOC AVX2 | ratio |\n|---|---:|---:|---:|\n");
        for (size_t s = 0; s < SL_COUNTOF(sizes); s++) {
            if (only_size && sizes[s] != only_size)
                continue;
            double m = throughput(r, P, sizes[s], runs, quick);
            printf("| triangles %dx%d (Mtri/s) | %.2f | %g-%g | %.2fx |\n", sizes[s], sizes[s], m, moc_mtri_lo[s],
                   moc_mtri_hi[s], m / moc_mtri_hi[s]);
            fflush(stdout);
        }
        if (only_size) {
            printf("\n");
            sl_raster_destroy(r);
            continue;
        }
        double c = clear_ms(r, runs);
        printf("| clear (ms) | %.4f | %.3f | %.2fx |\n", c, moc_clear_ms, moc_clear_ms / c);
        for (size_t q = 0; q < SL_COUNTOF(qsizes); q++) {
            double ns = query_ns(r, P, qsizes[q][0], qsizes[q][1], runs);
            printf("| query %dx%d, occluded (ns) | %.1f | %g | %.2fx |\n", qsizes[q][0], qsizes[q][1], ns,
                   moc_query_ns[q], moc_query_ns[q] / ns);
        }
        printf("\n");
        sl_raster_destroy(r);
    }
    if (threads > 1) {
        printf("## %s, built-in pool of %u threads\n\n", sl_raster_isa_name(best), threads);
        printf("| figure | wall clock | per CPU second of all threads |\n|---|---:|---:|\n");
        sl_raster *r = make(best, threads);
        for (size_t s = 0; s < SL_COUNTOF(sizes); s++) {
            if (only_size && sizes[s] != only_size)
                continue;
            which_clock = CLOCK_WALL;
            double wall = throughput(r, P, sizes[s], runs, quick);
            which_clock = CLOCK_PROCESS;
            double per_cpu = throughput(r, P, sizes[s], runs, quick);
            printf("| triangles %dx%d (Mtri/s) | %.2f | %.2f |\n", sizes[s], sizes[s], wall, per_cpu);
        }
        which_clock = CLOCK_THREAD;
        printf("\n");
        sl_raster_destroy(r);
    }
    if (only_size)
        return 0;
    /* memory of a context at 1920x1080: single-threaded, and with a 2-thread pool after binning
     * the largest stream (queue storage is kept for reuse) */
    sl_raster *r = make(SL_RASTER_ISA_AUTO, 1);
    printf("memory: context at %dx%d, one thread: %.1f KiB (buffer %.1f KiB: 96 bytes per 32x8 tile)\n", W, H,
           sl_raster_memory(r) / 1024.0, (double)((W + 31) / 32) * ((H + 7) / 8) * 96 / 1024.0);
    sl_raster_destroy(r);
    r = make(SL_RASTER_ISA_AUTO, 2);
    throughput(r, P, sizes[0], 1, quick);
    printf("memory: context at %dx%d, pool of 2 threads, after a %u-triangle batch: %.1f KiB\n", W, H,
           stream_len(sizes[0], quick), sl_raster_memory(r) / 1024.0);
    sl_raster_destroy(r);
    return 0;
}

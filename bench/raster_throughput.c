/* Occlusion rasterizer throughput at 1920x1080 on one thread, per instruction-set path:
 *   - random equal-size triangles whose bounding squares are 10..500 pixels, submitted back to
 *     front so that every one passes the depth test, none clipped: million triangles per second;
 *   - clearing the buffer: milliseconds (microseconds side by side; Sightline's clear is lazy: it
 *     marks the tile rows empty, and a row gets its zeros when the first occluder reaches it);
 *   - rectangle queries of 9x5 .. 480x270 pixels behind a full-screen occluder (every answer is
 *     OCCLUDED, so every pixel is read: the worst case): nanoseconds per query.
 * Each figure is the median of several runs. Prints the machine and a Markdown table per path.
 *
 * With --peer moc (a build configured with -DSL_MOC_DIR=<checkout of Intel's Masked Occlusion
 * Culling>, docs/rasterizer.md) every figure is measured side by side: both libraries get the same
 * vertex array, indices, matrix, order and backface setting, each forced to the same instruction set
 * (checked on both sides), run alternately Sightline/MOC in this process, timed by thread CPU time;
 * the table gives each side's median [min-max] and the median [min-max] of the per-pair ratio
 * MOC time / Sightline time (above 1 = Sightline faster). Two triangle shapes: Sightline's (above) and
 * MOC's FillrateTest shape (right triangles with S-pixel legs, randomly rotated in NDC as FillrateTest
 * does). Without a peer nothing but Sightline's figures is printed: no peer figure is typed in.
 *
 * usage: bench_raster_throughput [--runs N] [--quick] [--smoke] [--threads N] [--isa NAME]... [--size N]
 *                                [--coverage center|inner]
 *                                [--peer moc [--pairs N] [--list] [--peer-clip all|none]
 *                                            [--part triangles|clear|queries]
 *                                            [--city tiny|small|vienna [--views N]]]
 *   --runs N     runs per figure (default 7); --quick: 3 runs, fewer triangles; --smoke: one run of
 *                tiny streams on the best path (a test that the program works, no figures to keep)
 *   --threads N  also report triangle throughput with the built-in pool of N threads (AVX2/best),
 *                and the pool against one thread on 100,000-triangle frames (wall clock, alternating)
 *   --isa NAME   only this path (scalar, sse41, avx2, avx512); may repeat
 *   --size N     only the triangle figure for bounding squares of N pixels (one of the sizes
 *                above), no clear or query figures: for profiling one size
 *   --coverage inner  Sightline with SL_RASTER_COVERAGE_INNER (the resolution-independent rule of
 *                res=any; MOC has no such mode and keeps its own): its own rows, no target
 *   --part P     with --peer: only the triangle, clear or query rows
 *   --peer moc   side by side with MOC (sse41, avx2, avx512 paths); --pairs N: Sightline/MOC pairs
 *                per figure (default 15); --list: print every pair's ratio; --peer-clip none: MOC
 *                renders the triangle streams with CLIP_PLANE_NONE (as its FillrateTest does: the
 *                caller vouches that nothing needs clipping; Sightline has no such switch), default
 *                all (CLIP_PLANE_ALL, MOC's default)
 *   --city P     instead of the tables above, the city workload as MOC recommends it (front-to-back
 *                object boxes, a query before each draw, draw only what passed) on the generated
 *                city P: N street views (frames of the bench walk, default 100) and the same views
 *                raised 30 m and pitched down; time per view and boxes drawn by each */
#include "core/sl_core.h"
#include "sightline/camera.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/raster.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "bench_common.h"
#ifdef SL_HAVE_MOC
#include "moc_peer.h"
#endif
#ifdef SL_HAVE_BENCH_BUILD_H
#include "bench_build.h" /* SL_BENCH_BUILD: build type, compilers and flags (written by CMake) */
#else
#define SL_BENCH_BUILD "unknown build"
#endif

#define W 1920
#define H 1080

static const int sizes[] = {10, 25, 50, 100, 250, 500};
static const int qsizes[][2] = {{9, 5}, {48, 27}, {192, 108}, {480, 270}};
/* Vertices are 4 floats (x, y, z, z): Sightline reads (x, y, z) at offsets 0, 4, 8, MOC with a
 * matrix reads its model z at offset 12 (its fast layout: stride 16, y at 4, w/z at 12), so both
 * libraries read the same array on their fast paths. */
#define VSTRIDE 16
#define VFLOATS 4
static bool smoke; /* --smoke: tiny streams, one run */

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

enum { SHAPE_SL = 0, SHAPE_FILLRATE = 1 };

static void put_vertex(const float P[16], double px, double py, double dist, float *v)
{
    unproject(P, px, py, dist, v);
    v[3] = v[2];
}

/* n triangles of size S, farthest first (every one passes the depth test), none clipped:
 *   SHAPE_SL: random positions, S x S bounding squares (one corner, a point on the right edge and
 *     one on the bottom edge);
 *   SHAPE_FILLRATE: MOC's FillrateTest shape: the right triangle (0,0), (S,0), (0,S) pixels written
 *     in NDC, rotated by a random angle in NDC around its first vertex, placed at a random NDC
 *     point, redrawn until it lies on the screen. */
static void make_stream(const float P[16], int shape, int S, uint32_t n, uint64_t seed, float *v, uint32_t *ix)
{
    sl_rng rng;
    sl_rng_seed(&rng, seed + (uint64_t)shape * 7919u, (uint64_t)S);
    for (uint32_t t = 0; t < n; t++) {
        double dist = 900.0 - 890.0 * (double)t / (double)n; /* nearer and nearer */
        float *tv = v + 3 * VFLOATS * t;
        if (shape == SHAPE_SL) {
            double x0 = sl_rng_range(&rng, 0, (float)(W - S)), y0 = sl_rng_range(&rng, 0, (float)(H - S));
            double u = sl_rng_float(&rng), w = sl_rng_float(&rng);
            put_vertex(P, x0, y0, dist, tv);
            put_vertex(P, x0 + S, y0 + u * S, dist, tv + VFLOATS);
            put_vertex(P, x0 + w * S, y0 + S, dist, tv + 2 * VFLOATS);
        } else {
            const double leg[3][2] = {{0, 0}, {2.0 * S / W, 0}, {0, 2.0 * S / H}};
            double nx[3], ny[3];
            for (;;) {
                double ox = sl_rng_float(&rng) * 2.0 - 1.0, oy = sl_rng_float(&rng) * 2.0 - 1.0;
                double a = sl_rng_float(&rng) * 2.0 * 3.14159265358979323846;
                bool ok = true;
                for (int k = 0; k < 3; k++) {
                    nx[k] = cos(a) * leg[k][0] - sin(a) * leg[k][1] + ox;
                    ny[k] = sin(a) * leg[k][0] + cos(a) * leg[k][1] + oy;
                    ok &= nx[k] >= -1 && nx[k] <= 1 && ny[k] >= -1 && ny[k] <= 1;
                }
                if (ok)
                    break;
            }
            for (int k = 0; k < 3; k++)
                put_vertex(P, (nx[k] + 1.0) * (W / 2.0), (1.0 - ny[k]) * (H / 2.0), dist, tv + VFLOATS * k);
        }
        for (int k = 0; k < 3; k++)
            ix[3 * t + k] = 3 * t + (uint32_t)k;
    }
}

/* --coverage inner: Sightline's resolution-independent rule (SL_RASTER_COVERAGE_INNER) */
static sl_raster_coverage coverage = SL_RASTER_COVERAGE_CENTER;
/* --part: the peer table's rows (bit 1 triangles, 2 clear, 4 queries) */
static unsigned parts = 7;

static sl_raster *make(sl_raster_isa isa, uint32_t threads)
{
    sl_raster_options o = sl_raster_default_options(W, H);
    o.isa = isa;
    o.coverage = coverage;
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
    if (smoke)
        return (uint32_t)(n / 100 < 200 ? 200 : n / 100);
    return (uint32_t)(quick ? n / 4 : n);
}

static void *xmalloc(size_t size)
{
    void *p = malloc(size);
    if (!p) {
        fprintf(stderr, "bench_raster_throughput: out of memory\n");
        exit(1);
    }
    return p;
}

/* Render the stream once on a cleared buffer; exits unless every triangle was rasterized unclipped. */
static double render_once(sl_raster *r, const float P[16], const float *v, const uint32_t *ix, uint32_t n, int S)
{
    sl_raster_clear(r);
    double t0 = now();
    sl_raster_render_triangles(r, v, 3 * n, ix, n, VSTRIDE, P, SL_RASTER_CULL_NONE, NULL);
    double t = now() - t0;
    sl_raster_stats st;
    sl_raster_get_stats(r, &st);
    if (st.clipped || st.triangles_rasterized != n) {
        fprintf(stderr, "bench_raster_throughput: stream %d: %llu of %u rasterized, %llu clipped\n", S,
                (unsigned long long)st.triangles_rasterized, n, (unsigned long long)st.clipped);
        exit(1);
    }
    return t;
}

/* Median Mtri/s of rendering the stream for size S (Sightline's shape). */
static double throughput(sl_raster *r, const float P[16], int S, int runs, bool quick)
{
    uint32_t n = stream_len(S, quick);
    float *v = xmalloc(sizeof(float) * 3 * VFLOATS * n);
    uint32_t *ix = xmalloc(sizeof(uint32_t) * 3 * n);
    make_stream(P, SHAPE_SL, S, n, 1234, v, ix);
    double t[64];
    for (int i = 0; i < runs; i++)
        t[i] = (double)n / render_once(r, P, v, ix, n, S) * 1e-6;
    free(v);
    free(ix);
    return bench_median(t, runs);
}

static double clear_ms(sl_raster *r, int runs)
{
    double t[64];
    const int reps = smoke ? 10 : 2000;
    for (int i = 0; i < runs; i++) {
        double t0 = now();
        for (int k = 0; k < reps; k++)
            sl_raster_clear(r);
        t[i] = (now() - t0) / reps * 1e3;
    }
    return bench_median(t, runs);
}

/* The full-screen occluder of the query figures: a quad beyond the screen's edges at distance 10. */
static void make_wall(const float P[16], float wall[4 * VFLOATS])
{
    put_vertex(P, -10, -10, 10, wall);
    put_vertex(P, W + 10, -10, 10, wall + VFLOATS);
    put_vertex(P, W + 10, H + 10, 10, wall + 2 * VFLOATS);
    put_vertex(P, -10, H + 10, 10, wall + 3 * VFLOATS);
}
static const uint32_t wall_ix[6] = {0, 1, 2, 0, 2, 3};
#define QUERY_DIST 20.0f /* behind the wall */
enum { NQ = 1024 };

static void query_positions(int qw, int qh, int32_t *qx, int32_t *qy)
{
    sl_rng rng;
    sl_rng_seed(&rng, 99, (uint64_t)qw);
    for (int i = 0; i < NQ; i++) {
        qx[i] = (int32_t)sl_rng_below(&rng, (uint32_t)(W - qw));
        qy[i] = (int32_t)sl_rng_below(&rng, (uint32_t)(H - qh));
    }
}

static int query_reps(int qw, int qh) { return smoke ? 1 : qw * qh > 20000 ? 20 : 200; }

/* Seconds for reps x NQ queries; counts the OCCLUDED answers. */
static double query_once(const sl_raster *r, int qw, int qh, const int32_t *qx, const int32_t *qy, unsigned *occluded)
{
    const float depth = 1.0f / QUERY_DIST;
    int reps = query_reps(qw, qh);
    unsigned occ = 0;
    double t0 = now();
    for (int k = 0; k < reps; k++)
        for (int q = 0; q < NQ; q++)
            occ += sl_raster_test_rect(r, qx[q], qy[q], qx[q] + qw, qy[q] + qh, depth) == SL_RASTER_OCCLUDED;
    double t = now() - t0;
    *occluded = occ;
    return t;
}

static void check_tight(const char *who, int qw, int qh, unsigned occluded)
{
    if (occluded != (unsigned)(query_reps(qw, qh) * NQ)) {
        fprintf(stderr, "bench_raster_throughput: %s %dx%d query: %u of %d occluded (not tight)\n", who, qw, qh,
                occluded, query_reps(qw, qh) * NQ);
        exit(1);
    }
}

/* Median ns per rectangle query behind a full-screen occluder; every answer must be OCCLUDED. */
static double query_ns(sl_raster *r, const float P[16], int qw, int qh, int runs)
{
    sl_raster_clear(r);
    float wall[4 * VFLOATS];
    make_wall(P, wall);
    sl_raster_render_triangles(r, wall, 4, wall_ix, 2, VSTRIDE, P, SL_RASTER_CULL_NONE, NULL);
    int32_t qx[NQ], qy[NQ];
    query_positions(qw, qh, qx, qy);
    double t[64];
    for (int i = 0; i < runs; i++) {
        unsigned occluded;
        t[i] = query_once(r, qw, qh, qx, qy, &occluded) / ((double)query_reps(qw, qh) * NQ) * 1e9;
        check_tight("Sightline", qw, qh, occluded);
    }
    return bench_median(t, runs);
}

#ifdef SL_HAVE_MOC
/* ---- side by side with Intel's Masked Occlusion Culling ---- */

typedef struct pair_sample {
    int n;
    double ours[64], peer[64], ratio[64]; /* seconds per run, and peer / ours per pair */
} pair_sample;

static bool list_pairs;
static int peer_clip = 1; /* --peer-clip all (1) or none (0): MOC's clip planes for the triangle streams */
static const char *const shape_names[] = {"Sightline shape", "FillrateTest shape"};

static void pair_add(pair_sample *ps, double ours, double peer)
{
    ps->ours[ps->n] = ours;
    ps->peer[ps->n] = peer;
    ps->ratio[ps->n] = peer / ours;
    ps->n++;
}

/* "median [min-max]" of v[0..n) scaled by k (rates when inverse: k / v). */
static void print_spread(double *v, int n, double k, bool inverse, const char *fmt)
{
    double w[64];
    for (int i = 0; i < n; i++)
        w[i] = inverse ? k / v[i] : k * v[i];
    double med = bench_median(w, (size_t)n); /* sorts w */
    printf(" ");
    printf(fmt, med);
    printf(" [");
    printf(fmt, w[0]);
    printf("-");
    printf(fmt, w[n - 1]);
    printf("] |");
}

/* A table row: label, Sightline and MOC as rates (k / seconds, inverse) or times (k * seconds), ratio. */
static void print_row(const char *label, pair_sample *ps, double k, bool inverse, const char *fmt)
{
    double ratios[64];
    memcpy(ratios, ps->ratio, sizeof(double) * (size_t)ps->n);
    printf("| %s |", label);
    print_spread(ps->ours, ps->n, k, inverse, fmt);
    print_spread(ps->peer, ps->n, k, inverse, fmt);
    print_spread(ratios, ps->n, 1.0, false, "%.2fx");
    printf("\n");
    if (list_pairs) {
        printf("|   pairs |");
        for (int i = 0; i < ps->n; i++)
            printf(" %.2f", ps->ratio[i]);
        printf(" | | |\n");
    }
    fflush(stdout);
}

static slmoc *make_moc(int isa, uint32_t w, uint32_t h)
{
    slmoc *m = slmoc_create(isa);
    if (!m) {
        fprintf(stderr, "bench_raster_throughput: MOC: out of memory\n");
        exit(1);
    }
    slmoc_set_resolution(m, w, h);
    slmoc_set_near_clip(m, sl_raster_default_options(w, h).near_w); /* Sightline's near_w */
    slmoc_clear(m);
    return m;
}

static int moc_render_stream(slmoc *m, const float *v, const uint32_t *ix, uint32_t n, const float P[16],
                             int backface)
{
    return slmoc_render(m, v, ix, (int)n, P, backface, VSTRIDE, 4, 12, peer_clip);
}

/* Both libraries' winding conventions, checked: a triangle counter-clockwise in NDC is drawn by
 * both with "cull clockwise" and by neither with "cull counter-clockwise". */
static void check_winding(sl_raster *r, slmoc *m, const float P[16])
{
    float tri[3 * VFLOATS];
    put_vertex(P, 0.25 * W, 0.75 * H, 10, tri); /* bottom left, right, top: CCW with y up */
    put_vertex(P, 0.75 * W, 0.75 * H, 10, tri + VFLOATS);
    put_vertex(P, 0.5 * W, 0.25 * H, 10, tri + 2 * VFLOATS);
    const uint32_t ix[3] = {0, 1, 2};
    for (int cull = 1; cull <= 2; cull++) {
        sl_raster_clear(r);
        slmoc_clear(m);
        sl_raster_render_triangles(r, tri, 3, ix, 1, VSTRIDE, P, cull == 1 ? SL_RASTER_CULL_CW : SL_RASTER_CULL_CCW,
                                   NULL);
        slmoc_render(m, tri, ix, 1, P, cull, VSTRIDE, 4, 12, 1);
        bool ours = sl_raster_test_rect(r, W / 2 - 4, H / 2, W / 2 + 4, H / 2 + 4, 1.0f / QUERY_DIST) ==
                    SL_RASTER_OCCLUDED;
        bool peer = slmoc_test_rect(m, -4.0f / W, -8.0f / H, 4.0f / W, 0.0f, QUERY_DIST) == SLMOC_OCCLUDED;
        if (ours != (cull == 1) || peer != (cull == 1)) {
            fprintf(stderr,
                    "bench_raster_throughput: winding conventions differ: with cull %s Sightline %s, MOC %s a CCW "
                    "triangle\n",
                    cull == 1 ? "CW" : "CCW", ours ? "drew" : "culled", peer ? "drew" : "culled");
            exit(1);
        }
    }
    sl_raster_clear(r);
    slmoc_clear(m);
}

static void peer_path(sl_raster_isa isa, int moc_isa, const float P[16], int pairs, bool quick, int only_size)
{
    if (!sl_raster_isa_available(isa)) {
        printf("## %s: not available on this CPU\n\n", sl_raster_isa_name(isa));
        return;
    }
    slmoc *m = make_moc(moc_isa, W, H);
    if (slmoc_isa(m) != moc_isa) {
        printf("## %s: MOC runs %s on this CPU, not %s: not measured\n\n", sl_raster_isa_name(isa),
               slmoc_isa_name(slmoc_isa(m)), slmoc_isa_name(moc_isa));
        slmoc_destroy(m);
        return;
    }
    sl_raster *r = make(isa, 1);
    if (sl_raster_get_isa(r) != isa) {
        fprintf(stderr, "bench_raster_throughput: Sightline runs %s, not %s\n", sl_raster_isa_name(sl_raster_get_isa(r)),
                sl_raster_isa_name(isa));
        exit(1);
    }
    check_winding(r, m, P);
    printf("## %s (Sightline %s%s, MOC %s), %d pairs per row\n\n", sl_raster_isa_name(isa),
           sl_raster_isa_name(sl_raster_get_isa(r)),
           coverage == SL_RASTER_COVERAGE_INNER ? ", INNER coverage (resolution-independent)" : "",
           slmoc_isa_name(slmoc_isa(m)), pairs);
    printf("| figure | Sightline | MOC | MOC time / Sightline time |\n|---|---:|---:|---:|\n");
    char label[128];
    for (int shape = 0; shape < 2 && (parts & 1); shape++)
        for (size_t s = 0; s < SL_COUNTOF(sizes); s++) {
            int S = sizes[s];
            if (only_size && S != only_size)
                continue;
            uint32_t n = stream_len(S, quick);
            float *v = xmalloc(sizeof(float) * 3 * VFLOATS * n);
            uint32_t *ix = xmalloc(sizeof(uint32_t) * 3 * n);
            make_stream(P, shape, S, n, 1234, v, ix);
            pair_sample ps = {0};
            for (int i = 0; i < pairs; i++) {
                double ours = render_once(r, P, v, ix, n, S);
                slmoc_clear(m);
                double t0 = now();
                int res = moc_render_stream(m, v, ix, n, P, 0);
                double peer = now() - t0;
                if (res != SLMOC_VISIBLE) {
                    fprintf(stderr, "bench_raster_throughput: MOC culled the whole %d px stream\n", S);
                    exit(1);
                }
                pair_add(&ps, ours, peer);
            }
            snprintf(label, sizeof label, "triangles %d px, %s (Mtri/s)", S, shape_names[shape]);
            print_row(label, &ps, (double)n * 1e-6, true, "%.2f");
            free(v);
            free(ix);
        }
    if (only_size) {
        printf("\n");
        sl_raster_destroy(r);
        slmoc_destroy(m);
        return;
    }
    /* clear */
    if (parts & 2) {
        const int reps = smoke ? 10 : 2000;
        pair_sample ps = {0};
        for (int i = 0; i < pairs; i++) {
            double t0 = now();
            for (int k = 0; k < reps; k++)
                sl_raster_clear(r);
            double ours = (now() - t0) / reps;
            t0 = now();
            for (int k = 0; k < reps; k++)
                slmoc_clear(m);
            pair_add(&ps, ours, (now() - t0) / reps);
        }
        print_row("clear (us)", &ps, 1e6, false, "%.3f");
    }
    /* rect queries behind a full-screen occluder */
    float wall[4 * VFLOATS];
    make_wall(P, wall);
    sl_raster_clear(r);
    sl_raster_render_triangles(r, wall, 4, wall_ix, 2, VSTRIDE, P, SL_RASTER_CULL_NONE, NULL);
    slmoc_clear(m);
    slmoc_render(m, wall, wall_ix, 2, P, 0, VSTRIDE, 4, 12, 1);
    for (size_t q = 0; q < SL_COUNTOF(qsizes) && (parts & 4); q++) {
        int qw = qsizes[q][0], qh = qsizes[q][1], reps = query_reps(qw, qh);
        int32_t qx[NQ], qy[NQ];
        query_positions(qw, qh, qx, qy);
        float nd[NQ][4]; /* MOC's NDC rectangles: xmin, ymin (bottom), xmax, ymax */
        for (int i = 0; i < NQ; i++) {
            nd[i][0] = (float)(2.0 * qx[i] / W - 1.0);
            nd[i][1] = (float)(1.0 - 2.0 * (qy[i] + qh) / H);
            nd[i][2] = (float)(2.0 * (qx[i] + qw) / W - 1.0);
            nd[i][3] = (float)(1.0 - 2.0 * qy[i] / H);
        }
        pair_sample ps = {0};
        unsigned peer_occ = 0;
        for (int i = 0; i < pairs; i++) {
            unsigned occ;
            double ours = query_once(r, qw, qh, qx, qy, &occ);
            check_tight("Sightline", qw, qh, occ);
            occ = 0;
            double t0 = now();
            for (int k = 0; k < reps; k++)
                for (int j = 0; j < NQ; j++)
                    occ += slmoc_test_rect(m, nd[j][0], nd[j][1], nd[j][2], nd[j][3], QUERY_DIST) == SLMOC_OCCLUDED;
            double peer = now() - t0;
            peer_occ = occ;
            pair_add(&ps, ours / ((double)reps * NQ), peer / ((double)reps * NQ));
        }
        snprintf(label, sizeof label, "query %dx%d, occluded (ns)%s", qw, qh,
                 peer_occ == (unsigned)(reps * NQ) ? "" : " (MOC: not every answer OCCLUDED)");
        print_row(label, &ps, 1e9, false, "%.1f");
    }
    printf("\n");
    sl_raster_destroy(r);
    slmoc_destroy(m);
}

/* ---- the city workload, as MOC recommends using it ----
 * Per view: the objects' world boxes inside the view frustum, nearest first (by the distance from
 * the eye to the box centre; sorted outside the timing, the same order for both), each queried
 * before it is drawn and drawn (as its box: 12 triangles, back faces culled) only when the query
 * says it may be visible. Sightline queries with sl_raster_test_aabb (it projects the box itself);
 * MOC with TestRect, the caller projecting the 8 corners to an NDC rectangle (clamped to the screen)
 * and their nearest w, as MOC's documentation and examples do (inside MOC's timing); a box with a
 * corner nearer than the near plane is drawn without a query on MOC's side (Sightline's test says
 * VISIBLE for it). The same box vertices (x, y, z, z) and indices for both. */
#define CW 1024
#define CH 768
#define CITY_REPS 5 /* Sightline/MOC pairs per view */

typedef struct city_box {
    float d2;
    uint32_t object;
} city_box;

static int cmp_city_box(const void *a, const void *b)
{
    float x = ((const city_box *)a)->d2, y = ((const city_box *)b)->d2;
    return x < y ? -1 : x > y;
}

static uint32_t box_ix[36];

/* 12 triangles over corners c = x | y << 1 | z << 2, counter-clockwise seen from outside. */
static void make_box_indices(void)
{
    static const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    int k = 0;
    for (int f = 0; f < 6; f++) {
        const int *q = quads[f];
        int t[6] = {q[0], q[1], q[2], q[0], q[2], q[3]};
        for (int i = 0; i < 6; i += 3) {
            /* orient outward: normal . (centre of triangle - box centre) > 0 on the unit cube */
            double p[3][3];
            for (int v = 0; v < 3; v++)
                for (int a = 0; a < 3; a++)
                    p[v][a] = (t[i + v] >> a) & 1;
            double e1[3], e2[3], n[3], c[3];
            for (int a = 0; a < 3; a++) {
                e1[a] = p[1][a] - p[0][a];
                e2[a] = p[2][a] - p[0][a];
                c[a] = (p[0][a] + p[1][a] + p[2][a]) / 3.0 - 0.5;
            }
            n[0] = e1[1] * e2[2] - e1[2] * e2[1];
            n[1] = e1[2] * e2[0] - e1[0] * e2[2];
            n[2] = e1[0] * e2[1] - e1[1] * e2[0];
            bool out = n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0;
            box_ix[k++] = (uint32_t)t[i];
            box_ix[k++] = (uint32_t)(out ? t[i + 1] : t[i + 2]);
            box_ix[k++] = (uint32_t)(out ? t[i + 2] : t[i + 1]);
        }
    }
}

typedef struct city_views {
    sl_camera cam[512];
    uint32_t n;
} city_views;

static void city_die(const char *what, const sl_error *err) { bench_die("bench_raster_throughput", what, err); }

/* Sightline's side of one view: time (thread CPU) and boxes drawn. */
static double city_ours(sl_raster *r, const float *bv, const sl_aabb *boxes, const city_box *order, uint32_t n,
                        const float VP[16], uint32_t *drawn)
{
    uint32_t d = 0;
    double t0 = now();
    sl_raster_clear(r);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t o = order[i].object;
        const float lo[3] = {boxes[o].min.x, boxes[o].min.y, boxes[o].min.z};
        const float hi[3] = {boxes[o].max.x, boxes[o].max.y, boxes[o].max.z};
        if (sl_raster_test_aabb(r, lo, hi, VP) != SL_RASTER_VISIBLE)
            continue;
        sl_raster_render_triangles(r, bv + 32 * (size_t)o, 8, box_ix, 12, VSTRIDE, VP, SL_RASTER_CULL_CW, NULL);
        d++;
    }
    double t = now() - t0;
    *drawn = d;
    return t;
}

/* min and max as a C++ caller writes them (std::min/std::max): libm's fminf/fmaxf are calls here,
 * which would count against MOC */
static inline float mn(float a, float b) { return b < a ? b : a; }
static inline float mx(float a, float b) { return a < b ? b : a; }

static double city_moc(slmoc *m, const float *bv, const city_box *order, uint32_t n, const float VP[16], float near_w,
                       uint32_t *drawn)
{
    uint32_t d = 0;
    double t0 = now();
    slmoc_clear(m);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t o = order[i].object;
        const float *c = bv + 32 * (size_t)o;
        float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY, wmin = INFINITY;
        for (int k = 0; k < 8; k++) {
            const float *v = c + 4 * k;
            float x = VP[0] * v[0] + VP[4] * v[1] + VP[8] * v[2] + VP[12];
            float y = VP[1] * v[0] + VP[5] * v[1] + VP[9] * v[2] + VP[13];
            float w = VP[3] * v[0] + VP[7] * v[1] + VP[11] * v[2] + VP[15];
            wmin = mn(wmin, w);
            float iw = 1.0f / w;
            x0 = mn(x0, x * iw);
            x1 = mx(x1, x * iw);
            y0 = mn(y0, y * iw);
            y1 = mx(y1, y * iw);
        }
        if (wmin > near_w) {
            int res = slmoc_test_rect(m, mx(x0, -1.0f), mx(y0, -1.0f), mn(x1, 1.0f), mn(y1, 1.0f), wmin);
            if (res != SLMOC_VISIBLE)
                continue;
        }
        slmoc_render(m, c, box_ix, 12, VP, 1, VSTRIDE, 4, 12, 1);
        d++;
    }
    double t = now() - t0;
    *drawn = d;
    return t;
}

static void city_workload(const char *preset, sl_raster_isa isa, int moc_isa, uint32_t nviews)
{
    if (!sl_raster_isa_available(isa))
        return;
    make_box_indices();
    slmoc *m = make_moc(moc_isa, CW, CH);
    if (slmoc_isa(m) != moc_isa) {
        printf("## city, %s: MOC runs %s on this CPU: not measured\n\n", sl_raster_isa_name(isa),
               slmoc_isa_name(slmoc_isa(m)));
        slmoc_destroy(m);
        return;
    }
    sl_error err;
    sl_city_preset p;
    if (sl_city_preset_from_name(preset, &p, &err) != SL_OK)
        city_die(preset, &err);
    sl_city_options co = sl_city_defaults(p);
    sl_scene scene;
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK)
        city_die("gen city", &err);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.frames = 300;
    po.fps = 5;
    po.seed = 1;
    po.intrinsics.width = CW;
    po.intrinsics.height = CH;
    sl_path walk;
    if (sl_path_generate(scene, &po, NULL, &walk, &err) != SL_OK)
        city_die("walk", &err);
    uint32_t nobj = sl_scene_object_count(scene);
    const sl_aabb *boxes = sl_scene_object_bounds_array(scene);
    float *bv = xmalloc(sizeof(float) * 32 * nobj);
    for (uint32_t o = 0; o < nobj; o++)
        for (int k = 0; k < 8; k++) {
            float *v = bv + 32 * (size_t)o + 4 * k;
            v[0] = k & 1 ? boxes[o].max.x : boxes[o].min.x;
            v[1] = k & 2 ? boxes[o].max.y : boxes[o].min.y;
            v[2] = k & 4 ? boxes[o].max.z : boxes[o].min.z;
            v[3] = v[2];
        }
    city_box *order = xmalloc(sizeof(city_box) * (nobj ? nobj : 1));
    sl_raster_options ro = sl_raster_default_options(CW, CH);
    ro.isa = isa;
    sl_raster *r = NULL;
    if (sl_raster_create(&ro, NULL, &r, &err) != SL_OK)
        city_die("raster", &err);
    if (nviews > 256)
        nviews = 256;
    uint32_t frames = sl_path_count(walk);
    printf("## city workload, %s, %s (Sightline %s, MOC %s): %u objects; %u street views (walk frames) and the "
           "same views 30 m higher, pitched 20 degrees down; %ux%u\n\n",
           preset, sl_raster_isa_name(isa), sl_raster_isa_name(sl_raster_get_isa(r)), slmoc_isa_name(slmoc_isa(m)), nobj,
           nviews, CW, CH);
    printf("| views | boxes in frustum | Sightline ms/view | MOC ms/view | MOC time / Sightline time per view | boxes drawn: "
           "Sightline | boxes drawn: MOC |\n|---|---:|---:|---:|---:|---:|---:|\n");
    for (int kind = 0; kind < 2; kind++) {
        double inview = 0, dours = 0, dpeer = 0;
        static double ours_t[256], peer_t[256], ratio_t[256];
        for (uint32_t v = 0; v < nviews; v++) {
            sl_camera cam = sl_path_camera(walk, (uint32_t)((uint64_t)v * frames / nviews));
            if (kind == 1) {
                cam.position.z += 30.0f;
                cam.pitch = -0.35f;
            }
            sl_mat4 vp = sl_camera_view_proj(&cam);
            sl_frustum fr = sl_camera_frustum(&cam);
            uint32_t n = 0;
            for (uint32_t o = 0; o < nobj; o++) {
                if (!sl_frustum_test_aabb(&fr, &boxes[o]))
                    continue;
                float dx = 0.5f * (boxes[o].min.x + boxes[o].max.x) - cam.position.x;
                float dy = 0.5f * (boxes[o].min.y + boxes[o].max.y) - cam.position.y;
                float dz = 0.5f * (boxes[o].min.z + boxes[o].max.z) - cam.position.z;
                order[n].d2 = dx * dx + dy * dy + dz * dz;
                order[n].object = o;
                n++;
            }
            qsort(order, n, sizeof *order, cmp_city_box);
            slmoc_set_near_clip(m, cam.near_plane);
            uint32_t a = 0, b = 0;
            double to[CITY_REPS], tp[CITY_REPS];
            for (int k = 0; k < CITY_REPS; k++) { /* alternately; per side the median of the repeats */
                to[k] = city_ours(r, bv, boxes, order, n, vp.m, &a);
                tp[k] = city_moc(m, bv, order, n, vp.m, cam.near_plane, &b);
            }
            ours_t[v] = bench_median(to, CITY_REPS);
            peer_t[v] = bench_median(tp, CITY_REPS);
            ratio_t[v] = peer_t[v] / ours_t[v];
            inview += n;
            dours += a;
            dpeer += b;
        }
        double mo = bench_median(ours_t, nviews) * 1e3, mp = bench_median(peer_t, nviews) * 1e3;
        double mr = bench_median(ratio_t, nviews);
        printf("| %s | %.0f | %.3f | %.3f | %.2fx [%.2fx-%.2fx] | %.1f | %.1f |\n", kind ? "elevated" : "street",
               inview / nviews, mo, mp, mr, ratio_t[0], ratio_t[nviews - 1], dours / nviews, dpeer / nviews);
        fflush(stdout);
    }
    printf("\n(per view %d Sightline/MOC pairs, each side's median; times: median over the views; ratio: median "
           "[min-max] over the views; boxes: mean per view)\n\n",
           CITY_REPS);
    free(bv);
    free(order);
    sl_raster_destroy(r);
    slmoc_destroy(m);
    sl_path_destroy(walk);
    sl_scene_destroy(scene);
}
#endif

int main(int argc, char **argv)
{
    int runs = 7;
    bool quick = false;
    uint32_t threads = 0;
    sl_raster_isa only[8];
    int nonly = 0, only_size = 0, pairs = 15, views = 100;
    const char *city = NULL;
    bool peer = false;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--runs") && i + 1 < argc) {
            runs = atoi(argv[++i]);
            if (runs < 1 || runs > 64) {
                fprintf(stderr, "bench_raster_throughput: --runs must be 1..64\n");
                return 2;
            }
        } else if (!strcmp(argv[i], "--smoke")) {
            smoke = true;
            runs = 1;
            pairs = 2;
        } else if (!strcmp(argv[i], "--peer") && i + 1 < argc) {
            const char *name = argv[++i];
            if (strcmp(name, "moc")) {
                fprintf(stderr, "bench_raster_throughput: unknown peer %s (the one peer is moc)\n", name);
                return 2;
            }
#ifndef SL_HAVE_MOC
            fprintf(stderr, "bench_raster_throughput: --peer moc: this build was built without SL_MOC_DIR, so it has "
                            "no MOC to measure; configure with -DSL_MOC_DIR=/path/to/MaskedOcclusionCulling "
                            "(docs/rasterizer.md)\n");
            return 2;
#endif
            peer = true;
        } else if (!strcmp(argv[i], "--pairs") && i + 1 < argc) {
            pairs = atoi(argv[++i]);
            if (pairs < 1 || pairs > 64) {
                fprintf(stderr, "bench_raster_throughput: --pairs must be 1..64\n");
                return 2;
            }
        } else if (!strcmp(argv[i], "--list")) {
#ifdef SL_HAVE_MOC
            list_pairs = true;
#endif
        } else if (!strcmp(argv[i], "--city") && i + 1 < argc) {
            city = argv[++i];
        } else if (!strcmp(argv[i], "--views") && i + 1 < argc) {
            views = atoi(argv[++i]);
            if (views < 1 || views > 256) {
                fprintf(stderr, "bench_raster_throughput: --views must be 1..256\n");
                return 2;
            }
        } else if (!strcmp(argv[i], "--peer-clip") && i + 1 < argc) {
            const char *c = argv[++i];
            if (strcmp(c, "all") && strcmp(c, "none")) {
                fprintf(stderr, "bench_raster_throughput: --peer-clip must be all or none\n");
                return 2;
            }
#ifdef SL_HAVE_MOC
            peer_clip = !strcmp(c, "all");
#endif
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
        } else if (!strcmp(argv[i], "--coverage") && i + 1 < argc) {
            const char *c = argv[++i];
            if (strcmp(c, "center") && strcmp(c, "inner")) {
                fprintf(stderr, "bench_raster_throughput: --coverage must be center or inner\n");
                return 2;
            }
            coverage = strcmp(c, "inner") ? SL_RASTER_COVERAGE_CENTER : SL_RASTER_COVERAGE_INNER;
        } else if (!strcmp(argv[i], "--part") && i + 1 < argc) {
            const char *c = argv[++i];
            parts = !strcmp(c, "triangles") ? 1u : !strcmp(c, "clear") ? 2u : !strcmp(c, "queries") ? 4u : 0u;
            if (!parts) {
                fprintf(stderr, "bench_raster_throughput: --part must be triangles, clear or queries\n");
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
            fprintf(stderr,
                    "usage: %s [--runs N] [--quick] [--smoke] [--threads N] [--isa scalar|sse41|avx2|avx512]... "
                    "[--size N] [--coverage center|inner] [--peer moc [--pairs N] [--list] [--peer-clip all|none] "
                    "[--part triangles|clear|queries] [--city PRESET [--views N]]]\n",
                    argv[0]);
            return 2;
        }
    }
    char machine[320];
    bench_machine(machine, sizeof machine);
    float P[16];
    perspective(P, 1.0, (double)W / H, 0.5, 1000);
#ifdef SL_HAVE_MOC
    if (peer) {
        if (city) {
            printf("# Occlusion culling of a city side by side with Intel's Masked Occlusion Culling, one thread\n\n");
            printf("machine: %s; thread CPU time\nbuild: %s\n\n", machine, SL_BENCH_BUILD);
        } else
            printf("# Occlusion rasterizer side by side with Intel's Masked Occlusion Culling, %dx%d, one thread\n\n", W,
                   H);
        if (!city)
        printf("machine: %s; %d Sightline/MOC pairs per row, run alternately; thread CPU time; "
               "median [min-max]; ratio per pair = MOC time / Sightline time (above 1: Sightline faster); "
               "MOC's triangle streams with %s\n",
               machine, pairs, peer_clip ? "CLIP_PLANE_ALL (its default)" : "CLIP_PLANE_NONE (as its FillrateTest)");
        if (!city)
            printf("build: %s\n\n", SL_BENCH_BUILD);
        const sl_raster_isa pisa[] = {SL_RASTER_ISA_SSE41, SL_RASTER_ISA_AVX2, SL_RASTER_ISA_AVX512};
        const int misa[] = {SLMOC_SSE41, SLMOC_AVX2, SLMOC_AVX512};
        for (size_t p = 0; p < SL_COUNTOF(pisa); p++) {
            bool wanted = nonly == 0;
            for (int i = 0; i < nonly; i++)
                wanted |= only[i] == pisa[p];
            if (smoke && !nonly)
                wanted = p == 0;
            if (wanted && city)
                city_workload(city, pisa[p], misa[p], smoke ? 4 : (uint32_t)views);
            else if (wanted)
                peer_path(pisa[p], misa[p], P, pairs, quick, only_size);
        }
        return 0;
    }
#else
    (void)peer;
    (void)pairs;
    (void)views;
    if (city) {
        fprintf(stderr, "bench_raster_throughput: --city is a --peer moc workload\n");
        return 2;
    }
#endif
    printf("# Occlusion rasterizer, %dx%d, one thread\n\n", W, H);
    printf("machine: %s; median of %d runs; single-thread times are thread CPU time\n", machine, runs);
    printf("build: %s\n", SL_BENCH_BUILD);
    printf("no peer measured (bench_raster_throughput --peer moc, in a build with -DSL_MOC_DIR, measures Intel's "
           "Masked Occlusion Culling side by side)\n\n");
    sl_raster_isa paths[] = {SL_RASTER_ISA_SCALAR, SL_RASTER_ISA_SSE41, SL_RASTER_ISA_AVX2, SL_RASTER_ISA_AVX512};
    sl_raster_isa best = SL_RASTER_ISA_SCALAR;
    for (size_t p = 0; p < SL_COUNTOF(paths); p++) {
        sl_raster_isa isa = paths[p];
        bool wanted = nonly == 0;
        for (int i = 0; i < nonly; i++)
            wanted |= only[i] == isa;
        if (smoke && !nonly)
            wanted = isa == SL_RASTER_ISA_SCALAR || isa == SL_RASTER_ISA_AVX2;
        if (!wanted)
            continue;
        if (!sl_raster_isa_available(isa)) {
            printf("## %s: not available on this CPU\n\n", sl_raster_isa_name(isa));
            continue;
        }
        best = isa;
        sl_raster *r = make(isa, 1);
        printf("## %s\n\n", sl_raster_isa_name(isa));
        printf("| figure | Sightline |\n|---|---:|\n");
        for (size_t s = 0; s < SL_COUNTOF(sizes); s++) {
            if (only_size && sizes[s] != only_size)
                continue;
            double m = throughput(r, P, sizes[s], runs, quick);
            printf("| triangles %dx%d (Mtri/s) | %.2f |\n", sizes[s], sizes[s], m);
            fflush(stdout);
        }
        if (only_size) {
            printf("\n");
            sl_raster_destroy(r);
            continue;
        }
        double c = clear_ms(r, runs);
        printf("| clear (ms) | %.4f |\n", c);
        for (size_t q = 0; q < SL_COUNTOF(qsizes); q++) {
            double ns = query_ns(r, P, qsizes[q][0], qsizes[q][1], runs);
            printf("| query %dx%d, occluded (ns) | %.1f |\n", qsizes[q][0], qsizes[q][1], ns);
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
        /* scaling: 100,000-triangle frames, the pool against one thread, run alternately */
        printf("## %s, %u threads against one, 100,000-triangle frames, wall clock, alternating (%d pairs)\n\n",
               sl_raster_isa_name(best), threads, runs);
        printf("| figure | 1 thread (ms/frame) | %u threads (ms/frame) | 1-thread time / %u-thread time, per pair |\n"
               "|---|---:|---:|---:|\n",
               threads, threads);
        sl_raster *r1 = make(best, 1), *rn = make(best, threads);
        which_clock = CLOCK_WALL;
        for (size_t s = 0; s < SL_COUNTOF(sizes); s++) {
            if (only_size && sizes[s] != only_size)
                continue;
            uint32_t n = smoke ? 2000 : 100000;
            float *v = xmalloc(sizeof(float) * 3 * VFLOATS * n);
            uint32_t *ix = xmalloc(sizeof(uint32_t) * 3 * n);
            make_stream(P, SHAPE_SL, sizes[s], n, 1234, v, ix);
            double a1[64], an[64], rt[64];
            for (int i = 0; i < runs; i++) {
                a1[i] = render_once(r1, P, v, ix, n, sizes[s]);
                an[i] = render_once(rn, P, v, ix, n, sizes[s]);
                rt[i] = a1[i] / an[i];
            }
            double m1 = bench_median(a1, (size_t)runs) * 1e3, mn = bench_median(an, (size_t)runs) * 1e3;
            double mr = bench_median(rt, (size_t)runs); /* sorts rt */
            printf("| triangles %dx%d | %.2f | %.2f | %.2fx [%.2fx-%.2fx] |\n", sizes[s], sizes[s], m1, mn, mr, rt[0],
                   rt[runs - 1]);
            free(v);
            free(ix);
        }
        which_clock = CLOCK_THREAD;
        printf("\n");
        sl_raster_destroy(r1);
        sl_raster_destroy(rn);
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

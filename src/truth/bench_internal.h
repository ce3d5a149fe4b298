/* Internals of the benchmark harness shared by bench.c (running and summaries), bench_report.c
 * (CSV, JSON, Markdown, plots) and bench_map.c (top-down maps). */
#ifndef SL_TRUTH_BENCH_INTERNAL_H
#define SL_TRUTH_BENCH_INTERNAL_H

#include "sightline/bench.h"
#include "core/sl_core.h"

typedef struct bench_method {
    char *name;
    char *options;              /* effective options ("" for external methods) */
    sl_culler culler;           /* NULL for an external method */
    sl_cull_guarantee guarantee;
    uint32_t *result;           /* last frame's ids, object_count capacity */
    uint32_t result_count;
} bench_method;

struct sl_bench_t {
    sl_allocator alloc;
    sl_scene scene;
    sl_bench_options opt;
    char *label;
    char stage[96];             /* progress stage text */
    sl_oracle oracle;
    uint32_t object_count;
    uint32_t *triangles;        /* per object: triangles of its mesh */
    bench_method methods[SL_BENCH_MAX_METHODS];
    uint32_t method_count;
    sl_array frames;            /* sl_bench_frame */
    sl_array records;           /* sl_bench_record, frame-major: frames x method_count */
    sl_oracle_frame truth;      /* the oracle's last frame (arrays owned by the oracle) */
    bool have_truth;
    double *times;              /* repeat timings, opt.repeat entries */
};

/* The record of (frame, method); no checks. */
static inline sl_bench_record *bench_rec(struct sl_bench_t *b, uint32_t frame, uint32_t method)
{
    return &((sl_bench_record *)b->records.data)[(size_t)frame * b->method_count + method];
}

#endif

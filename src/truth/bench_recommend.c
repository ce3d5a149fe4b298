/* The bench's recommendation (bench.h, sl_bench_recommend): the fastest conservative method within
 * a tightness bound and the tightest within a time bound, from the summaries of one bench. */
#include "bench_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

sl_status sl_bench_recommend(sl_bench b, sl_bench_recommendation *out, sl_error *err)
{
    if (!b || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_recommend: NULL argument");
    memset(out, 0, sizeof *out);
    out->fastest = out->tightest = -1;
    out->max_overestimation = b->opt.max_overestimation > 0 ? b->opt.max_overestimation : 2.0;
    out->max_ms = b->opt.max_ms > 0 ? b->opt.max_ms : 2.0;
    double best_ms = INFINITY, best_over = INFINITY;
    sl_bench_summary fs = {0}, ts = {0};
    uint32_t eligible = 0;
    for (uint32_t mi = 0; mi < b->method_count; mi++) {
        const bench_method *m = &b->methods[mi];
        if (!sl_cull_guarantee_keeps_visible(m->guarantee, true))
            continue;
        sl_bench_summary s;
        sl_status st = sl_bench_summarize(b, mi, &s, err);
        if (st != SL_OK)
            return st;
        if (!s.frames || s.missed_objects_total)
            continue;
        eligible++;
        if (s.overestimation <= out->max_overestimation && s.cull_ms.median < best_ms) {
            best_ms = s.cull_ms.median;
            out->fastest = (int32_t)mi;
            fs = s;
        }
        if (s.cull_ms.median <= out->max_ms && s.overestimation < best_over) {
            best_over = s.overestimation;
            out->tightest = (int32_t)mi;
            ts = s;
        }
    }
    char *t = out->text;
    size_t size = sizeof out->text, used = 0;
#define PUT(...)                                                                                                       \
    do {                                                                                                               \
        int w_ = snprintf(t + used, used < size ? size - used : 0, __VA_ARGS__);                                       \
        if (w_ > 0)                                                                                                    \
            used += (size_t)w_;                                                                                        \
    } while (0)
    if (!eligible) {
        PUT("No recommendation: no conservative method ran here without a miss.");
        return SL_OK;
    }
    if (out->fastest >= 0)
        PUT("Fastest within %.3g× the exact visible set: %s (%.3g×, %.3g ms median). ", out->max_overestimation,
            b->methods[out->fastest].name, fs.overestimation, fs.cull_ms.median);
    else
        PUT("No conservative method passed at most %.3g× the exact visible set here (raise --max-overestimation). ",
            out->max_overestimation);
    if (out->tightest >= 0)
        PUT("Tightest within %.3g ms a frame: %s (%.3g×, %.3g ms median). ", out->max_ms,
            b->methods[out->tightest].name, ts.overestimation, ts.cull_ms.median);
    else
        PUT("No conservative method culled in at most %.3g ms median here (raise --max-ms). ", out->max_ms);
    if (out->fastest >= 0 && out->fastest == out->tightest)
        PUT("%s is both: take it for these views.", b->methods[out->fastest].name);
    else if (out->fastest >= 0 && out->tightest >= 0) {
        /* of the two, the one passing fewer objects for a renderer whose cost is in drawing, the
         * quicker one where culling time is what counts */
        bool f_tighter = fs.overestimation < ts.overestimation, f_quicker = fs.cull_ms.median <= ts.cull_ms.median;
        int32_t draw_pick = f_tighter ? out->fastest : out->tightest, cull_pick = f_quicker ? out->fastest : out->tightest;
        if (draw_pick == cull_pick)
            PUT("%s is the better of the two on both counts here.", b->methods[draw_pick].name);
        else
            PUT("Take %s where the renderer's time per object drawn dominates, %s where culling time does.",
                b->methods[draw_pick].name, b->methods[cull_pick].name);
    }
    else if (out->fastest >= 0 || out->tightest >= 0)
        PUT("Take %s for these views.", b->methods[out->fastest >= 0 ? out->fastest : out->tightest].name);
#undef PUT
    return SL_OK;
}

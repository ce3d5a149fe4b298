/* The public bake session (include/sightline/bake.h): sl_bake (pvs_internal.h, the bake the thread
 * driver uses) behind an opaque handle, for drivers outside the library such as tools/pvs_mpi.c. */
#include "pvs_internal.h"

struct sl_bake_session_t {
    sl_bake b;
};

struct sl_bake_worker_t {
    const sl_pvs_method *method;
    const sl_allocator *a;
    void *state;
};

sl_status sl_bake_session_begin(sl_scene scene, sl_viewcells cells, const char *output,
                                const sl_pvs_build_options *opt, bool writer, sl_bake_session *out, sl_error *err)
{
    if (out)
        *out = NULL;
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bake_session_begin: out must not be NULL");
    const sl_allocator *a = sl_alloc_or_default(opt ? opt->alloc : NULL);
    struct sl_bake_session_t *s = sl_calloc(a, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    sl_status st = sl_bake_begin(&s->b, scene, cells, output, opt, writer, err);
    if (st != SL_OK) {
        sl_bake_end(&s->b);
        sl_free(a, s, sizeof *s);
        return st;
    }
    *out = s;
    return SL_OK;
}

void sl_bake_session_end(sl_bake_session s)
{
    if (!s)
        return;
    const sl_allocator *a = s->b.a;
    sl_bake_end(&s->b);
    sl_free(a, s, sizeof *s);
}

uint64_t sl_bake_session_key(sl_bake_session s) { return s ? s->b.key : 0; }
uint32_t sl_bake_session_cell_count(sl_bake_session s) { return s ? s->b.cell_count : 0; }
uint32_t sl_bake_session_object_count(sl_bake_session s) { return s ? s->b.object_count : 0; }
const sl_allocator *sl_bake_session_allocator(sl_bake_session s) { return s ? s->b.a : sl_default_allocator(); }
bool sl_bake_session_cell_done(sl_bake_session s, uint32_t cell)
{
    return s && s->b.done && cell < s->b.cell_count && s->b.done[cell];
}
uint32_t sl_bake_session_done_count(sl_bake_session s) { return s ? s->b.done_count : 0; }
uint32_t sl_bake_session_baked(sl_bake_session s) { return s ? s->b.baked : 0; }
const char *sl_bake_session_journal(sl_bake_session s) { return s && s->b.journal ? s->b.journal : ""; }
const char *sl_bake_session_output(sl_bake_session s) { return s && s->b.output ? s->b.output : ""; }

sl_status sl_bake_session_store(sl_bake_session s, uint32_t cell, const uint32_t *ids, uint32_t count, double seconds,
                                sl_error *err)
{
    if (!s || !s->b.writer)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bake_session_store: not a writer session");
    sl_status st = sl_bake_store(&s->b, cell, ids, count, seconds, err);
    if (st == SL_OK)
        s->b.baked++;
    return st;
}

sl_status sl_bake_session_store_encoded(sl_bake_session s, uint32_t cell, const uint8_t *bytes, uint32_t size,
                                        uint32_t count, double seconds, sl_error *err)
{
    if (!s || !s->b.writer)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bake_session_store_encoded: not a writer session");
    sl_status st = sl_bake_store_encoded(&s->b, cell, bytes, size, count, seconds, true, err);
    if (st == SL_OK)
        s->b.baked++;
    return st;
}

sl_status sl_bake_session_finish(sl_bake_session s, const char *output, const sl_pvs_build_options *opt, sl_error *err)
{
    if (!s || !s->b.writer)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bake_session_finish: not a writer session");
    return sl_bake_finish(&s->b, output, opt, err);
}

void sl_bake_session_note_kept(sl_bake_session s, sl_error *err)
{
    if (s)
        sl_bake_note_kept(&s->b, err);
}

void sl_bake_session_stats(sl_bake_session s, sl_pvs_build_stats *out)
{
    if (!out)
        return;
    if (!s) {
        memset(out, 0, sizeof *out);
        return;
    }
    sl_bake_stats(&s->b, out);
}

sl_status sl_bake_worker_create(sl_bake_session s, sl_bake_worker *out, sl_error *err)
{
    if (out)
        *out = NULL;
    if (!s || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bake_worker_create: session and out must not be NULL");
    struct sl_bake_worker_t *w = sl_calloc(s->b.a, 1, sizeof *w);
    if (!w)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs bake: out of memory");
    w->method = s->b.method;
    w->a = s->b.a;
    sl_status st = w->method->worker_create(s->b.shared, &w->state, err);
    if (st != SL_OK) {
        if (w->state)
            w->method->worker_destroy(w->state);
        sl_free(w->a, w, sizeof *w);
        return st;
    }
    *out = w;
    return SL_OK;
}

void sl_bake_worker_destroy(sl_bake_worker w)
{
    if (!w)
        return;
    w->method->worker_destroy(w->state);
    sl_free(w->a, w, sizeof *w);
}

sl_status sl_bake_worker_cell(sl_bake_worker w, uint32_t cell, uint32_t *ids, uint32_t *count, sl_error *err)
{
    if (count)
        *count = 0;
    if (!w || !ids || !count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bake_worker_cell: worker, ids and count must not be NULL");
    sl_pvs_cell_result res = {ids, 0, 0};
    sl_status st = w->method->cell(w->state, cell, &res, err);
    if (st == SL_OK)
        *count = res.count;
    return st;
}

size_t sl_bake_encode_set(const uint32_t *ids, uint32_t count, uint8_t *out) { return sl_pvs_encode(ids, count, out); }

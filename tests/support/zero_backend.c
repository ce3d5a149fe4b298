#include "support/zero_backend.h"

static sl_status zb_begin_frame(void *u, const float m[16], uint32_t w, uint32_t h, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.begin_frame(z->inner.user, m, w, h, e);
}
static sl_status zb_draw(void *u, const uint32_t *ids, uint32_t n, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.draw_objects(z->inner.user, ids, n, e);
}
static sl_status zb_create(void *u, uint32_t n, sl_draw_query *q, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.create_queries(z->inner.user, n, q, e);
}
static void zb_destroy(void *u, const sl_draw_query *q, uint32_t n)
{
    sl_test_zero_backend *z = u;
    z->inner.destroy_queries(z->inner.user, q, n);
}
static sl_status zb_begin_query(void *u, sl_draw_query q, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.begin_query(z->inner.user, q, e);
}
static sl_status zb_boxes(void *u, const sl_aabb *b, uint32_t n, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.query_boxes(z->inner.user, b, n, e);
}
static sl_status zb_objects(void *u, const uint32_t *ids, uint32_t n, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.query_objects(z->inner.user, ids, n, e);
}
static sl_status zb_end_query(void *u, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.end_query(z->inner.user, e);
}
static sl_status zb_poll(void *u, sl_draw_query q, bool *ready, uint64_t *samples, sl_error *e)
{
    sl_test_zero_backend *z = u;
    sl_status st = z->inner.poll_query(z->inner.user, q, ready, samples, e);
    *samples = 0;
    return st;
}
static sl_status zb_wait(void *u, sl_draw_query q, uint64_t *samples, sl_error *e)
{
    sl_test_zero_backend *z = u;
    sl_status st = z->inner.wait_query(z->inner.user, q, samples, e);
    *samples = 0;
    return st;
}
static sl_status zb_end_frame(void *u, sl_error *e)
{
    sl_test_zero_backend *z = u;
    return z->inner.end_frame(z->inner.user, e);
}

sl_draw_backend sl_test_zero_table(sl_test_zero_backend *z, sl_draw_backend inner)
{
    z->inner = inner;
    sl_draw_backend t = {SL_DRAW_BACKEND_VERSION, z, zb_begin_frame, zb_draw, zb_create, zb_destroy, zb_begin_query,
                         zb_boxes, zb_objects, zb_end_query, zb_poll, zb_wait, zb_end_frame};
    return t;
}

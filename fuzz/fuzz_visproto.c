/* libFuzzer target: the visibility protocol's decoder (src/net/visproto.c, docs/protocol.md), fed
 * a byte stream as the server or the client reads it. The first byte picks the side: even, the
 * server's (frames of at most SLVP_CLIENT_BODY_MAX bytes: a HELLO, then VIEWs with increasing
 * seq); odd, the client's (a WELCOME, whose object count sizes the frame limit and the id buffer,
 * then SETs and ERRORs). A set that decodes must hold strictly ascending ids below the object
 * count, and encoding them again must decode to the same ids (no allocation beyond the limits the
 * reader checks first). */
#include "net/visproto.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* the fuzzer's cap on a welcome's object count (the protocol allows 2^28: the same code, less memory) */
#define FUZZ_OBJECTS_MAX (1u << 16)

static ZSTD_DCtx *g_dctx;
static ZSTD_CCtx *g_cctx;

static void check_set(const slvp_set *m, uint32_t objects, uint32_t *ids, uint8_t *scratch)
{
    char why[256];
    if (!slvp_set_decode(g_dctx, m, objects, scratch, ids, why, sizeof why))
        return;
    for (uint32_t i = 0; i < m->count; i++)
        if (ids[i] >= objects || (i && ids[i - 1] >= ids[i]))
            abort();
    uint8_t *out = malloc(slvp_payload_bound(objects) + 1);
    uint32_t *back = malloc(((size_t)m->count + 1) * sizeof *back);
    size_t n;
    uint8_t enc;
    if (!out || !back || !slvp_set_encode(g_cctx, 1, ids, m->count, objects, scratch, out, &n, &enc, why, sizeof why))
        abort();
    slvp_set again = {.seq = 1, .validity = 0, .encoding = enc, .cell = UINT32_MAX, .count = m->count,
                      .payload_size = (uint32_t)n, .payload = out};
    if (n > slvp_payload_bound(objects) || !slvp_set_decode(g_dctx, &again, objects, scratch, back, why, sizeof why) ||
        memcmp(ids, back, (size_t)m->count * sizeof *ids) != 0)
        abort();
    free(out);
    free(back);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    if (!g_dctx) {
        g_dctx = ZSTD_createDCtx();
        g_cctx = ZSTD_createCCtx();
    }
    bool server_side = (data[0] & 1) == 0;
    const uint8_t *p = data + 1;
    size_t left = size - 1;
    char why[256];
    uint32_t prev_seq = 0, objects = 0;
    bool started = false;
    uint32_t *ids = NULL;
    uint8_t *scratch = NULL;
    uint32_t limit = server_side ? SLVP_CLIENT_BODY_MAX : SLVP_WELCOME_FIXED + SLVP_METHOD_MAX;
    for (;;) {
        uint32_t len;
        if (slvp_frame(p, left, limit, &len, why, sizeof why) != 1)
            break;
        const uint8_t *body = p + SLVP_LEN_BYTES;
        p += SLVP_LEN_BYTES + len;
        left -= SLVP_LEN_BYTES + len;
        uint8_t type = slvp_type_of(body, len);
        if (server_side) {
            if (!started) {
                slvp_hello h;
                if (type != SLVP_HELLO || !slvp_read_hello(body, len, &h, why, sizeof why))
                    break;
                started = true;
            } else {
                slvp_view v;
                if (type != SLVP_VIEW || !slvp_read_view(body, len, prev_seq, &v, why, sizeof why))
                    break;
                prev_seq = v.seq;
            }
        } else if (!started) {
            slvp_welcome w;
            if (type != SLVP_WELCOME || !slvp_read_welcome(body, len, &w, why, sizeof why) ||
                w.object_count > FUZZ_OBJECTS_MAX)
                break;
            objects = w.object_count;
            limit = w.max_body;
            ids = malloc(((size_t)objects + 1) * sizeof *ids);
            scratch = malloc(slvp_scratch_bytes(objects));
            started = true;
        } else if (type == SLVP_SET) {
            slvp_set m;
            if (!slvp_read_set(body, len, objects, &m, why, sizeof why))
                break;
            check_set(&m, objects, ids, scratch);
        } else {
            slvp_errmsg e;
            slvp_read_error(body, len, &e, why, sizeof why);
            break;
        }
    }
    free(ids);
    free(scratch);
    return 0;
}

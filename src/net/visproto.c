/* The visibility protocol codec (docs/protocol.md). Layout of every body, offsets from its type
 * byte; integers and floats little-endian:
 *   HELLO   0 type, 1 magic u32, 5 version u16, 7 projection u8, 8 fov_y f32, 12 ortho_height f32,
 *           16 near f32, 20 far f32, 24 width u32, 28 height u32                      (32 bytes)
 *   WELCOME 0 type, 1 magic u32, 5 version u16, 7 flags u8, 8 object_count u32, 12 scene_key u64,
 *           20 max_rate_hz u32, 24 max_body u32, 28 method_len u16, 30 method    (30 + method_len)
 *   VIEW    0 type, 1 seq u32, 5 eye f32 x3, 17 yaw f32, 21 pitch f32, 25 roll f32, 29 speed f32 (33)
 *   SET     0 type, 1 seq u32, 5 validity u8, 6 encoding u8, 7 cell u32, 11 count u32,
 *           15 payload_size u32, 19 payload                                    (19 + payload_size)
 *   ERROR   0 type, 1 code u16, 3 text_len u16, 5 text                           (5 + text_len)
 * A reader refuses a body whose length is not exactly what its fields say, so nothing is ever read
 * past the end and no trailing bytes are silently ignored. */
#include "net/visproto.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}
static void put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}
static void put_f32(uint8_t *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32(p, v);
}
static uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static uint32_t get_u32(const uint8_t *p) { return slvp_u32(p); }
static uint64_t get_u64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | p[i];
    return v;
}
static float get_f32(const uint8_t *p)
{
    uint32_t v = get_u32(p);
    float f;
    memcpy(&f, &v, 4);
    return f;
}

static bool fail(char *why, size_t size, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static bool fail(char *why, size_t size, const char *fmt, ...)
{
    if (why && size) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(why, size, fmt, ap);
        va_end(ap);
    }
    return false;
}

int slvp_frame(const uint8_t *buf, size_t avail, uint32_t max_body, uint32_t *body_len, char *why, size_t why_size)
{
    if (avail < SLVP_LEN_BYTES)
        return 0;
    uint32_t len = get_u32(buf);
    if (len == 0) {
        fail(why, why_size, "frame length 0: a message has at least its type byte");
        return -1;
    }
    if (len > max_body) {
        fail(why, why_size, "frame length %u: above the limit of %u bytes", len, max_body);
        return -1;
    }
    if (avail - SLVP_LEN_BYTES < len)
        return 0;
    *body_len = len;
    return 1;
}

uint8_t slvp_type_of(const uint8_t *body, size_t len) { return len ? body[0] : 0; }

/* ---- writers ---- */

size_t slvp_write_hello(uint8_t *out, const slvp_hello *m)
{
    uint8_t *b = out + SLVP_LEN_BYTES;
    put_u32(out, SLVP_HELLO_BODY);
    b[0] = SLVP_HELLO;
    put_u32(b + 1, SLVP_MAGIC);
    put_u16(b + 5, (uint16_t)m->version);
    b[7] = m->projection;
    put_f32(b + 8, m->fov_y);
    put_f32(b + 12, m->ortho_height);
    put_f32(b + 16, m->near_plane);
    put_f32(b + 20, m->far_plane);
    put_u32(b + 24, m->width);
    put_u32(b + 28, m->height);
    return SLVP_LEN_BYTES + SLVP_HELLO_BODY;
}

size_t slvp_write_welcome(uint8_t *out, const slvp_welcome *m)
{
    size_t n = strnlen(m->method, SLVP_METHOD_MAX);
    uint8_t *b = out + SLVP_LEN_BYTES;
    put_u32(out, (uint32_t)(SLVP_WELCOME_FIXED + n));
    b[0] = SLVP_WELCOME;
    put_u32(b + 1, SLVP_MAGIC);
    put_u16(b + 5, (uint16_t)m->version);
    b[7] = m->flags;
    put_u32(b + 8, m->object_count);
    put_u64(b + 12, m->scene_key);
    put_u32(b + 20, m->max_rate_hz);
    put_u32(b + 24, m->max_body);
    put_u16(b + 28, (uint16_t)n);
    memcpy(b + 30, m->method, n);
    return SLVP_LEN_BYTES + SLVP_WELCOME_FIXED + n;
}

size_t slvp_write_view(uint8_t *out, const slvp_view *m)
{
    uint8_t *b = out + SLVP_LEN_BYTES;
    put_u32(out, SLVP_VIEW_BODY);
    b[0] = SLVP_VIEW;
    put_u32(b + 1, m->seq);
    for (int i = 0; i < 3; i++)
        put_f32(b + 5 + 4 * i, m->eye[i]);
    put_f32(b + 17, m->yaw);
    put_f32(b + 21, m->pitch);
    put_f32(b + 25, m->roll);
    put_f32(b + 29, m->speed);
    return SLVP_LEN_BYTES + SLVP_VIEW_BODY;
}

size_t slvp_write_error(uint8_t *out, uint16_t code, const char *text)
{
    size_t n = strnlen(text, SLVP_ERROR_TEXT_MAX);
    uint8_t *b = out + SLVP_LEN_BYTES;
    put_u32(out, (uint32_t)(5 + n));
    b[0] = SLVP_ERROR;
    put_u16(b + 1, code);
    put_u16(b + 3, (uint16_t)n);
    /* only printable ASCII goes on the wire (the reader refuses anything else) */
    for (size_t i = 0; i < n; i++)
        b[5 + i] = (text[i] >= 0x20 && text[i] < 0x7f) ? (uint8_t)text[i] : (uint8_t)'?';
    return SLVP_LEN_BYTES + 5 + n;
}

size_t slvp_write_set_header(uint8_t *out, const slvp_set *m)
{
    uint8_t *b = out + SLVP_LEN_BYTES;
    put_u32(out, SLVP_SET_FIXED + m->payload_size);
    b[0] = SLVP_SET;
    put_u32(b + 1, m->seq);
    b[5] = m->validity;
    b[6] = m->encoding;
    put_u32(b + 7, m->cell);
    put_u32(b + 11, m->count);
    put_u32(b + 15, m->payload_size);
    return SLVP_LEN_BYTES + SLVP_SET_FIXED;
}

/* ---- readers ---- */

static bool check_len(const char *what, size_t len, size_t want, char *why, size_t ws)
{
    if (len != want)
        return fail(why, ws, "%s: body of %zu bytes, expected %zu", what, len, want);
    return true;
}

static bool check_magic(const char *what, const uint8_t *b, char *why, size_t ws)
{
    if (get_u32(b + 1) != SLVP_MAGIC)
        return fail(why, ws, "%s offset 1: magic 0x%08x, expected 0x%08x (\"SLVP\")", what, get_u32(b + 1), SLVP_MAGIC);
    return true;
}

static bool check_printable(const char *what, const char *field, const uint8_t *p, size_t n, size_t off, char *why,
                            size_t ws)
{
    for (size_t i = 0; i < n; i++)
        if (p[i] < 0x20 || p[i] >= 0x7f)
            return fail(why, ws, "%s offset %zu: %s: byte 0x%02x is not printable ASCII", what, off + i, field, p[i]);
    return true;
}

bool slvp_read_hello(const uint8_t *b, size_t len, slvp_hello *m, char *why, size_t ws)
{
    if (!check_len("HELLO", len, SLVP_HELLO_BODY, why, ws) || !check_magic("HELLO", b, why, ws))
        return false;
    m->version = get_u16(b + 5);
    if (m->version != SLVP_VERSION)
        return fail(why, ws, "HELLO offset 5: protocol version %u, this server speaks %u", m->version, SLVP_VERSION);
    m->projection = b[7];
    if (m->projection > 1)
        return fail(why, ws, "HELLO offset 7: projection %u: 0 (perspective) or 1 (orthographic)", m->projection);
    m->fov_y = get_f32(b + 8);
    m->ortho_height = get_f32(b + 12);
    m->near_plane = get_f32(b + 16);
    m->far_plane = get_f32(b + 20);
    m->width = get_u32(b + 24);
    m->height = get_u32(b + 28);
    const float f[4] = {m->fov_y, m->ortho_height, m->near_plane, m->far_plane};
    static const char *const names[4] = {"fov_y", "ortho_height", "near", "far"};
    for (int i = 0; i < 4; i++)
        if (!isfinite(f[i]))
            return fail(why, ws, "HELLO offset %d: %s: not finite", 8 + 4 * i, names[i]);
    if (m->projection == 0 && !(m->fov_y > 1e-3f && m->fov_y < 3.1f))
        return fail(why, ws, "HELLO offset 8: fov_y %g: outside (0.001, 3.1) radians", (double)m->fov_y);
    if (m->projection == 1 && !(m->ortho_height > 0.0f && m->ortho_height <= SLVP_COORD_MAX))
        return fail(why, ws, "HELLO offset 12: ortho_height %g: outside (0, 1e7]", (double)m->ortho_height);
    if (!(m->near_plane >= 1e-4f && m->near_plane <= 1e4f))
        return fail(why, ws, "HELLO offset 16: near %g: outside [1e-4, 1e4]", (double)m->near_plane);
    if (!(m->far_plane > m->near_plane && m->far_plane <= 1e8f))
        return fail(why, ws, "HELLO offset 20: far %g: must exceed near and be at most 1e8", (double)m->far_plane);
    if (m->width < 1 || m->width > SLVP_VIEWPORT_MAX)
        return fail(why, ws, "HELLO offset 24: width %u: outside [1, %u]", m->width, SLVP_VIEWPORT_MAX);
    if (m->height < 1 || m->height > SLVP_VIEWPORT_MAX)
        return fail(why, ws, "HELLO offset 28: height %u: outside [1, %u]", m->height, SLVP_VIEWPORT_MAX);
    return true;
}

bool slvp_read_welcome(const uint8_t *b, size_t len, slvp_welcome *m, char *why, size_t ws)
{
    if (len < SLVP_WELCOME_FIXED)
        return fail(why, ws, "WELCOME: body of %zu bytes, at least %u expected", len, SLVP_WELCOME_FIXED);
    if (!check_magic("WELCOME", b, why, ws))
        return false;
    m->version = get_u16(b + 5);
    if (m->version != SLVP_VERSION)
        return fail(why, ws, "WELCOME offset 5: protocol version %u, this client speaks %u", m->version, SLVP_VERSION);
    m->flags = b[7];
    if (m->flags & ~1u)
        return fail(why, ws, "WELCOME offset 7: flags 0x%02x: unknown bits", m->flags);
    m->object_count = get_u32(b + 8);
    if (m->object_count > SLVP_OBJECTS_MAX)
        return fail(why, ws, "WELCOME offset 8: object_count %u: above %u", m->object_count, SLVP_OBJECTS_MAX);
    m->scene_key = get_u64(b + 12);
    m->max_rate_hz = get_u32(b + 20);
    if (m->max_rate_hz < 1 || m->max_rate_hz > 10000)
        return fail(why, ws, "WELCOME offset 20: max_rate_hz %u: outside [1, 10000]", m->max_rate_hz);
    m->max_body = get_u32(b + 24);
    if (m->max_body != slvp_set_body_max(m->object_count))
        return fail(why, ws, "WELCOME offset 24: max_body %u: expected %u for %u objects", m->max_body,
                    slvp_set_body_max(m->object_count), m->object_count);
    size_t n = get_u16(b + 28);
    if (n > SLVP_METHOD_MAX)
        return fail(why, ws, "WELCOME offset 28: method length %zu: above %u", n, SLVP_METHOD_MAX);
    if (!check_len("WELCOME", len, SLVP_WELCOME_FIXED + n, why, ws) ||
        !check_printable("WELCOME", "method", b + 30, n, 30, why, ws))
        return false;
    memcpy(m->method, b + 30, n);
    m->method[n] = 0;
    return true;
}

bool slvp_read_view(const uint8_t *b, size_t len, uint32_t prev_seq, slvp_view *m, char *why, size_t ws)
{
    if (!check_len("VIEW", len, SLVP_VIEW_BODY, why, ws))
        return false;
    m->seq = get_u32(b + 1);
    if (m->seq <= prev_seq)
        return fail(why, ws, "VIEW offset 1: seq %u: not above the previous %u", m->seq, prev_seq);
    static const char *const names[7] = {"eye.x", "eye.y", "eye.z", "yaw", "pitch", "roll", "speed"};
    float v[7];
    for (int i = 0; i < 7; i++) {
        v[i] = get_f32(b + 5 + 4 * i);
        if (!isfinite(v[i]))
            return fail(why, ws, "VIEW offset %d: %s: not finite", 5 + 4 * i, names[i]);
    }
    for (int i = 0; i < 3; i++)
        if (fabsf(v[i]) > SLVP_COORD_MAX)
            return fail(why, ws, "VIEW offset %d: %s %g: beyond +-1e7 m", 5 + 4 * i, names[i], (double)v[i]);
    if (fabsf(v[3]) > SLVP_ANGLE_MAX || fabsf(v[5]) > SLVP_ANGLE_MAX)
        return fail(why, ws, "VIEW offset %d: %s: beyond +-1e4 radians", fabsf(v[3]) > SLVP_ANGLE_MAX ? 17 : 25,
                    fabsf(v[3]) > SLVP_ANGLE_MAX ? "yaw" : "roll");
    if (fabsf(v[4]) > 1.5707964f)
        return fail(why, ws, "VIEW offset 21: pitch %g: outside [-pi/2, pi/2]", (double)v[4]);
    if (v[6] < 0.0f || v[6] > SLVP_SPEED_MAX)
        return fail(why, ws, "VIEW offset 29: speed %g: outside [0, 1e4] m/s", (double)v[6]);
    memcpy(m->eye, v, sizeof m->eye);
    m->yaw = v[3];
    m->pitch = v[4];
    m->roll = v[5];
    m->speed = v[6];
    return true;
}

bool slvp_read_set(const uint8_t *b, size_t len, uint32_t object_count, slvp_set *m, char *why, size_t ws)
{
    if (len < SLVP_SET_FIXED)
        return fail(why, ws, "SET: body of %zu bytes, at least %u expected", len, SLVP_SET_FIXED);
    m->seq = get_u32(b + 1);
    if (m->seq == 0)
        return fail(why, ws, "SET offset 1: seq 0 (viewpoints start at 1)");
    m->validity = b[5];
    m->encoding = b[6];
    m->cell = get_u32(b + 7);
    m->count = get_u32(b + 11);
    m->payload_size = get_u32(b + 15);
    if (m->validity > 1)
        return fail(why, ws, "SET offset 5: validity %u: 0 (point) or 1 (cell)", m->validity);
    if (m->encoding < SLVP_ENC_VARINT || m->encoding > SLVP_ENC_BITSET)
        return fail(why, ws, "SET offset 6: encoding %u: 1 (varint), 2 (varint+zstd) or 3 (bitset)", m->encoding);
    if (m->validity == 0 ? m->cell != UINT32_MAX : m->cell == UINT32_MAX)
        return fail(why, ws, "SET offset 7: cell %u with validity %u", m->cell, m->validity);
    if (m->count > object_count)
        return fail(why, ws, "SET offset 11: count %u: above the scene's %u objects", m->count, object_count);
    if (m->payload_size != len - SLVP_SET_FIXED)
        return fail(why, ws, "SET offset 15: payload_size %u, but %zu bytes follow", m->payload_size,
                    len - SLVP_SET_FIXED);
    if (m->payload_size > slvp_payload_bound(object_count))
        return fail(why, ws, "SET offset 15: payload_size %u: above the bitset's %zu bytes", m->payload_size,
                    slvp_payload_bound(object_count));
    m->payload = b + SLVP_SET_FIXED;
    return true;
}

bool slvp_read_error(const uint8_t *b, size_t len, slvp_errmsg *m, char *why, size_t ws)
{
    if (len < 5)
        return fail(why, ws, "ERROR: body of %zu bytes, at least 5 expected", len);
    m->code = get_u16(b + 1);
    size_t n = get_u16(b + 3);
    if (n > SLVP_ERROR_TEXT_MAX)
        return fail(why, ws, "ERROR offset 3: text length %zu: above %u", n, SLVP_ERROR_TEXT_MAX);
    if (!check_len("ERROR", len, 5 + n, why, ws) || !check_printable("ERROR", "text", b + 5, n, 5, why, ws))
        return false;
    memcpy(m->text, b + 5, n);
    m->text[n] = 0;
    return true;
}

/* ---- the set codec ---- */

size_t slvp_bitset_bytes(uint32_t object_count) { return ((size_t)object_count + 7) / 8; }
size_t slvp_scratch_bytes(uint32_t count) { return (size_t)count * 5 + 16; }
size_t slvp_payload_bound(uint32_t object_count) { return slvp_bitset_bytes(object_count); }
uint32_t slvp_set_body_max(uint32_t object_count)
{
    return (uint32_t)(SLVP_SET_FIXED + slvp_payload_bound(object_count));
}

/* The first id, then each gap minus one (ids strictly ascend, so gaps are >= 1), as LEB128. */
static size_t varint_gaps(const uint32_t *ids, uint32_t count, uint8_t *out)
{
    size_t k = 0;
    uint32_t prev = 0;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t v = i == 0 ? ids[0] : ids[i] - prev - 1;
        prev = ids[i];
        while (v >= 0x80) {
            out[k++] = (uint8_t)(v | 0x80);
            v >>= 7;
        }
        out[k++] = (uint8_t)v;
    }
    return k;
}

bool slvp_set_encode(ZSTD_CCtx *cctx, int level, const uint32_t *ids, uint32_t count, uint32_t object_count,
                     uint8_t *scratch, uint8_t *out, size_t *out_size, uint8_t *encoding, char *why, size_t ws)
{
    size_t bits = slvp_bitset_bytes(object_count);
    size_t v = varint_gaps(ids, count, scratch);
    size_t best = bits;
    uint8_t enc = SLVP_ENC_BITSET;
    if (v <= best) {
        best = v;
        enc = SLVP_ENC_VARINT;
    }
    /* zstd pays off only on longer lists: its frame header alone is 6+ bytes */
    if (v > 32) {
        size_t z = ZSTD_compressCCtx(cctx, out, bits, scratch, v, level);
        if (!ZSTD_isError(z) && z < best) {
            *out_size = z;
            *encoding = SLVP_ENC_VARINT_ZSTD;
            return true;
        }
        if (ZSTD_isError(z) && ZSTD_getErrorCode(z) != ZSTD_error_dstSize_tooSmall)
            return fail(why, ws, "zstd: %s", ZSTD_getErrorName(z));
    }
    if (enc == SLVP_ENC_VARINT) {
        memcpy(out, scratch, v);
    } else {
        memset(out, 0, bits);
        for (uint32_t i = 0; i < count; i++)
            out[ids[i] >> 3] |= (uint8_t)(1u << (ids[i] & 7));
    }
    *out_size = best;
    *encoding = enc;
    return true;
}

/* Decode exactly count canonical varints filling exactly n bytes into ascending ids. */
static bool decode_gaps(const uint8_t *p, size_t n, uint32_t count, uint32_t object_count, uint32_t *ids, size_t base,
                        char *why, size_t ws)
{
    size_t k = 0;
    uint64_t prev = 0;
    for (uint32_t i = 0; i < count; i++) {
        uint64_t v = 0;
        int shift = 0;
        size_t start = k;
        for (;;) {
            if (k >= n)
                return fail(why, ws, "SET payload offset %zu: id %u: truncated varint", base + k, i);
            uint8_t c = p[k++];
            if (shift == 28 && (c & 0xf0))
                return fail(why, ws, "SET payload offset %zu: id %u: varint beyond 32 bits", base + k - 1, i);
            v |= (uint64_t)(c & 0x7f) << shift;
            if (!(c & 0x80)) {
                if (c == 0 && k - start > 1)
                    return fail(why, ws, "SET payload offset %zu: id %u: varint not in its shortest form", base + start,
                                i);
                break;
            }
            shift += 7;
        }
        uint64_t id = i == 0 ? v : prev + v + 1;
        if (id >= object_count)
            return fail(why, ws, "SET payload offset %zu: id %u is %llu, the scene has %u objects", base + start, i,
                        (unsigned long long)id, object_count);
        ids[i] = (uint32_t)id;
        prev = id;
    }
    if (k != n)
        return fail(why, ws, "SET payload offset %zu: %zu bytes after the last of %u ids", base + k, n - k, count);
    return true;
}

bool slvp_set_decode(ZSTD_DCtx *dctx, const slvp_set *m, uint32_t object_count, uint8_t *scratch, uint32_t *ids,
                     char *why, size_t ws)
{
    const uint8_t *p = m->payload;
    size_t n = m->payload_size;
    switch (m->encoding) {
    case SLVP_ENC_VARINT:
        if (n < m->count || n > (size_t)m->count * 5)
            return fail(why, ws, "SET payload: %zu bytes cannot hold %u varints", n, m->count);
        return decode_gaps(p, n, m->count, object_count, ids, 0, why, ws);
    case SLVP_ENC_VARINT_ZSTD: {
        unsigned long long size = ZSTD_getFrameContentSize(p, n);
        if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN)
            return fail(why, ws, "SET payload offset 0: not a zstd frame with a declared size");
        if (size < m->count || size > (unsigned long long)m->count * 5)
            return fail(why, ws, "SET payload offset 0: zstd content of %llu bytes cannot hold %u varints", size,
                        m->count);
        size_t fz = ZSTD_findFrameCompressedSize(p, n);
        if (ZSTD_isError(fz) || fz != n)
            return fail(why, ws, "SET payload: %zu bytes are not exactly one zstd frame", n);
        size_t got = ZSTD_decompressDCtx(dctx, scratch, (size_t)size, p, n);
        if (ZSTD_isError(got))
            return fail(why, ws, "SET payload: zstd: %s", ZSTD_getErrorName(got));
        if (got != size)
            return fail(why, ws, "SET payload: zstd gave %zu bytes, its frame declares %llu", got, size);
        return decode_gaps(scratch, got, m->count, object_count, ids, 0, why, ws);
    }
    case SLVP_ENC_BITSET: {
        if (n != slvp_bitset_bytes(object_count))
            return fail(why, ws, "SET payload: bitset of %zu bytes, %zu expected for %u objects", n,
                        slvp_bitset_bytes(object_count), object_count);
        uint32_t k = 0;
        for (size_t byte = 0; byte < n; byte++) {
            uint8_t c = p[byte];
            while (c) {
                uint32_t id = (uint32_t)(byte * 8 + (size_t)__builtin_ctz(c));
                c &= (uint8_t)(c - 1);
                if (id >= object_count)
                    return fail(why, ws, "SET payload offset %zu: bit %u set beyond the scene's %u objects", byte, id,
                                object_count);
                if (k >= m->count)
                    return fail(why, ws, "SET payload offset %zu: more than count %u bits set", byte, m->count);
                ids[k++] = id;
            }
        }
        if (k != m->count)
            return fail(why, ws, "SET payload: %u bits set, count says %u", k, m->count);
        return true;
    }
    default:
        return fail(why, ws, "SET: encoding %u", m->encoding);
    }
}

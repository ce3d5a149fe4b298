/* The visibility protocol's messages, encoded and decoded without I/O (docs/protocol.md), so that
 * the decoder can be fuzzed (fuzz/fuzz_visproto.c) and tested on its own (tests/test_net.c).
 *
 * A frame is a little-endian u32 length L (the bytes that follow it), then L bytes: a u8 message
 * type and the message's fields. Every reader checks the length against its limit before it
 * buffers a byte, every field's range (sizes, counts, finite floats) before it uses it, and says
 * where and why it refused: "VIEW offset 9: eye.x: not finite". Pure functions: thread-safe,
 * allocation-free (the set codec works in buffers the caller sizes with the *_bound functions and
 * in the caller's zstd contexts). */
#ifndef SL_NET_VISPROTO_H
#define SL_NET_VISPROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <zstd.h>
#include <zstd_errors.h>

#define SLVP_MAGIC 0x50564c53u /* "SLVP" little-endian */
#define SLVP_VERSION 1u
#define SLVP_LEN_BYTES 4u

enum slvp_type { SLVP_HELLO = 1, SLVP_WELCOME = 2, SLVP_VIEW = 3, SLVP_SET = 4, SLVP_ERROR = 5 };

/* Body sizes (type byte included). */
#define SLVP_HELLO_BODY 32u
#define SLVP_VIEW_BODY 33u
#define SLVP_SET_FIXED 19u          /* type + the set's fixed fields; the payload follows */
#define SLVP_WELCOME_FIXED 30u      /* type + fixed fields; the method text follows */
#define SLVP_METHOD_MAX 255u
#define SLVP_ERROR_TEXT_MAX 255u
/* The longest body a server reads (HELLO and VIEW are the only messages a client sends). */
#define SLVP_CLIENT_BODY_MAX 64u
/* Objects a scene may have for the protocol (ids are below it). */
#define SLVP_OBJECTS_MAX (1u << 28)
/* Coordinate, angle and speed limits of a viewpoint. */
#define SLVP_COORD_MAX 1.0e7f
#define SLVP_ANGLE_MAX 1.0e4f
#define SLVP_SPEED_MAX 1.0e4f
#define SLVP_VIEWPORT_MAX 16384u

enum slvp_encoding { SLVP_ENC_VARINT = 1, SLVP_ENC_VARINT_ZSTD = 2, SLVP_ENC_BITSET = 3 };
enum slvp_error_code { SLVP_ERR_PROTOCOL = 1, SLVP_ERR_VERSION = 2, SLVP_ERR_LIMIT = 3, SLVP_ERR_RATE = 4,
                       SLVP_ERR_FULL = 5, SLVP_ERR_INTERNAL = 6 };

typedef struct slvp_hello {
    uint32_t version;
    uint8_t projection;           /* 0 perspective, 1 orthographic (camera.h) */
    float fov_y, ortho_height, near_plane, far_plane;
    uint32_t width, height;
} slvp_hello;

typedef struct slvp_welcome {
    uint32_t version;
    uint8_t flags;                /* bit 0: the server answers with cell sets where it can */
    uint32_t object_count;
    uint64_t scene_key;
    uint32_t max_rate_hz;
    uint32_t max_body;            /* the longest body the server will send */
    char method[SLVP_METHOD_MAX + 1];
} slvp_welcome;

typedef struct slvp_view {
    uint32_t seq;                 /* >= 1, increasing on a connection */
    float eye[3];
    float yaw, pitch, roll;
    float speed;
} slvp_view;

typedef struct slvp_set {
    uint32_t seq;                 /* the viewpoint answered */
    uint8_t validity;             /* sl_vis_validity */
    uint8_t encoding;             /* slvp_encoding */
    uint32_t cell;                /* SL_VIS_CELL: the cell; else UINT32_MAX */
    uint32_t count;               /* ids */
    uint32_t payload_size;
    const uint8_t *payload;       /* decoding: points into the body */
} slvp_set;

typedef struct slvp_errmsg {
    uint16_t code;
    char text[SLVP_ERROR_TEXT_MAX + 1];
} slvp_errmsg;

/* A little-endian u32 at p (the length prefix, fields). */
static inline uint32_t slvp_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* The frame at buf[0..avail): 1 with *body_len when complete, 0 when more bytes are needed, -1
 * (why filled) when its length is 0 or above max_body. */
int slvp_frame(const uint8_t *buf, size_t avail, uint32_t max_body, uint32_t *body_len, char *why, size_t why_size);

/* Writers: the whole frame (length included) into out, returning its size; out holds at least
 * SLVP_LEN_BYTES + the body (welcome: SLVP_WELCOME_FIXED + strlen(method) <= 285 bytes; error:
 * 5 + strlen(text) <= 260). */
size_t slvp_write_hello(uint8_t *out, const slvp_hello *m);
size_t slvp_write_welcome(uint8_t *out, const slvp_welcome *m);
size_t slvp_write_view(uint8_t *out, const slvp_view *m);
size_t slvp_write_error(uint8_t *out, uint16_t code, const char *text);
/* The set's fixed part (SLVP_LEN_BYTES + SLVP_SET_FIXED bytes); the payload follows it on the wire. */
size_t slvp_write_set_header(uint8_t *out, const slvp_set *m);

/* Readers of one body (type byte first) of len bytes. */
uint8_t slvp_type_of(const uint8_t *body, size_t len);
bool slvp_read_hello(const uint8_t *body, size_t len, slvp_hello *m, char *why, size_t why_size);
bool slvp_read_welcome(const uint8_t *body, size_t len, slvp_welcome *m, char *why, size_t why_size);
/* prev_seq: the connection's last seq (0 before the first); seq must exceed it. */
bool slvp_read_view(const uint8_t *body, size_t len, uint32_t prev_seq, slvp_view *m, char *why, size_t why_size);
/* The fixed fields are checked against object_count (count, cell range), the payload's size
 * against the encoding; the payload itself by slvp_set_decode. */
bool slvp_read_set(const uint8_t *body, size_t len, uint32_t object_count, slvp_set *m, char *why, size_t why_size);
bool slvp_read_error(const uint8_t *body, size_t len, slvp_errmsg *m, char *why, size_t why_size);

/* ---- the set codec ---- */
/* Bytes of a bitset of object_count bits. */
size_t slvp_bitset_bytes(uint32_t object_count);
/* Scratch bytes the codec needs for count ids (varints: 5 per id). */
size_t slvp_scratch_bytes(uint32_t count);
/* The largest payload slvp_set_encode makes (it never exceeds the bitset). */
size_t slvp_payload_bound(uint32_t object_count);
/* The longest SET body for object_count objects. */
uint32_t slvp_set_body_max(uint32_t object_count);
/* Encode ids[0..count) (strictly ascending, < object_count) as the smallest of: varint gaps,
 * varint gaps compressed by zstd (cctx, level), a bitset. out holds slvp_payload_bound bytes,
 * scratch slvp_scratch_bytes(count). false only when zstd fails (why says so). */
bool slvp_set_encode(ZSTD_CCtx *cctx, int level, const uint32_t *ids, uint32_t count, uint32_t object_count,
                     uint8_t *scratch, uint8_t *out, size_t *out_size, uint8_t *encoding, char *why, size_t why_size);
/* Decode a payload into ids (capacity >= m->count): exactly m->count ids, strictly ascending, each
 * below object_count, canonical varints, one complete zstd frame of a declared size, no bit set
 * beyond object_count. scratch holds slvp_scratch_bytes(m->count). */
bool slvp_set_decode(ZSTD_DCtx *dctx, const slvp_set *m, uint32_t object_count, uint8_t *scratch, uint32_t *ids,
                     char *why, size_t why_size);

#endif

/* The command's own small helpers, written with the public API only (tools/ includes nothing but
 * include/sightline/ and its own headers: scripts/check_layers.sh): arithmetic macros, errors,
 * time, allocation through an sl_allocator and a growable byte buffer. Every function is
 * thread-safe on distinct arguments. */
#ifndef SL_TOOLS_TOOL_H
#define SL_TOOLS_TOOL_H

#include "sightline/core.h"

#include <stdarg.h>

#define TOOL_MIN(a, b) ((a) < (b) ? (a) : (b))
#define TOOL_MAX(a, b) ((a) > (b) ? (a) : (b))
#define TOOL_COUNTOF(a) (sizeof(a) / sizeof((a)[0]))

/* ---- errors ---- */
/* Store status and a printf-style message in err (may be NULL); returns status. */
sl_status tool_fail(sl_error *err, sl_status status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* Put "PREFIX: " before err's message (cut to the message's size). NULL err is ignored. */
void tool_error_prefix(sl_error *err, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* ---- progress ---- */
/* Report to p (NULL or without a function: nothing); false when the callback asked to stop. */
static inline bool tool_progress(const sl_progress *p, const char *stage, uint64_t done, uint64_t total)
{
    return !p || !p->fn || p->fn(p->user, stage, done, total);
}

/* ---- time ---- */
/* Seconds of the monotonic clock. */
double tool_now(void);

/* ---- allocation through an sl_allocator (NULL: the default), 16-byte aligned ---- */
void *tool_alloc(const sl_allocator *a, size_t size);
/* count * size zeroed bytes; NULL on overflow or failure. */
void *tool_calloc(const sl_allocator *a, size_t count, size_t size);
/* Resize a block of old_size bytes (p NULL: allocate); NULL on failure, p then still valid. */
void *tool_realloc(const sl_allocator *a, void *p, size_t old_size, size_t new_size);
/* Free a block of size bytes. NULL is ignored. */
void tool_free(const sl_allocator *a, void *p, size_t size);

/* ---- a growable byte buffer ---- */
typedef struct tool_bytes {
    uint8_t *data;
    size_t count, cap;
} tool_bytes;
/* Append n bytes from src; false when out of memory (b unchanged). */
bool tool_bytes_push(const sl_allocator *a, tool_bytes *b, const void *src, size_t n);
/* Release b's memory and empty it. */
void tool_bytes_free(const sl_allocator *a, tool_bytes *b);

#endif

/* The command's own small helpers (tool.h), on the public API. */
#include "tool.h"

#include <stdio.h>
#include <string.h>
#include <time.h>

sl_status tool_fail(sl_error *err, sl_status status, const char *fmt, ...)
{
    if (!err)
        return status;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->message, sizeof err->message, fmt, ap);
    va_end(ap);
    err->status = status;
    return status;
}

void tool_error_prefix(sl_error *err, const char *fmt, ...)
{
    if (!err)
        return;
    char head[256], rest[sizeof err->message];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(head, sizeof head, fmt, ap);
    va_end(ap);
    memcpy(rest, err->message, sizeof rest);
    rest[sizeof rest - 1] = 0;
    /* "HEAD: REST", cut to the message's size like any message */
    size_t cap = sizeof err->message - 1, k = 0;
    for (const char *parts[3] = {head, ": ", rest}, **q = parts; q < parts + 3; q++)
        for (const char *c = *q; *c && k < cap; c++)
            err->message[k++] = *c;
    err->message[k] = 0;
}

double tool_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static const sl_allocator *resolve(const sl_allocator *a) { return a ? a : sl_default_allocator(); }

void *tool_alloc(const sl_allocator *a, size_t size)
{
    a = resolve(a);
    return a->alloc(a->user, size, 16);
}

void *tool_calloc(const sl_allocator *a, size_t count, size_t size)
{
    size_t total;
    if (__builtin_mul_overflow(count, size, &total))
        return NULL;
    void *p = tool_alloc(a, total);
    if (p)
        memset(p, 0, total);
    return p;
}

void *tool_realloc(const sl_allocator *a, void *p, size_t old_size, size_t new_size)
{
    a = resolve(a);
    return p ? a->realloc(a->user, p, old_size, new_size, 16) : a->alloc(a->user, new_size, 16);
}

void tool_free(const sl_allocator *a, void *p, size_t size)
{
    if (p) {
        a = resolve(a);
        a->free(a->user, p, size);
    }
}

bool tool_bytes_push(const sl_allocator *a, tool_bytes *b, const void *src, size_t n)
{
    if (n > b->cap - b->count) {
        size_t cap = b->cap ? b->cap : 64;
        while (cap - b->count < n) {
            if (cap > SIZE_MAX / 2)
                return false;
            cap *= 2;
        }
        uint8_t *d = tool_realloc(a, b->data, b->cap, cap);
        if (!d)
            return false;
        b->data = d;
        b->cap = cap;
    }
    memcpy(b->data + b->count, src, n);
    b->count += n;
    return true;
}

void tool_bytes_free(const sl_allocator *a, tool_bytes *b)
{
    tool_free(a, b->data, b->cap);
    b->data = NULL;
    b->count = b->cap = 0;
}

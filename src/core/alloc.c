/* Allocation through user hooks. Every handle stores the allocator it was created with; the
 * default one is aligned malloc. Sizes are passed to free so that arena allocators work. */
#include "sl_core.h"

#include <stdlib.h>

static void *default_alloc(void *user, size_t size, size_t align)
{
    (void)user;
    if (align < sizeof(void *))
        align = sizeof(void *);
    if (size == 0)
        size = 1;
    void *p = NULL;
    if (posix_memalign(&p, align, size) != 0)
        return NULL;
    return p;
}

static void *default_realloc(void *user, void *ptr, size_t old_size, size_t new_size, size_t align)
{
    (void)user;
    if (align <= 16) {
        /* glibc malloc is 16-byte aligned: realloc can grow in place */
        return realloc(ptr, new_size ? new_size : 1);
    }
    void *p = default_alloc(user, new_size, align);
    if (!p)
        return NULL;
    if (ptr) {
        memcpy(p, ptr, SL_MIN(old_size, new_size));
        free(ptr);
    }
    return p;
}

static void default_free(void *user, void *ptr, size_t size)
{
    (void)user;
    (void)size;
    free(ptr);
}

static const sl_allocator g_default = {default_alloc, default_realloc, default_free, NULL};

const sl_allocator *sl_default_allocator(void) { return &g_default; }

const sl_allocator *sl_alloc_or_default(const sl_allocator *a) { return a ? a : &g_default; }

void *sl_alloc_aligned(const sl_allocator *a, size_t size, size_t align)
{
    a = sl_alloc_or_default(a);
    return a->alloc(a->user, size, align);
}

void *sl_alloc(const sl_allocator *a, size_t size) { return sl_alloc_aligned(a, size, 16); }

void *sl_calloc(const sl_allocator *a, size_t count, size_t size)
{
    size_t total;
    if (!sl_mul_size(count, size, &total))
        return NULL;
    void *p = sl_alloc(a, total);
    if (p)
        memset(p, 0, total);
    return p;
}

void *sl_realloc(const sl_allocator *a, void *p, size_t old_size, size_t new_size)
{
    a = sl_alloc_or_default(a);
    if (!p)
        return a->alloc(a->user, new_size, 16);
    return a->realloc(a->user, p, old_size, new_size, 16);
}

void sl_free(const sl_allocator *a, void *p, size_t size)
{
    if (!p)
        return;
    a = sl_alloc_or_default(a);
    a->free(a->user, p, size);
}

char *sl_strdup(const sl_allocator *a, const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = sl_alloc(a, n);
    if (d)
        memcpy(d, s, n);
    return d;
}

void sl_strfree(const sl_allocator *a, char *s)
{
    if (s)
        sl_free(a, s, strlen(s) + 1);
}

bool sl_array_reserve(const sl_allocator *a, sl_array *arr, size_t elem, size_t extra)
{
    if (arr->cap == 0 && arr->data && !sl_array_own(a, arr, elem))
        return false;
    size_t need;
    if (!sl_add_size(arr->count, extra, &need))
        return false;
    if (need <= arr->cap)
        return true;
    size_t cap = arr->cap ? arr->cap : 16;
    while (cap < need) {
        if (cap > SIZE_MAX / 2)
            return false;
        cap *= 2;
    }
    size_t old_bytes = arr->cap * elem, new_bytes;
    if (!sl_mul_size(cap, elem, &new_bytes))
        return false;
    void *p = sl_realloc(a, arr->data, old_bytes, new_bytes);
    if (!p)
        return false;
    arr->data = p;
    arr->cap = cap;
    return true;
}

void *sl_array_push(const sl_allocator *a, sl_array *arr, size_t elem, const void *src, size_t n)
{
    if (!sl_array_reserve(a, arr, elem, n))
        return NULL;
    char *dst = (char *)arr->data + arr->count * elem;
    if (n) {
        if (src)
            memcpy(dst, src, n * elem);
        else
            memset(dst, 0, n * elem);
    }
    arr->count += n;
    return dst;
}

bool sl_array_own(const sl_allocator *a, sl_array *arr, size_t elem)
{
    if (arr->cap != 0 || !arr->data)
        return true;
    size_t cap = arr->count ? arr->count : 1, bytes;
    if (!sl_mul_size(cap, elem, &bytes))
        return false;
    void *p = sl_alloc(a, bytes);
    if (!p)
        return false;
    memcpy(p, arr->data, arr->count * elem);
    arr->data = p;
    arr->cap = cap;
    return true;
}

void sl_array_free(const sl_allocator *a, sl_array *arr, size_t elem)
{
    if (arr->cap)
        sl_free(a, arr->data, arr->cap * elem);
    arr->data = NULL;
    arr->count = arr->cap = 0;
}

#include "support/counting_alloc.h"

#include <stdlib.h>
#include <string.h>

static void *c_alloc(void *u, size_t size, size_t align)
{
    sl_test_counter *c = u;
    void *p = NULL;
    if (posix_memalign(&p, align < sizeof(void *) ? sizeof(void *) : align, size ? size : 1))
        return NULL;
    c->live += size, c->calls++;
    if (c->live > c->peak)
        c->peak = c->live;
    return p;
}

static void *c_realloc(void *u, void *ptr, size_t old_size, size_t new_size, size_t align)
{
    sl_test_counter *c = u;
    void *p = c_alloc(u, new_size, align);
    if (p && ptr) {
        memcpy(p, ptr, old_size < new_size ? old_size : new_size);
        free(ptr);
        c->live -= old_size;
    }
    return p;
}

static void c_free(void *u, void *ptr, size_t size)
{
    sl_test_counter *c = u;
    c->live -= size;
    free(ptr);
}

sl_allocator sl_test_counting_allocator(sl_test_counter *c)
{
    sl_allocator a = {c_alloc, c_realloc, c_free, c};
    return a;
}

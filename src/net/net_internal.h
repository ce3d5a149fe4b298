/* Internal pieces shared by the server, the client and the reference of src/net: allocation
 * through an sl_allocator, error messages, the clock, and the reference's internals. The layer
 * calls the library's public API only (libsightline_net links libsightline.so). */
#ifndef SL_NET_INTERNAL_H
#define SL_NET_INTERNAL_H

#include "sightline/net.h"
#include "sightline/cull.h"
#include "sightline/pvs.h"
#include "sightline/region.h"

#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* The network threads (the server's loop, the client's) are created with SIGPIPE blocked: a
 * write to a peer that has gone (EPIPE) then fails on that connection instead of raising SIGPIPE,
 * whose default action ends the whole process. A SIGPIPE the kernel raises for a blocked thread
 * stays pending on that thread and is never delivered. The process's disposition is left alone
 * (no global state), and the creating thread's mask is restored. The workers, which never write
 * to a socket, are created with it blocked as well. */
static inline int net_thread_create(pthread_t *t, void *(*fn)(void *), void *arg)
{
    sigset_t pipe_only, old;
    sigemptyset(&pipe_only);
    sigaddset(&pipe_only, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_only, &old);
    int rc = pthread_create(t, NULL, fn, arg);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    return rc;
}

static inline void *net_alloc(const sl_allocator *a, size_t size)
{
    return a->alloc(a->user, size ? size : 1, 16);
}
static inline void *net_calloc(const sl_allocator *a, size_t size)
{
    void *p = net_alloc(a, size);
    if (p)
        memset(p, 0, size ? size : 1);
    return p;
}
static inline void net_free(const sl_allocator *a, void *p, size_t size)
{
    if (p)
        a->free(a->user, p, size ? size : 1);
}

sl_status net_fail(sl_error *err, sl_status st, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Monotonic seconds. */
static inline double net_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Split "NAME[:key=value[:key=value...]]" into name (size bytes) and the options as the cullers
 * take them ("key=value,key=value"; "" when none), into options (options_size bytes). */
sl_status net_split_spec(const char *spec, char *name, size_t size, char *options, size_t options_size,
                         sl_error *err);

/* The value of file= in an options string (false when absent or longer than size - 1). */
bool net_spec_file(const char *opts, char *out, size_t size);

/* A reference made with a PVS handle shared with others (the server's workers): pvs is borrowed
 * when not NULL (else opened from the spec's file= when the method is pvs). */
sl_status net_reference_create(sl_scene scene, const char *spec, bool reuse, sl_scene_accel accel, sl_pvs shared_pvs,
                               const sl_allocator *alloc, sl_vis_reference *out, sl_error *err);
/* The region key of a camera's eye: cell and reach level (the near-plane reach rounded up to
 * R = 0.05 m * 2^level), or false when no cell set holds there: no regions, the eye outside the
 * domain or in no cell, or the box of the eye +- R not covered by the cells. */
bool net_reference_region_key(sl_vis_reference ref, const sl_camera *cam, uint32_t *cell, uint32_t *level);
/* The set of region (cell, level): the union of the sets of the cells that the cell's box +- R
 * meets, and every dynamic object; ascending. *valid false when it meets none. */
sl_status net_reference_region_set(sl_vis_reference ref, uint32_t cell, uint32_t level, uint32_t *ids,
                                   uint32_t capacity, uint32_t *count, bool *valid, sl_error *err);
uint32_t net_reference_object_count(sl_vis_reference ref);

#endif

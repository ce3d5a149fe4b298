/* The one thread limit (SL_MAX_THREADS, include/sightline/core.h), held against what the OpenMP
 * runtime allows: asking libgomp for 100000 threads crashed it, so every thread count a caller
 * or a command gives is checked here first. */
#include "core/sl_core.h"

#include <omp.h>

uint32_t sl_thread_limit(void)
{
    int rt = omp_get_thread_limit(); /* thread-limit-var: INT_MAX unless OMP_THREAD_LIMIT is set */
    uint32_t limit = SL_MAX_THREADS;
    if (rt >= 1 && (uint32_t)rt < limit)
        limit = (uint32_t)rt;
    return limit;
}

sl_status sl_threads_check(uint32_t threads, bool zero_ok, const char *what, sl_error *err)
{
    uint32_t limit = sl_thread_limit();
    if (threads == 0 && !zero_ok)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: 0 threads (at least 1)", what ? what : "threads");
    if (threads > limit) {
        if (limit < SL_MAX_THREADS)
            return sl_fail(err, SL_ERROR_LIMIT,
                           "%s: %u threads, at most %u (the OpenMP runtime's thread limit, OMP_THREAD_LIMIT; "
                           "Sightline's own limit is SL_MAX_THREADS = %u)",
                           what ? what : "threads", threads, limit, SL_MAX_THREADS);
        return sl_fail(err, SL_ERROR_LIMIT, "%s: %u threads, at most %u (SL_MAX_THREADS)", what ? what : "threads",
                       threads, limit);
    }
    return SL_OK;
}

/* Sightline core: status codes, errors, allocator hooks, progress callbacks, version.
 *
 * Conventions shared by the whole public API:
 *  - Every fallible function returns an sl_status and takes an optional `sl_error *err` as its
 *    last argument. On failure the status is also stored in err->status and err->message holds a
 *    readable sentence naming the file, offset or element and the reason. err may be NULL.
 *  - Handles are opaque pointers created by sl_X_create/sl_X_load and released by sl_X_destroy.
 *  - Every handle remembers the allocator it was created with; NULL means malloc/free.
 *  - There is no global mutable state. Distinct handles may be used from distinct threads;
 *    one handle is not to be used from two threads at once unless its header says otherwise.
 *  - Coordinates are metres, right-handed, Z up (x east, y north). Importers convert.
 */
#ifndef SIGHTLINE_CORE_H
#define SIGHTLINE_CORE_H

#include <stddef.h>
#include <stdint.h>
#include <stdbool.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(SL_BUILDING_SHARED) && defined(__GNUC__)
#define SL_API __attribute__((visibility("default")))
#else
#define SL_API
#endif

/* The version of these headers: always CMake's project version (CMakeLists.txt refuses to
 * configure otherwise). Semantic versioning from 1.0 on: the shared libraries' SONAME carries the
 * major version (libsightline.so.MAJOR), which changes with every incompatible ABI change; the file
 * formats have versions of their own (docs/versions.md). */
#define SL_VERSION_MAJOR 0
#define SL_VERSION_MINOR 1
#define SL_VERSION_PATCH 0

/* Marks "no object / no index" wherever an id is expected. */
#define SL_NONE UINT32_MAX

typedef enum sl_status {
    SL_OK = 0,
    SL_ERROR_INVALID_ARGUMENT = 1, /* a caller passed something the contract forbids */
    SL_ERROR_OUT_OF_MEMORY = 2,
    SL_ERROR_IO = 3,               /* open/read/write/rename failed (errno in the message) */
    SL_ERROR_FORMAT = 4,           /* malformed, truncated or hostile input data */
    SL_ERROR_UNSUPPORTED = 5,      /* valid input of a kind or version we do not handle */
    SL_ERROR_NOT_FOUND = 6,        /* a named file, entry, method or key does not exist */
    SL_ERROR_LIMIT = 7,            /* a size or count beyond what the format/API allows */
    SL_ERROR_CANCELLED = 8,        /* a progress callback asked to stop */
    SL_ERROR_INTERNAL = 9
} sl_status;

/* Error report filled by a failing call. */
typedef struct sl_error {
    sl_status status;
    char message[512];
} sl_error;

/* Short constant name of a status ("format error", ...). */
SL_API const char *sl_status_string(sl_status status);

/* Allocator hooks. alloc/realloc must return memory aligned to at least `align` (a power of two,
 * at most 4096). free/realloc receive the size passed when the block was allocated. */
typedef struct sl_allocator {
    void *(*alloc)(void *user, size_t size, size_t align);
    void *(*realloc)(void *user, void *ptr, size_t old_size, size_t new_size, size_t align);
    void (*free)(void *user, void *ptr, size_t size);
    void *user;
} sl_allocator;

/* The allocator used when NULL is passed: aligned malloc/free. */
SL_API const sl_allocator *sl_default_allocator(void);

/* Progress report for long work. `stage` names what is being done; total may be 0 if unknown.
 * Returning false cancels the work, which then fails with SL_ERROR_CANCELLED. */
typedef bool (*sl_progress_fn)(void *user, const char *stage, uint64_t done, uint64_t total);

typedef struct sl_progress {
    sl_progress_fn fn;
    void *user;
} sl_progress;

/* The most threads any Sightline call or `sightline` command takes (the PVS bake's threads per
 * process, the oracle's, the bench's, the renderer's): one limit, so that a request the thread
 * runtime cannot honour is refused with this number instead of crashing inside it. */
#define SL_MAX_THREADS 256u

/* The effective thread limit: SL_MAX_THREADS, or less when the OpenMP runtime allows fewer
 * (omp_get_thread_limit(), OMP_THREAD_LIMIT). Every thread count is checked against it. This and
 * sl_threads_check ask the OpenMP runtime: full library (libsightline) only, not in
 * libsightline_runtime. */
SL_API uint32_t sl_thread_limit(void);

/* Check a requested thread count (0 means "default", allowed when zero_ok): SL_OK, or
 * SL_ERROR_LIMIT with a message "WHAT: N threads, at most LIMIT ..." naming the limit. */
SL_API sl_status sl_threads_check(uint32_t threads, bool zero_ok, const char *what, sl_error *err);

/* The version of the library linked at run time as "major.minor.patch" (a static string).
 * Thread-safe. */
SL_API const char *sl_version_string(void);
/* The same as numbers; any pointer may be NULL. A program built against other headers can compare
 * them with SL_VERSION_MAJOR/MINOR/PATCH. Thread-safe. */
SL_API void sl_version(uint32_t *major, uint32_t *minor, uint32_t *patch);

#ifdef __cplusplus
}
#endif
#endif

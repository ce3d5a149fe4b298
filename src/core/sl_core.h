/* Internal core helpers shared by every layer: allocation through the handle's allocator, error
 * reporting, growable arrays, deterministic random numbers, checked arithmetic, file helpers. */
#ifndef SL_CORE_INTERNAL_H
#define SL_CORE_INTERNAL_H

#include "sightline/core.h"
#include "sightline/geom.h"
#include "frustum_classify.h" /* margins.h with it */

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#if defined(__GNUC__)
#define SL_PRINTF(f, a) __attribute__((format(printf, f, a)))
#define SL_LIKELY(x) __builtin_expect(!!(x), 1)
#define SL_UNLIKELY(x) __builtin_expect(!!(x), 0)
#else
#define SL_PRINTF(f, a)
#define SL_LIKELY(x) (x)
#define SL_UNLIKELY(x) (x)
#endif

#define SL_MIN(a, b) ((a) < (b) ? (a) : (b))
#define SL_MAX(a, b) ((a) > (b) ? (a) : (b))
#define SL_CLAMP(x, lo, hi) SL_MIN(SL_MAX(x, lo), hi)
#define SL_COUNTOF(a) (sizeof(a) / sizeof((a)[0]))

/* ---- errors ---- */

/* Record status and a printf-style message in err (if non-NULL); returns status. */
sl_status sl_fail(sl_error *err, sl_status status, const char *fmt, ...) SL_PRINTF(3, 4);
/* Clear err to SL_OK. */
void sl_error_clear(sl_error *err);
/* Prefix err's message with "prefix: " (used to add a file name on the way up). */
void sl_error_prefix(sl_error *err, const char *fmt, ...) SL_PRINTF(2, 3);

/* ---- allocation ---- */

/* Resolve NULL to the default allocator. */
const sl_allocator *sl_alloc_or_default(const sl_allocator *a);
void *sl_alloc(const sl_allocator *a, size_t size);             /* 16-byte aligned, NULL on failure */
void *sl_alloc_aligned(const sl_allocator *a, size_t size, size_t align);
void *sl_calloc(const sl_allocator *a, size_t count, size_t size); /* zeroed, overflow-checked */
void *sl_realloc(const sl_allocator *a, void *p, size_t old_size, size_t new_size);
void sl_free(const sl_allocator *a, void *p, size_t size);
char *sl_strdup(const sl_allocator *a, const char *s);
/* Free a string from sl_strdup. */
void sl_strfree(const sl_allocator *a, char *s);

/* Overflow-checked size arithmetic: return false on overflow. */
static inline bool sl_mul_size(size_t a, size_t b, size_t *out) { return !__builtin_mul_overflow(a, b, out); }
static inline bool sl_add_size(size_t a, size_t b, size_t *out) { return !__builtin_add_overflow(a, b, out); }

/* ---- growable arrays ----
 * An sl_array is {data, count, cap} of fixed-size elements. cap == 0 with data != NULL means the
 * data is borrowed (e.g. memory-mapped) and read-only: growing it copies it first. */
typedef struct sl_array {
    void *data;
    size_t count;
    size_t cap;
} sl_array;

/* Ensure room for `extra` more elements of `elem` bytes. */
bool sl_array_reserve(const sl_allocator *a, sl_array *arr, size_t elem, size_t extra);
/* Append n elements (copied from src, or zeroed when src is NULL). Returns pointer to the first. */
void *sl_array_push(const sl_allocator *a, sl_array *arr, size_t elem, const void *src, size_t n);
/* Make a borrowed array owned (copies). */
bool sl_array_own(const sl_allocator *a, sl_array *arr, size_t elem);
void sl_array_free(const sl_allocator *a, sl_array *arr, size_t elem);
#define SL_AT(arr, T, i) (((T *)(arr).data)[i])

/* ---- deterministic random numbers: sl_rng in sightline/core.h ---- */

/* ---- hashing ---- */
uint64_t sl_hash64(const void *data, size_t size, uint64_t seed); /* XXH3-64 */

/* ---- files ---- */

/* Open an input for reading: non-blocking first (a FIFO would block open(2) for ever), then
 * refused with "PATH: not a regular file (a FIFO)" unless it is a regular file, then blocking
 * again. *fd receives the descriptor (close it), *size (may be NULL) the file's size. */
sl_status sl_file_open_read(const char *path, int *fd, uint64_t *size, sl_error *err);
/* "a directory", "a FIFO", "a character device", ... for a st_mode. */
const char *sl_file_kind_name(unsigned mode);
/* A file the library keeps open and rewrites in place (a bake journal, its lock): opened with
 * open(2) flags (O_WRONLY or O_RDWR, O_CREAT, O_TRUNC) plus O_NOFOLLOW (a symbolic link there is
 * refused: resolve it first) and O_NONBLOCK (cleared again: a FIFO never blocks), and refused
 * unless it is a regular file: "PATH: cannot use it as WHAT: it is a FIFO, not a regular file". */
sl_status sl_file_open_regular(const char *path, int flags, const char *what, int *fd, sl_error *err);
/* path with its symbolic links resolved as the atomic writer resolves an output's (the file a
 * chain of links ends at; for a dangling link, the file it would create), or path itself when
 * it is no link or does not exist; from sl_strdup(a). NULL with err set on failure. */
char *sl_file_resolve_links(const sl_allocator *a, const char *path, sl_error *err);

/* Read a whole (regular) file into memory allocated with a. */
sl_status sl_file_read_all(const sl_allocator *a, const char *path, uint8_t **out, size_t *size, sl_error *err);

/* Read-only memory map of a whole (regular) file. */
typedef struct sl_mapping { void *data; size_t size; } sl_mapping;
sl_status sl_file_map(const char *path, sl_mapping *out, sl_error *err);
void sl_file_unmap(sl_mapping *m);

/* The writer of every output. Where path is a regular file or does not exist, it writes to
 * "<target>.tmp.<pid>.<16 hex digits>" and renames that over target on commit; abort (or any
 * failure) removes the temporary file, so no partial output is ever left behind. target is path,
 * or where path's symbolic links end (the link stays, its target is replaced or, for a dangling
 * link, created). A device or a FIFO is written through (direct: opened and written, never
 * replaced; abort leaves what was written); a directory or a socket is refused. Opening also
 * removes the temporaries of the same target left by processes that no longer exist. */
typedef struct sl_atomic_file {
    FILE *fp;
    char *path;     /* as given, for messages */
    char *target;   /* the file renamed over (NULL when direct) */
    char *tmp_path; /* NULL when direct */
    const sl_allocator *alloc;
    bool failed;
    int error;      /* errno of the write that set failed (reported by commit), 0 if none */
    bool direct;    /* written through; stays set after commit or abort */
} sl_atomic_file;
sl_status sl_atomic_open(const sl_allocator *a, const char *path, sl_atomic_file *out, sl_error *err);
/* Write bytes; errors are sticky and reported by commit, with the errno of the failing write. */
void sl_atomic_write(sl_atomic_file *f, const void *data, size_t size);
/* The writer over an open file descriptor (a duplicate of fd; fd stays open): written straight
 * through from fd's offset, as for a device or a pipe; name is the file's name in messages. */
sl_status sl_atomic_open_fd(const sl_allocator *a, int fd, const char *name, sl_atomic_file *out, sl_error *err);
sl_status sl_atomic_commit(sl_atomic_file *f, sl_error *err);
void sl_atomic_abort(sl_atomic_file *f);
/* Whether name is "<base>.tmp.<pid>.<16 hex digits>" (a temporary of the writer); *pid receives pid. */
bool sl_atomic_temp_name_pid(const char *base, const char *name, long *pid);

/* ---- progress ---- */
/* Report progress; returns false when the callback asked to cancel. NULL progress is fine. */
static inline bool sl_progress_report(const sl_progress *p, const char *stage, uint64_t done, uint64_t total)
{
    return !p || !p->fn || p->fn(p->user, stage, done, total);
}

/* ---- time ---- */
/* Monotonic time in seconds. */
double sl_now(void);

/* ---- small plane geometry ---- */
/* Convex hull of n <= 8 points (x, y pairs) by Andrew's monotone chain, counter-clockwise, without
 * collinear points; writes it to hull (room for 16 values) and returns its vertex count, at least
 * 1 for n >= 1 (all points equal: that point). */
uint32_t sl_convex_hull8(const double *xy, uint32_t n, double *hull);

/* ---- floats ---- */
static inline bool sl_finite3(const float *v) { return __builtin_isfinite(v[0]) && __builtin_isfinite(v[1]) && __builtin_isfinite(v[2]); }

#endif

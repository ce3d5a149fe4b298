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
#include <stdio.h>

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

/* ---- outputs written atomically ----
 * The writer of every file the library and the command write. Where path is a regular file or
 * does not exist, the bytes go to a temporary "<target>.tmp.<pid>.<16 hex digits>" beside it,
 * renamed over target on commit; abort (or any failure) removes the temporary, so no partial file
 * is ever left behind. target is path, or where path's symbolic links end (the link stays). A
 * device or a FIFO is written through; a directory or a socket is refused. Opening also removes
 * the temporaries of the same target left by processes that no longer exist. One output is used by
 * one thread at a time; distinct outputs may be used from distinct threads. */
typedef struct sl_output_t *sl_output;

/* Open an output for path (alloc may be NULL). */
SL_API sl_status sl_output_open(const char *path, const sl_allocator *alloc, sl_output *out, sl_error *err);
/* The stdio stream to write to (valid until commit or abort). A write error is sticky
 * (ferror) and reported by sl_output_commit. */
SL_API FILE *sl_output_stream(sl_output out);
/* Flush, sync and put the file in place; on any write error "PATH: write failed: REASON"
 * (SL_ERROR_IO) and the temporary is removed. Releases out either way. */
SL_API sl_status sl_output_commit(sl_output out, sl_error *err);
/* Drop what was written (the temporary is removed) and release out. NULL is ignored. */
SL_API void sl_output_abort(sl_output out);
/* Whether name is "<base>.tmp.<pid>.<16 hex digits>", the name of a temporary of the writer (pid:
 * decimal without a leading zero, at most INT_MAX); *pid receives pid. Also the pattern of the
 * command's staged output folders, so that a later run can remove those of a process that is
 * gone. Pure, thread-safe. */
SL_API bool sl_output_temp_name_pid(const char *base, const char *name, long *pid);

/* ---- reading untrusted text (command lines, option strings) ----
 * Pure functions: no allocation, no messages (the caller names what it read), thread-safe. They
 * are fuzzed (fuzz/fuzz_options.c) as readers of hostile text. */

/* Exactly n (1..16) comma-separated finite numbers ("1.5,-2,3e2"), as floats: each must convert
 * to a finite float (3e39 is refused, 1e-50 reads as 0); nothing may follow the last. On failure
 * out is left unchanged. */
SL_API bool sl_parse_floats(const char *text, float *out, int n);

/* A frame range "A:B" (frames A to B-1), "A:" (A to the end), ":B" (0 to B-1), ":" (all) or "A"
 * (frame A alone), decimal digits only (no sign, no white space), into *first and *end (one past
 * the last frame; UINT32_MAX: to the end). A must be below B and below UINT32_MAX (a path holds
 * fewer than 2^32 frames, so frame UINT32_MAX never exists), B at most UINT32_MAX. The `bench` and
 * `render` commands' --frames. *first and *end are untouched on failure. */
SL_API bool sl_parse_range(const char *text, uint32_t *first, uint32_t *end);

/* ---- "did you mean": the nearest names to a mistyped one ----
 * Pure, allocation-free, thread-safe; for messages (unknown options, methods, maps, commands). */

/* Edit distance between a and b, ASCII case folded: insertions, deletions, substitutions and
 * swaps of two neighbours count 1 each (optimal string alignment). Only the first 63 bytes of each
 * count; a longer tail adds its length. */
SL_API uint32_t sl_text_distance(const char *a, const char *b);

/* The candidates close to `word` (distance at most 1 for words of up to 4 characters, 2 up to 8,
 * 3 beyond; or one is a prefix of the other, at least 3 characters long), nearest first (ties in
 * the candidates' order), at most 3, written to out as "a, b or c" (size bytes, always
 * terminated; "" when none). NULL candidates are skipped. Returns how many were written. */
SL_API uint32_t sl_text_suggest(const char *word, const char *const *candidates, size_t count, char *out, size_t size);

/* ---- text made safe for a terminal or a log ---- */

/* Copy text (names, paths, importers' messages) into buf (size bytes, always terminated) C-style:
 * control bytes (below 0x20, 0x7f), C1 controls (U+0080..U+009F), bytes that are not well-formed
 * UTF-8 and backslashes are written as \xNN (a backslash as \\); well-formed UTF-8 passes
 * unchanged. At most max_in input bytes are read; when the input is longer (or buf fills), "..."
 * ends the result. Returns buf. Pure, thread-safe. */
SL_API char *sl_escape_text(const char *text, size_t max_in, char *buf, size_t size);

/* Length of the well-formed UTF-8 sequence at s (1..4, at most n bytes), or 0 when the bytes are
 * not one (overlong, surrogate, beyond U+10FFFF, truncated, or a C1 control). ASCII counts as 1,
 * controls included: the caller decides about those. Pure, thread-safe. */
SL_API size_t sl_utf8_sequence(const unsigned char *s, size_t n);

/* ---- deterministic random numbers ----
 * PCG32 (XSH RR, 64-bit state): the same seed and stream give the same numbers on every machine
 * and in every version (generated cities and sampled tests depend on it). A generator is plain
 * data, used by one thread at a time. */
typedef struct sl_rng { uint64_t state, inc; } sl_rng;
/* Seed a generator; distinct streams give independent sequences for one seed. */
SL_API void sl_rng_seed(sl_rng *r, uint64_t seed, uint64_t stream);
/* The next 32 random bits. */
SL_API uint32_t sl_rng_u32(sl_rng *r);
/* Uniform in [0,1). */
SL_API float sl_rng_float(sl_rng *r);
SL_API double sl_rng_double(sl_rng *r);
/* Uniform in [lo,hi). */
SL_API float sl_rng_range(sl_rng *r, float lo, float hi);
/* Uniform integer in [0,n), n > 0, unbiased. */
SL_API uint32_t sl_rng_below(sl_rng *r, uint32_t n);

#ifdef __cplusplus
}
#endif
#endif

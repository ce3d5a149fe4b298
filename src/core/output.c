/* The public face of the atomic writer (sightline/core.h: sl_output): an sl_atomic_file on the
 * heap of the caller's allocator. */
#include "sl_core.h"

struct sl_output_t {
    sl_atomic_file file;
    const sl_allocator *alloc;
};

sl_status sl_output_open(const char *path, const sl_allocator *alloc, sl_output *out, sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_output_open: path and out must not be NULL");
    if (!path[0])
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "an empty output path");
    *out = NULL;
    alloc = sl_alloc_or_default(alloc);
    sl_output o = sl_calloc(alloc, 1, sizeof *o);
    if (!o)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    o->alloc = alloc;
    sl_status st = sl_atomic_open(alloc, path, &o->file, err);
    if (st != SL_OK) {
        sl_free(alloc, o, sizeof *o);
        return st;
    }
    *out = o;
    return SL_OK;
}

FILE *sl_output_stream(sl_output out) { return out ? out->file.fp : NULL; }

sl_status sl_output_commit(sl_output out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_output_commit: no output");
    if (out->file.fp && ferror(out->file.fp))
        out->file.failed = true;
    sl_status st = sl_atomic_commit(&out->file, err);
    sl_free(out->alloc, out, sizeof *out);
    return st;
}

void sl_output_abort(sl_output out)
{
    if (!out)
        return;
    sl_atomic_abort(&out->file);
    sl_free(out->alloc, out, sizeof *out);
}

bool sl_output_temp_name_pid(const char *base, const char *name, long *pid)
{
    return sl_atomic_temp_name_pid(base, name, pid);
}

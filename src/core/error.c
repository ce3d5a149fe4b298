/* Status strings and error reporting. */
#include "sl_core.h"

const char *sl_status_string(sl_status status)
{
    switch (status) {
    case SL_OK: return "ok";
    case SL_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case SL_ERROR_OUT_OF_MEMORY: return "out of memory";
    case SL_ERROR_IO: return "i/o error";
    case SL_ERROR_FORMAT: return "format error";
    case SL_ERROR_UNSUPPORTED: return "unsupported";
    case SL_ERROR_NOT_FOUND: return "not found";
    case SL_ERROR_LIMIT: return "limit exceeded";
    case SL_ERROR_CANCELLED: return "cancelled";
    case SL_ERROR_INTERNAL: return "internal error";
    }
    return "unknown status";
}

sl_status sl_fail(sl_error *err, sl_status status, const char *fmt, ...)
{
    if (err) {
        err->status = status;
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return status;
}

void sl_error_clear(sl_error *err)
{
    if (err) {
        err->status = SL_OK;
        err->message[0] = 0;
    }
}

void sl_error_prefix(sl_error *err, const char *fmt, ...)
{
    if (!err)
        return;
    char prefix[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    char old[sizeof err->message];
    memcpy(old, err->message, sizeof old);
    /* compose by hand: the result is deliberately truncated to the message size */
    size_t np = strnlen(prefix, sizeof prefix), cap = sizeof err->message - 1, k = 0;
    for (size_t i = 0; i < np && k < cap; i++)
        err->message[k++] = prefix[i];
    for (const char *sep = ": "; *sep && k < cap; sep++)
        err->message[k++] = *sep;
    for (size_t i = 0; old[i] && k < cap; i++)
        err->message[k++] = old[i];
    err->message[k] = 0;
}

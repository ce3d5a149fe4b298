/* The key=value option reader shared by the cullers (src/cull) and the PVS bake methods
 * (src/region): see opts.h. Moved here from cull/culler.c so that both layers use it from below. */
#include "opts.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static bool key_char(char c) { return isalnum((unsigned char)c) || c == '_' || c == '.' || c == '-'; }
static bool separator(char c) { return c == ',' || isspace((unsigned char)c); }

sl_status sl_opts_parse(sl_opts *o, const char *method, const char *options, sl_error *err)
{
    memset(o, 0, sizeof *o);
    o->method = method ? method : "culler";
    if (!options)
        return SL_OK;
    size_t len = strlen(options);
    if (len > SL_OPTS_MAX_CHARS)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: the options string is %zu characters long (at most %u)",
                       o->method, len, SL_OPTS_MAX_CHARS);
    memcpy(o->text, options, len + 1);
    char *p = o->text;
    while (*p) {
        if (separator(*p)) {
            *p++ = 0;
            continue;
        }
        char *item = p;
        while (*p && !separator(*p))
            p++;
        if (*p)
            *p++ = 0;
        char *eq = strchr(item, '=');
        if (!eq)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "%s: option '%s' is not key=value (items are separated by commas or spaces, with no "
                           "space around '=')", o->method, item);
        *eq = 0;
        const char *key = item, *value = eq + 1;
        if (!*key)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option '=%s' has no key", o->method, value);
        for (const char *k = key; *k; k++)
            if (!key_char(*k))
                return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                               "%s: option key '%s' has the character '%c' (keys use letters, digits, '_', '.', '-')",
                               o->method, key, *k);
        if (!*value)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option '%s' has an empty value", o->method, key);
        for (uint32_t i = 0; i < o->count; i++)
            if (strcmp(o->keys[i], key) == 0)
                return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option '%s' is given twice ('%s' and '%s')",
                               o->method, key, o->values[i], value);
        if (o->count == SL_OPTS_MAX_ENTRIES)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: more than %u options", o->method, SL_OPTS_MAX_ENTRIES);
        o->keys[o->count] = key;
        o->values[o->count] = value;
        o->count++;
    }
    return SL_OK;
}

/* Note that `key` is valid, append its effective value, and return the given value or NULL. */
static const char *lookup(sl_opts *o, const char *key)
{
    bool known = false;
    for (uint32_t i = 0; i < o->known_count; i++)
        known |= strcmp(o->known[i], key) == 0;
    if (!known && o->known_count < SL_OPTS_MAX_ENTRIES)
        o->known[o->known_count++] = key;
    for (uint32_t i = 0; i < o->count; i++)
        if (strcmp(o->keys[i], key) == 0) {
            o->used[i] = true;
            return o->values[i];
        }
    return NULL;
}

static void record(sl_opts *o, const char *key, const char *fmt, ...) SL_PRINTF(3, 4);
static void record(sl_opts *o, const char *key, const char *fmt, ...)
{
    size_t n = strlen(o->effective);
    char value[128];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(value, sizeof value, fmt, ap);
    va_end(ap);
    /* a report string: silently truncated at the (generous) limit */
    snprintf(o->effective + n, sizeof o->effective - n, "%s%s=%s", n ? "," : "", key, value);
}

sl_status sl_opts_u32(sl_opts *o, const char *key, uint32_t def, uint32_t min, uint32_t max, uint32_t *out, sl_error *err)
{
    const char *v = lookup(o, key);
    uint32_t x = def;
    if (v) {
        bool digits = true;
        for (const char *c = v; *c; c++)
            digits &= *c >= '0' && *c <= '9';
        errno = 0;
        unsigned long long u = digits ? strtoull(v, NULL, 10) : 0;
        if (!digits || errno == ERANGE || u > UINT32_MAX)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s=%s: expected a whole number in [%u, %u]",
                           o->method, key, v, min, max);
        x = (uint32_t)u;
        if (x < min || x > max)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s=%s is outside [%u, %u]", o->method, key, v,
                           min, max);
    }
    *out = x;
    record(o, key, "%u", x);
    return SL_OK;
}

sl_status sl_opts_float(sl_opts *o, const char *key, float def, float min, float max, float *out, sl_error *err)
{
    const char *v = lookup(o, key);
    float x = def;
    if (v) {
        char *end = NULL;
        errno = 0;
        double d = strtod(v, &end);
        if (end == v || *end || !isfinite(d) || isspace((unsigned char)*v))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s=%s: expected a finite number in [%g, %g]",
                           o->method, key, v, (double)min, (double)max);
        if (!(d >= min && d <= max))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s=%s is outside [%g, %g]", o->method, key, v,
                           (double)min, (double)max);
        x = (float)d;
    }
    *out = x;
    record(o, key, "%g", (double)x);
    return SL_OK;
}

sl_status sl_opts_bool(sl_opts *o, const char *key, bool def, bool *out, sl_error *err)
{
    static const char *const yes[] = {"true", "1", "yes", "on"}, *const no[] = {"false", "0", "no", "off"};
    const char *v = lookup(o, key);
    bool x = def;
    if (v) {
        int found = -1;
        for (size_t i = 0; i < SL_COUNTOF(yes); i++) {
            if (strcasecmp(v, yes[i]) == 0)
                found = 1;
            if (strcasecmp(v, no[i]) == 0)
                found = 0;
        }
        if (found < 0)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "%s: option %s=%s: expected true/false (also 1/0, yes/no, on/off)", o->method, key, v);
        x = found == 1;
    }
    *out = x;
    record(o, key, "%s", x ? "true" : "false");
    return SL_OK;
}

sl_status sl_opts_string(sl_opts *o, const char *key, const char **out, sl_error *err)
{
    (void)err;
    *out = lookup(o, key);
    /* the report string keeps at most 127 characters of a value (record) */
    record(o, key, "%s", *out ? *out : "none");
    return SL_OK;
}

sl_status sl_opts_enum(sl_opts *o, const char *key, const char *const *names, uint32_t count, uint32_t def,
                       uint32_t *out, sl_error *err)
{
    const char *v = lookup(o, key);
    uint32_t x = def;
    if (v) {
        x = count;
        for (uint32_t i = 0; i < count; i++)
            if (strcmp(v, names[i]) == 0)
                x = i;
        if (x == count) {
            char list[256] = "";
            for (uint32_t i = 0; i < count; i++) {
                size_t n = strlen(list);
                snprintf(list + n, sizeof list - n, "%s%s", i ? ", " : "", names[i]);
            }
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s=%s: expected one of %s", o->method, key, v,
                           list);
        }
    }
    *out = x;
    record(o, key, "%s", x < count ? names[x] : "?");
    return SL_OK;
}

sl_status sl_opts_check_unused(const sl_opts *o, sl_error *err)
{
    for (uint32_t i = 0; i < o->count; i++) {
        if (o->used[i])
            continue;
        if (o->known_count == 0)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: unknown option '%s' (%s takes no options)", o->method,
                           o->keys[i], o->method);
        char list[384] = "";
        for (uint32_t k = 0; k < o->known_count; k++) {
            size_t n = strlen(list);
            snprintf(list + n, sizeof list - n, "%s%s", k ? ", " : "", o->known[k]);
        }
        char near[160];
        if (sl_text_suggest(o->keys[i], (const char *const *)o->known, o->known_count, near, sizeof near))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: unknown option '%s' (did you mean %s? valid options: %s)",
                           o->method, o->keys[i], near, list);
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: unknown option '%s' (valid options: %s)", o->method,
                       o->keys[i], list);
    }
    return SL_OK;
}

/* Internal (core): the "key=value,..." option reader of the cullers (src/cull) and the PVS bake
 * methods (src/region). */
#ifndef SL_CORE_OPTS_H
#define SL_CORE_OPTS_H

#include "sl_core.h"

#define SL_OPTS_MAX_ENTRIES 32
#define SL_OPTS_MAX_CHARS 1024

/* Parsed "key=value" options. Keys and values point into `text`. Every getter records the key it
 * asked for (so an unknown key can be answered with the list of valid ones) and the value it
 * settled on (so the culler can report its effective options). */
typedef struct sl_opts {
    const char *method;                     /* for messages */
    char text[SL_OPTS_MAX_CHARS + 1];
    uint32_t count;
    const char *keys[SL_OPTS_MAX_ENTRIES];
    const char *values[SL_OPTS_MAX_ENTRIES];
    bool used[SL_OPTS_MAX_ENTRIES];
    uint32_t known_count;
    const char *known[SL_OPTS_MAX_ENTRIES]; /* keys asked for, in order (static strings) */
    char effective[SL_OPTS_MAX_CHARS + 1];  /* "key=value,..." of every key asked for */
} sl_opts;

/* Parse an options string (NULL or empty: none). Separators are commas and white space; each
 * item is key=value with a non-empty key of [A-Za-z0-9_.-] and a non-empty value; a key may not
 * repeat. */
sl_status sl_opts_parse(sl_opts *o, const char *method, const char *options, sl_error *err);

/* Typed getters (float and bool exported: the render layer's gpu-hiz, libsightline_render, reads its
 * options with them): *out receives the value given for `key`, or `def` when the key is absent. A
 * malformed or out-of-range value fails with SL_ERROR_INVALID_ARGUMENT naming the key. */
sl_status sl_opts_u32(sl_opts *o, const char *key, uint32_t def, uint32_t min, uint32_t max, uint32_t *out, sl_error *err);
SL_API sl_status sl_opts_float(sl_opts *o, const char *key, float def, float min, float max, float *out, sl_error *err);
/* true/false, 1/0, yes/no, on/off (any case). */
SL_API sl_status sl_opts_bool(sl_opts *o, const char *key, bool def, bool *out, sl_error *err);
/* One of names[0..count-1] (exact match); *out is its index. */
sl_status sl_opts_enum(sl_opts *o, const char *key, const char *const *names, uint32_t count, uint32_t def,
                       uint32_t *out, sl_error *err);

/* A string value (copy it: it points into o's text); *out is NULL when the key is absent, which
 * is recorded as "none". Values cannot hold commas or white space (the separators). */
sl_status sl_opts_string(sl_opts *o, const char *key, const char **out, sl_error *err);

/* After configure: fail naming the first key no getter asked for, with the valid keys. */
sl_status sl_opts_check_unused(const sl_opts *o, sl_error *err);

#endif

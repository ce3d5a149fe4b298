/* Object names (scene.h: sl_scene_set_object_name, sl_scene_object_name): the node names an
 * importer keeps, or an engine's own, stored per object in object order. In memory as in a
 * .slscene 1.1 file (sections ONAM, NAMT): a length per object (0: no name) and the names' bytes,
 * each followed by a NUL, in object order; the start of each name is derived. */
#include "scene_internal.h"

#include "core/sl_core.h"

#include <string.h>

#define A(s) (&(s)->alloc)

/* NULL when text[0..len) is a valid name: at most SL_OBJECT_NAME_MAX bytes of well-formed UTF-8
 * without NUL or control bytes; else why not. */
static const char *name_problem(const char *text, size_t len)
{
    if (len > SL_OBJECT_NAME_MAX)
        return "is longer than SL_OBJECT_NAME_MAX bytes";
    for (size_t i = 0; i < len;) {
        const unsigned char c = (const unsigned char)text[i];
        if (c < 0x20 || c == 0x7f)
            return "holds a control byte or NUL";
        size_t n = sl_utf8_sequence((const unsigned char *)text + i, len - i);
        if (!n)
            return "is not well-formed UTF-8";
        i += n;
    }
    return NULL;
}

/* The derived starts from the lengths. */
static void index_names(struct sl_scene_t *s)
{
    uint32_t *off = (uint32_t *)s->object_name_off.data;
    const uint32_t *len = (const uint32_t *)s->object_name_len.data;
    uint64_t at = 0;
    for (size_t i = 0; i < s->object_name_len.count; i++) {
        off[i] = (uint32_t)at;
        if (len[i])
            at += (uint64_t)len[i] + 1;
    }
}

/* Lengths and starts cover every object (names were set, or objects added after some were). */
static bool cover_objects(struct sl_scene_t *s)
{
    size_t n = s->objects.count, have = s->object_name_len.count;
    if (have >= n)
        return true;
    if (!sl_array_reserve(A(s), &s->object_name_len, sizeof(uint32_t), n - have) ||
        !sl_array_reserve(A(s), &s->object_name_off, sizeof(uint32_t), n - have))
        return false;
    uint32_t end = (uint32_t)s->object_name_text.count;
    sl_array_push(A(s), &s->object_name_len, sizeof(uint32_t), NULL, n - have);
    for (size_t i = have; i < n; i++)
        sl_array_push(A(s), &s->object_name_off, sizeof(uint32_t), &end, 1);
    return true;
}

sl_status sl_scene_set_object_name(sl_scene s, uint32_t object, const char *name, sl_error *err)
{
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_object_name: scene is NULL");
    if (object >= s->objects.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_object_name: object %u does not exist (%zu objects)",
                       object, s->objects.count);
    size_t len = name ? strlen(name) : 0;
    const char *why = name_problem(name ? name : "", len);
    if (why) {
        char shown[120];
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_object_name: object %u: the name \"%s\" %s", object,
                       sl_escape_text(name, 60, shown, sizeof shown), why);
    }
    if (!len && !s->object_name_len.count)
        return SL_OK; /* no names at all, and none given */
    if (s->object_name_text.count + len + 1 > UINT32_MAX)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_name: names exceed 4 GiB");
    if (!cover_objects(s) || !sl_array_own(A(s), &s->object_name_len, sizeof(uint32_t)) ||
        !sl_array_own(A(s), &s->object_name_text, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_name: out of memory");
    uint32_t *lens = (uint32_t *)s->object_name_len.data, *offs = (uint32_t *)s->object_name_off.data;
    size_t old = lens[object] ? (size_t)lens[object] + 1 : 0, now = len ? len + 1 : 0, at = offs[object];
    size_t tail = s->object_name_text.count - at - old;
    /* make room (or close the gap) for the new name in place, then index again */
    if (now > old) {
        if (!sl_array_reserve(A(s), &s->object_name_text, 1, now - old))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_name: out of memory");
        sl_array_push(A(s), &s->object_name_text, 1, NULL, now - old);
    }
    char *text = (char *)s->object_name_text.data;
    memmove(text + at + now, text + at + old, tail);
    if (now < old)
        s->object_name_text.count -= old - now;
    if (len) {
        memcpy(text + at, name, len);
        text[at + len] = 0;
    }
    lens[object] = (uint32_t)len;
    if (now != old || object + 1 < s->object_name_len.count)
        index_names(s);
    return SL_OK;
}

const char *sl_scene_object_name(sl_scene s, uint32_t object)
{
    if (!s || object >= s->object_name_len.count || object >= s->object_name_off.count)
        return "";
    if (!SL_AT(s->object_name_len, uint32_t, object))
        return "";
    return (const char *)s->object_name_text.data + SL_AT(s->object_name_off, uint32_t, object);
}

uint32_t sl_scene_find_object(sl_scene s, const char *name)
{
    if (!s || !name || !name[0])
        return SL_NONE;
    size_t len = strlen(name);
    for (size_t i = 0; i < s->object_name_len.count; i++)
        if (SL_AT(s->object_name_len, uint32_t, i) == len &&
            !memcmp((const char *)s->object_name_text.data + SL_AT(s->object_name_off, uint32_t, i), name, len))
            return (uint32_t)i;
    return SL_NONE;
}

void sl_scene_names_on_add(struct sl_scene_t *s)
{
    /* the object just added has no name; room was reserved by sl_scene_names_reserve */
    if (!s->object_name_len.count)
        return;
    uint32_t zero = 0, end = (uint32_t)s->object_name_text.count;
    sl_array_push(A(s), &s->object_name_len, sizeof(uint32_t), &zero, 1);
    sl_array_push(A(s), &s->object_name_off, sizeof(uint32_t), &end, 1);
}

bool sl_scene_names_reserve(struct sl_scene_t *s)
{
    return !s->object_name_len.count || (sl_array_own(A(s), &s->object_name_len, sizeof(uint32_t)) &&
                                         sl_array_reserve(A(s), &s->object_name_len, sizeof(uint32_t), 1) &&
                                         sl_array_reserve(A(s), &s->object_name_off, sizeof(uint32_t), 1));
}

void sl_scene_names_free(struct sl_scene_t *s)
{
    sl_array_free(A(s), &s->object_name_len, sizeof(uint32_t));
    sl_array_free(A(s), &s->object_name_text, 1);
    sl_array_free(A(s), &s->object_name_off, sizeof(uint32_t));
}

sl_status sl_scene_names_load(struct sl_scene_t *s, sl_error *err)
{
    size_t n = s->object_name_len.count;
    if (!n) {
        if (s->object_name_text.count)
            return sl_fail(err, SL_ERROR_FORMAT, "object names: %zu bytes of names but no name lengths",
                           s->object_name_text.count);
        return SL_OK;
    }
    if (n != s->objects.count)
        return sl_fail(err, SL_ERROR_FORMAT, "object names: %zu lengths for %zu objects", n, s->objects.count);
    const uint32_t *len = (const uint32_t *)s->object_name_len.data;
    const char *text = (const char *)s->object_name_text.data;
    uint64_t at = 0;
    for (size_t i = 0; i < n; i++) {
        if (!len[i])
            continue;
        if ((uint64_t)len[i] + 1 > s->object_name_text.count - at)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: name of %u bytes at byte %llu runs past the %zu bytes of names",
                           i, len[i], (unsigned long long)at, s->object_name_text.count);
        const char *why = name_problem(text + at, len[i]);
        if (why)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: name at byte %llu %s", i, (unsigned long long)at, why);
        if (text[at + len[i]] != 0)
            return sl_fail(err, SL_ERROR_FORMAT, "object %zu: name at byte %llu is not followed by a NUL", i,
                           (unsigned long long)at);
        at += (uint64_t)len[i] + 1;
    }
    if (at != s->object_name_text.count)
        return sl_fail(err, SL_ERROR_FORMAT, "object names: %llu bytes used by the names, section has %zu",
                       (unsigned long long)at, s->object_name_text.count);
    s->object_name_off.count = 0;
    if (!sl_array_reserve(A(s), &s->object_name_off, sizeof(uint32_t), n))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "object names: out of memory");
    sl_array_push(A(s), &s->object_name_off, sizeof(uint32_t), NULL, n);
    index_names(s);
    return SL_OK;
}

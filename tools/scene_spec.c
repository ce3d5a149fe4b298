/* The scene argument of `bench`, `render` and `demo` (cli.h: cli_open_scene): a generated city by
 * preset and seed, or a file of any format sl_scene_open_with reads. Public API only. */
#include "cli.h"
#include "tool.h"

#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/slscene.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* text[0..len) into label, each character outside [A-Za-z0-9._-] as '-'; "s" for nothing. */
static void put_label(char *label, size_t size, const char *text, size_t len)
{
    if (!label || !size)
        return;
    size_t n = 0;
    while (n < len && n + 1 < size) {
        char c = text[n];
        bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '-';
        label[n++] = keep ? c : '-';
    }
    if (n == 0 && size > 1)
        label[n++] = 's';
    label[n] = 0;
}

/* "city:PRESET[:SEED]" (spec starts with "city:"). */
static sl_status open_city(const char *spec, const char *map, const sl_progress *progress, sl_scene *out,
                           char *label, size_t label_size, sl_error *err)
{
    const char *name = spec + 5, *colon = strchr(name, ':');
    char preset_name[32];
    size_t len = TOOL_MIN(colon ? (size_t)(colon - name) : strlen(name), sizeof preset_name - 1);
    memcpy(preset_name, name, len);
    preset_name[len] = 0;
    sl_city_preset preset;
    if (sl_city_preset_from_name(preset_name, &preset, NULL) != SL_OK)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT,
                         "scene '%s': unknown city preset '%s' (use city:tiny, city:small, city:vienna, city:oldtown or city:oldtown-small, "
                         "optionally :SEED)", spec, preset_name);
    if (map)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "scene '%s': a map name only applies to .pk3 archives", spec);
    sl_city_options co = sl_city_defaults(preset);
    if (colon) {
        const char *digits = colon + 1;
        char *end;
        errno = 0;
        unsigned long long seed = strtoull(digits, &end, 10);
        if (!*digits || *end || errno || *digits == '-' || *digits == '+' || *digits == ' ')
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT,
                             "scene '%s': the seed '%s' is not a non-negative integer", spec, digits);
        co.seed = seed;
    }
    if (progress)
        co.progress = *progress;
    sl_status st = sl_gen_city(&co, NULL, out, err);
    if (st != SL_OK) {
        tool_error_prefix(err, "scene '%s'", spec);
        return st;
    }
    char text[96];
    snprintf(text, sizeof text, "city-%s-%llu", sl_city_preset_name(preset), (unsigned long long)co.seed);
    put_label(label, label_size, text, strlen(text));
    return SL_OK;
}

sl_status cli_open_scene(const char *spec, const char *map, const struct sl_import_options *opt,
                         const sl_progress *progress, sl_scene *out, char *label, size_t label_size, sl_error *err)
{
    *out = NULL;
    if (!strncmp(spec, "city:", 5))
        return open_city(spec, map, progress, out, label, label_size, err);
    sl_status st = sl_scene_open_with(spec, map, opt, NULL, out, err);
    if (st != SL_OK) {
        tool_error_prefix(err, "scene"); /* which argument: "scene: FILE: reason" */
        return st;
    }
    const char *base = strrchr(spec, '/');
    base = base ? base + 1 : spec;
    const char *dot = strrchr(base, '.');
    size_t len = dot && dot != base ? (size_t)(dot - base) : strlen(base);
    if (map) {
        char text[256];
        snprintf(text, sizeof text, "%.*s-%s", (int)TOOL_MIN(len, 120), base, map);
        put_label(label, label_size, text, strlen(text));
    } else {
        put_label(label, label_size, base, len);
    }
    return SL_OK;
}

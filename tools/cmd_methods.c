/* `sightline methods`: the culling methods of the registry (cull.h), each with its guarantee, its
 * one-line summary and its options. Whatever src/cull/registry.c lists appears here. */
#include "cli.h"

#include "sightline/cull.h"
#include "sightline/import.h"
#include "sightline/scene.h"

#include <string.h>

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline methods [NAME...] [--long] [--scene SCENE [--map NAME]] [--json]\n\n"
            "List the registered culling methods. By default a short table: name, guarantee\n"
            "(conservative: never drops a visible object, held to the oracle with zero tolerance;\n"
            "conservative-at-resolution: the same at the resolution it culls at; aggressive: may drop\n"
            "some, its missed pixels are measured) and the scenes it suits. With NAME or --long: what\n"
            "each method does and its options (key=TYPE (default D): meaning). Options are given to\n"
            "bench, render and view as --methods NAME:key=value:key=value.\n\n"
            "options:\n"
            "  NAME...   only these methods, in full (an unknown name is a usage error, exit status 2)\n"
            "  --long    every method in full\n"
            "  --scene SCENE  also say, per method, whether it applies to SCENE (a file or city:PRESET):\n"
            "            \"not applicable\" with the reason when the scene lacks what the method culls with\n"
            "            (footprints for the 2.5D methods, occluders for the occlusion methods; bench and\n"
            "            demo do not run those), \"needs options\" when it cannot run with its defaults\n"
            "  --map NAME     the map of a .pk3 given as --scene\n"
            "  --json    machine-readable output on stdout (always in full)\n"
            "  --help    this text\n\n"
            "examples:\n"
            "  sightline methods\n"
            "  sightline methods hzb\n"
            "  sightline methods vfc --json\n"
            "  sightline methods --scene model.slscene\n");
}

/* Print an options help text indented, one option per line. */
static void print_indented(const char *text, const char *indent)
{
    const char *p = text;
    while (p && *p) {
        const char *nl = strchr(p, '\n');
        size_t len = nl ? (size_t)(nl - p) : strlen(p);
        if (len)
            printf("%s%.*s\n", indent, (int)len, p);
        p = nl ? nl + 1 : NULL;
    }
}

static int list(const char *cmd, const char *const *only, uint32_t only_count, bool full, bool json, sl_scene scene,
                const char *label);

int sl_cmd_methods(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    const char *name, *val;
    bool json = false, full = false;
    const char *only[64];
    uint32_t only_count = 0;
    cli_common com = {0};
    const char *scene_spec = NULL;
    cli_import imp = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_JSON | CLI_MAP, &com)) {
        } else if (name && !strcmp(name, "scene")) {
            scene_spec = cli_value(&a, name, val);
        } else if (name && cli_import_option(&a, name, val, &imp)) {
        } else if (name && !strcmp(name, "long")) {
            full = true;
        } else if (!name) {
            if (only_count == 64) {
                cli_error(argv[0], "too many method names");
                return 2;
            }
            only[only_count++] = val;
        } else {
            cli_unknown(&a, name);
        }
    }
    json = com.json;
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    if (com.map && !scene_spec) {
        cli_error(argv[0], "--map needs --scene");
        return 2;
    }
    sl_error err;
    sl_scene scene = NULL;
    char label[256] = "";
    if (scene_spec) {
        sl_import_options io = sl_import_defaults();
        cli_import_apply(&imp, &io);
        if (cli_open_scene(scene_spec, com.map, &io, NULL, &scene, label, sizeof label, &err) != SL_OK)
            return cli_fail(argv[0], &err);
    }
    int rc = list(argv[0], only, only_count, full, json, scene, label);
    sl_scene_destroy(scene);
    return rc;
}

/* Whether method d applies to scene with its default options: 1 yes, 0 not applicable (why), -1
 * needs options (why: the method's message). */
static int applies(const sl_cull_method_desc *d, sl_scene scene, char *why, size_t why_size)
{
    bool ok = true;
    sl_error err;
    if (sl_cull_method_applicable(d->name, NULL, scene, &ok, why, why_size, &err) != SL_OK) {
        snprintf(why, why_size, "%s", err.message);
        return -1;
    }
    return ok ? 1 : 0;
}

static const char *applies_word(int a) { return a > 0 ? "yes" : a == 0 ? "not applicable" : "needs options"; }

static int list(const char *cmd, const char *const *only, uint32_t only_count, bool full, bool json, sl_scene scene,
                const char *label)
{
    sl_error err;
    char why[512];
    uint32_t idx[64];
    uint32_t count = 0;
    if (only_count) {
        for (uint32_t i = 0; i < only_count; i++)
            if (sl_cull_method_find(only[i], &idx[count++], &err) != SL_OK) {
                cli_error(cmd, "%s", err.message);
                return 2;
            }
    } else {
        uint32_t n = sl_cull_method_count();
        for (uint32_t i = 0; i < n && count < 64; i++)
            idx[count++] = i;
    }
    if (!json && !full && !only_count) {
        /* the short table */
        if (scene)
            printf("%-12s %-33s %-15s %s\n", "method", "guarantee", "applies", "suits");
        else
            printf("%-12s %-33s %s\n", "method", "guarantee", "suits");
        for (uint32_t i = 0; i < count; i++) {
            sl_cull_method_desc d;
            if (sl_cull_method_info(idx[i], &d, &err) != SL_OK)
                return cli_fail(cmd, &err);
            char g[64];
            snprintf(g, sizeof g, "%s%s", sl_cull_guarantee_name(d.guarantee), d.res_culling ? " (res=culling: @res)" : "");
            if (scene)
                printf("%-12s %-33s %-15s %s\n", d.name, g, applies_word(applies(&d, scene, why, sizeof why)),
                       d.suits[0] ? d.suits : "-");
            else
                printf("%-12s %-33s %s\n", d.name, g, d.suits[0] ? d.suits : "-");
        }
        if (scene) {
            printf("\nOn %s:\n", label);
            for (uint32_t i = 0; i < count; i++) {
                sl_cull_method_desc d;
                int ap = sl_cull_method_info(idx[i], &d, &err) == SL_OK ? applies(&d, scene, why, sizeof why) : 1;
                if (ap <= 0)
                    printf("  %s: %s: %s\n", d.name, applies_word(ap), why);
            }
        }
        printf("\n@res: conservative at the resolution it culls at. What each does and its options: sightline "
               "methods NAME, or --long; choosing one: README, \"Choosing a method\".\n");
        return 0;
    }
    cli_json j;
    if (json) {
        cli_json_begin(&j, stdout);
        cli_json_array_begin(&j, "methods");
    }
    for (uint32_t i = 0; i < count; i++) {
        sl_cull_method_desc d;
        if (sl_cull_method_info(idx[i], &d, &err) != SL_OK)
            return cli_fail(cmd, &err);
        if (json) {
            cli_json_object_begin(&j, NULL);
            cli_json_string(&j, "name", d.name);
            cli_json_string(&j, "guarantee", sl_cull_guarantee_name(d.guarantee));
            if (d.res_culling)
                cli_json_string(&j, "res_culling_guarantee", sl_cull_guarantee_name(SL_CONSERVATIVE_AT_RESOLUTION));
            cli_json_string(&j, "summary", d.summary);
            cli_json_string(&j, "suits", d.suits);
            if (scene) {
                int ap = applies(&d, scene, why, sizeof why);
                cli_json_string(&j, "applies", ap > 0 ? "yes" : ap == 0 ? "not_applicable" : "needs_options");
                if (ap <= 0)
                    cli_json_string(&j, "why", why);
            }
            cli_json_array_begin(&j, "options");
            const char *p = d.options_help;
            while (p && *p) {
                const char *nl = strchr(p, '\n');
                size_t len = nl ? (size_t)(nl - p) : strlen(p);
                if (len) {
                    char line[512];
                    snprintf(line, sizeof line, "%.*s", (int)(len < sizeof line ? len : sizeof line - 1), p);
                    cli_json_string(&j, NULL, line);
                }
                p = nl ? nl + 1 : NULL;
            }
            cli_json_array_end(&j);
            cli_json_object_end(&j);
        } else {
            printf("%s%s (%s%s%s)\n  %s\n", i ? "\n" : "", d.name, sl_cull_guarantee_name(d.guarantee),
                   d.res_culling ? "; res=culling: " : "",
                   d.res_culling ? sl_cull_guarantee_name(SL_CONSERVATIVE_AT_RESOLUTION) : "", d.summary);
            if (d.suits[0])
                printf("  suits: %s\n", d.suits);
            if (scene) {
                int ap = applies(&d, scene, why, sizeof why);
                printf("  on %s: %s%s%s\n", label, applies_word(ap), ap > 0 ? "" : ": ", ap > 0 ? "" : why);
            }
            if (d.options_help && d.options_help[0]) {
                printf("  options:\n");
                print_indented(d.options_help, "    ");
            } else {
                printf("  options: none\n");
            }
        }
    }
    if (json) {
        cli_json_array_end(&j);
        cli_json_end(&j);
    }
    return 0;
}

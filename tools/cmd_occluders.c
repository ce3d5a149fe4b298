/* `sightline occluders SCENE -o OUT.slscene`: synthesise conservative occluders (boxes inside the
 * closed objects, sl_synth_occluders) for an existing scene and save it; and the synthesis options
 * and statistics `sightline import` shares (docs/occluder-synthesis.md). */
#include "cli.h"

#include "tool.h"
#include "sightline/import.h"
#include "sightline/region.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <string.h>
#include <sys/stat.h>

bool cli_synth_option(cli_args *a, const char *name, const char *val, sl_synth_options *o)
{
    float f;
    if (!strcmp(name, "voxel") || !strcmp(name, "min-box") || !strcmp(name, "weld")) {
        if (!cli_parse_float(a, name, cli_value(a, name, val), &f))
            return true;
        if (!(f > 0)) {
            cli_error(a->cmd, "--%s must be positive", name);
            a->error = true;
            return true;
        }
        *(!strcmp(name, "voxel") ? &o->voxel : !strcmp(name, "min-box") ? &o->min_box : &o->weld) = f;
    } else if (!strcmp(name, "per-object")) {
        cli_parse_u32(a, name, cli_value(a, name, val), &o->max_boxes_per_object);
    } else if (!strcmp(name, "max-boxes")) {
        cli_parse_u32(a, name, cli_value(a, name, val), &o->max_boxes);
    } else if (!strcmp(name, "max-voxels")) {
        cli_parse_u32(a, name, cli_value(a, name, val), &o->max_voxels);
    } else if (!strcmp(name, "no-expand")) {
        o->no_expand = true;
    } else {
        return false;
    }
    return true;
}

void cli_synth_print(const sl_synth_stats *s)
{
    printf("  occluders      %u boxes in %u meshes for %u of %u closed objects (%u open, %u see-through,\n"
           "                 %u with their own occluders, %u dynamic); >= %.1f%% of the closed volume\n",
           s->boxes, s->occluder_meshes, s->objects_with_boxes, s->closed, s->open, s->see_through, s->native,
           s->dynamic, 100.0 * s->volume_fraction);
    if (s->partial || s->t_junctions)
        printf("                 %u of the closed with open parts left out; %u triangles split at T-junctions\n",
               s->partial, s->t_junctions);
    if (s->dropped_by_budget)
        printf("                 %u boxes left out by the budget (--max-boxes)\n", s->dropped_by_budget);
    printf("  synthesis      %.3f s (%.3f s CPU), %llu voxels (%llu solid)\n", s->seconds, s->cpu_seconds,
           (unsigned long long)s->voxels, (unsigned long long)s->solid_voxels);
}

void cli_synth_json(cli_json *j, const sl_synth_stats *s)
{
    cli_json_object_begin(j, "occluders");
    cli_json_uint(j, "considered", s->considered);
    cli_json_uint(j, "closed", s->closed);
    cli_json_uint(j, "open", s->open);
    cli_json_uint(j, "see_through", s->see_through);
    cli_json_uint(j, "native", s->native);
    cli_json_uint(j, "dynamic", s->dynamic);
    cli_json_uint(j, "partial", s->partial);
    cli_json_uint(j, "t_junctions", s->t_junctions);
    cli_json_uint(j, "objects_with_boxes", s->objects_with_boxes);
    cli_json_uint(j, "boxes", s->boxes);
    cli_json_uint(j, "meshes", s->occluder_meshes);
    cli_json_uint(j, "dropped_by_budget", s->dropped_by_budget);
    cli_json_uint(j, "voxels", s->voxels);
    cli_json_uint(j, "solid_voxels", s->solid_voxels);
    cli_json_double(j, "closed_volume", s->closed_volume);
    cli_json_double(j, "covered_volume", s->covered_volume);
    cli_json_double(j, "volume_fraction", s->volume_fraction);
    cli_json_double(j, "seconds", s->seconds);
    cli_json_double(j, "cpu_seconds", s->cpu_seconds);
    cli_json_object_end(j);
}

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline occluders SCENE -o OUT.slscene [--voxel M] [--min-box M] [--weld M]\n"
            "                           [--per-object N] [--max-boxes N] [--max-voxels N] [--no-expand]\n"
            "                           [--json] [--quiet]\n"
            "       sightline occluders SCENE -o OUT.slscene --instant-levels E1,E2,...\n"
            "                           [--instant-vertical Z] [--merge] [--json] [--quiet]\n\n"
            "Synthesise conservative occluders for a scene (any scene argument: a .slscene, a model\n"
            "file, city:PRESET) and save it: every static, opaque object without occluders of its own\n"
            "whose mesh is closed after welding gets boxes that lie strictly inside it (voxelised\n"
            "solid interior merged into boxes); open meshes get none. The occlusion methods (hzb,\n"
            "lazygrid, ...) then use them as the objects' occluders. `sightline import` does this by\n"
            "default (docs/occluder-synthesis.md).\n\n"
            "With --instant-levels, no boxes are synthesised: the scene's building footprints are shrunk\n"
            "(GEOS) by each eps in metres in plan, their roofs lowered and bases raised by Z, and stored\n"
            "with the scene as occluder levels for the `instant` culler (.slscene 1.2; docs/instant.md):\n"
            "a set computed at P on a level holds for every eye within eps of P in plan and Z in height.\n\n"
            "options:\n"
            "  -o, --output FILE  the scene with its occluders (.slscene; required)\n"
            CLI_SYNTH_HELP
            "  --instant-levels L up to 16 distinct eps values in metres, comma-separated (e.g. 0.5,1,1.5,2,3)\n"
            "  --instant-vertical Z  vertical tolerance in metres (default 0.5; at most each eps; 'ball': eps)\n"
            "  --merge            erode touching footprints as one block (default: each alone, which keeps\n"
            "                     the buildings behind a near one as occluders when the near one is left out)\n"
            "  --json             statistics as JSON on stdout\n"
            "  --quiet            no progress output\n"
            "  --help             this text\n\n"
            "examples:\n"
            "  sightline occluders house.slscene -o house-occ.slscene\n"
            "  sightline occluders model.glb --voxel 0.1 --per-object 32 -o model.slscene --json\n"
            "  sightline occluders city:vienna --instant-levels 0.5,1,1.5,2,3 -o vienna-iv.slscene\n");
}

/* "0.5,1,1.5": up to SL_OCCLUDER_LEVELS_MAX comma-separated numbers. */
static bool parse_levels(cli_args *a, const char *text, float *out, uint32_t *n)
{
    if (!text)
        return false;
    uint32_t k = 1;
    for (const char *p = text; *p; p++)
        k += *p == ',';
    if (k > SL_OCCLUDER_LEVELS_MAX || !sl_parse_floats(text, out, (int)k)) {
        cli_error(a->cmd, "--instant-levels: expected 1..%u comma-separated numbers, got '%s'", SL_OCCLUDER_LEVELS_MAX,
                  text);
        a->error = true;
        return false;
    }
    *n = k;
    return true;
}

int sl_cmd_occluders(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_common com = {0};
    cli_import imp = {0};
    sl_synth_options so = sl_synth_defaults();
    const char *name, *val;
    float levels[SL_OCCLUDER_LEVELS_MAX];
    uint32_t nlevels = 0;
    bool merge = false;
    float vertical = 0.5f;
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_OUTPUT | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!strcmp(name, "instant-levels")) {
            parse_levels(&a, cli_value(&a, name, val), levels, &nlevels);
        } else if (!strcmp(name, "merge")) {
            merge = true;
        } else if (!strcmp(name, "instant-vertical")) {
            const char *m = cli_value(&a, name, val);
            if (m && !strcmp(m, "ball"))
                vertical = -1;
            else if (m && cli_parse_float(&a, name, m, &vertical) && !(vertical >= 0 && vertical < 1e4f)) {
                cli_error(a.cmd, "--instant-vertical: expected a number in [0, 10000) or 'ball', got '%s'", m);
                a.error = true;
            }
        } else if (cli_synth_option(&a, name, val, &so)) {
        } else if (!cli_import_option(&a, name, val, &imp)) {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    if (!com.input) {
        cli_error(a.cmd, "missing SCENE (see sightline occluders --help)");
        return 2;
    }
    if (!com.output) {
        cli_error(a.cmd, "missing -o OUT.slscene (see sightline occluders --help)");
        return 2;
    }
    struct stat si, sout;
    if (stat(com.input, &si) == 0 && stat(com.output, &sout) == 0 && si.st_dev == sout.st_dev &&
        si.st_ino == sout.st_ino) {
        cli_error(a.cmd, "the output %s is the input file", com.output);
        return 2;
    }
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&imp, &io);
    sl_error err;
    sl_scene scene;
    if (cli_open_scene(com.input, NULL, &io, NULL, &scene, NULL, 0, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    if (nlevels) {
        sl_occluder_levels_stats ls;
        if (sl_shrink_occluder_levels(scene, levels, nlevels, vertical, merge, NULL, &ls, &err) != SL_OK ||
            sl_scene_save(scene, com.output, &err) != SL_OK) {
            sl_scene_destroy(scene);
            return cli_fail(a.cmd, &err);
        }
        if (com.json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            cli_json_string(&j, "input", com.input);
            cli_json_string(&j, "output", com.output);
            cli_json_uint(&j, "footprints", sl_scene_footprint_count(scene));
            cli_json_bool(&j, "merge", merge);
            cli_json_array_begin(&j, "levels");
            for (uint32_t l = 0; l < ls.levels; l++) {
                cli_json_object_begin(&j, NULL);
                cli_json_double(&j, "eps", ls.eps[l]);
                cli_json_double(&j, "eps_z", ls.eps_z[l]);
                cli_json_uint(&j, "footprints", ls.footprints[l]);
                cli_json_uint(&j, "vanished", ls.vanished[l]);
                cli_json_uint(&j, "pieces_dropped", ls.pieces_dropped[l]);
                cli_json_uint(&j, "holes_dropped", ls.holes_dropped[l]);
                cli_json_object_end(&j);
            }
            cli_json_array_end(&j);
            cli_json_double(&j, "seconds", ls.seconds);
            cli_json_end(&j);
        } else {
            printf("%s -> %s\n", com.input, com.output);
            printf("  footprints     %u, shrunk%s in %.2f s\n", sl_scene_footprint_count(scene),
                   merge ? " (touching ones merged)" : "", ls.seconds);
            for (uint32_t l = 0; l < ls.levels; l++)
                printf("  level eps %-5g eps_z %-5g %u footprints (%u vanished, %u pieces and %u courtyards dropped)\n",
                       (double)ls.eps[l], (double)ls.eps_z[l], ls.footprints[l], ls.vanished[l], ls.pieces_dropped[l], ls.holes_dropped[l]);
        }
        sl_scene_destroy(scene);
        return 0;
    }
    uint32_t before = sl_scene_occluder_count(scene);
    sl_synth_stats st;
    if (sl_synth_occluders(scene, &so, NULL, &st, &err) != SL_OK || sl_scene_save(scene, com.output, &err) != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    if (com.json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "input", com.input);
        cli_json_string(&j, "output", com.output);
        cli_json_uint(&j, "objects", sl_scene_object_count(scene));
        cli_json_uint(&j, "occluders_before", before);
        cli_json_uint(&j, "occluders_after", sl_scene_occluder_count(scene));
        cli_synth_json(&j, &st);
        cli_json_end(&j);
    } else {
        printf("%s -> %s\n", com.input, com.output);
        printf("  objects        %u (occluder meshes %u before, %u after)\n", sl_scene_object_count(scene), before,
               sl_scene_occluder_count(scene));
        cli_synth_print(&st);
    }
    sl_scene_destroy(scene);
    return 0;
}

/* `sightline gen city`: generate the procedural city (include/sightline/gen.h), save it as a
 * .slscene and print a summary (or --json). Only the city generator exists; `gen` with anything
 * else is a usage error. Every field of sl_city_options has an option; the preset sets the
 * defaults whatever the order of the options. */
#include "cli.h"

#include "tool.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <inttypes.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline gen city [--preset NAME] [--style grid|oldtown] [--seed N] [-o|--output FILE.slscene]\n"
            "                          [--detail 0-4] [--terrain|--no-terrain] [--relief M] [--cars N] ...\n"
            "                          [--stats] [--json] [--quiet]\n"
            "       sightline gen edit SCENE --region X0,Y0,X1,Y1 [--seed N] -o OUT.slscene   (--help there)\n\n"
            "Generate a procedural city (irregular street lattice, perimeter blocks of buildings with\n"
            "façade detail, parks, squares, a river with quays and bridges, cars, trees, street lamps,\n"
            "optional terrain), save it and print a summary. The same options give the same file.\n\n"
            "presets (defaults for every option below):\n"
            "  tiny     300 x 260 m, a dozen blocks, < 50k triangles (tests)\n"
            "  small    800 x 750 m, about 130 blocks, about 0.6M triangles\n"
            "  vienna   3000 x 2700 m, about 2,000 blocks, about 8M triangles (default)\n"
            "  oldtown  3000 x 2700 m, style oldtown with the vienna densities and heights\n"
            "  oldtown-small  800 x 750 m, style oldtown (tests)\n\n"
            "styles:\n"
            "  grid     the street lattice with straight avenues and a river (tiny, small, vienna)\n"
            "  oldtown  a historic centre: meandering streets, T-junctions in a brick pattern per\n"
            "           district, deep merged blocks, more squares, no avenues, no river\n\n");
    fprintf(out,
            "options:\n"
            "  --preset NAME         tiny, small, vienna, oldtown or oldtown-small (default vienna)\n"
            "  --style NAME          grid or oldtown (default: the preset's)\n"
            "  --stats               also print sl_city_measure's figures (extent, objects, mean building\n"
            "                        height, street-area fraction, sight lines along the streets)\n"
            "  --seed N              random seed (default 1)\n"
            "  -o, --output FILE     output .slscene (default city-<preset>-<seed>.slscene)\n"
            "  --dry-run             generate and summarise, write nothing\n"
            "  --extent W[xH]        city size in metres (e.g. 2000 or 3000x2700)\n"
            "  --block-min M         smallest street spacing (block size incl. streets)\n"
            "  --block-max M         largest street spacing\n"
            "  --jitter F            node displacement, fraction of the block size (0..0.25)\n"
            "  --street-min M        narrowest street (sidewalks included)\n"
            "  --street-max M        widest ordinary street\n"
            "  --avenue-width M      width of avenues and quays\n"
            "  --avenue-spacing M    distance between straight avenues (0: none)\n"
            "  --street-removal F    probability of dropping a minor street segment (0..0.5)\n"
            "  --meander M           amplitude of the streets' sine meander (0..0.3 block-min)\n"
            "  --meander-wavelength M  its wavelength along a street (100..5000)\n"
            "  --district N          oldtown: district size in cells of the brick pattern (2..64)\n"
            "  --parks F             share of cells that are parks\n"
            "  --squares F           share of cells that are paved squares\n"
            "  --towers F            share of cells that hold a tower\n"
            "  --river, --no-river   a river row with quays, banks and bridges (default on)\n"
            "  --river-width M       water width\n"
            "  --bank-width M        open bank on each side of the water\n"
            "  --bridge-spacing M    distance between bridges (0: none; the street graph then splits)\n"
            "  --height-min M        lowest eave height of ordinary buildings\n"
            "  --height-max M        highest eave height of ordinary buildings\n"
            "  --tower-min M         lowest tower\n"
            "  --tower-max M         highest tower\n"
            "  --detail N            0 prism, 1 roofs and cornices, 2 ledges, 3 recessed windows on street\n"
            "                        façades, 4 sills and courtyard windows too\n"
            "  --cars N              cars per km of street (0: none)\n"
            "  --traffic-speed V     m/s of the cars in the driving lanes (default 11; 0: parked, no paths);\n"
            "                        they shuttle along their lanes under sl_scene_animate (docs/motion.md)\n"
            "  --trees N             trees per hectare in parks and courtyards\n"
            "  --street-trees M      tree spacing along avenues and river banks (0: none)\n"
            "  --lamps M             street lamp spacing (0: none)\n"
            "  --terrain, --no-terrain  smooth relief rising from the river (default off)\n"
            "  --relief M            highest ground above the river\n"
            "  --json                machine-readable summary on stdout\n"
            "  --quiet               no progress bar\n"
            "  --help                this text\n\n"
            "examples:\n"
            "  sightline gen city --preset vienna --seed 1\n"
            "  sightline gen city --preset oldtown --stats --dry-run\n"
            "  sightline gen city --preset tiny --detail 4 --terrain -o tiny.slscene --json\n"
            "  sightline gen city --preset small --extent 1200x1000 --cars 40 --no-river -o small.slscene\n");
}

static bool parse_extent(cli_args *a, const char *text, sl_city_options *o)
{
    if (!text)
        return false;
    char buf[64];
    snprintf(buf, sizeof buf, "%s", text);
    char *x = strchr(buf, 'x');
    if (x)
        *x = 0;
    float w, h;
    if (!cli_parse_float(a, "extent", buf, &w))
        return false;
    h = w;
    if (x && !cli_parse_float(a, "extent", x + 1, &h))
        return false;
    o->extent_x = w, o->extent_y = h;
    return true;
}

typedef struct float_opt {
    const char *name;
    size_t offset;
} float_opt;

#define FOPT(n, f) {n, offsetof(sl_city_options, f)}
static const float_opt float_opts[] = {
    FOPT("block-min", block_size_min),     FOPT("block-max", block_size_max),   FOPT("jitter", jitter),
    FOPT("street-min", street_width_min),  FOPT("street-max", street_width_max), FOPT("avenue-width", avenue_width),
    FOPT("avenue-spacing", avenue_spacing), FOPT("street-removal", street_removal), FOPT("parks", park_fraction),
    FOPT("squares", square_fraction),      FOPT("towers", tower_fraction),      FOPT("river-width", river_width),
    FOPT("bank-width", bank_width),        FOPT("bridge-spacing", bridge_spacing), FOPT("height-min", height_min),
    FOPT("height-max", height_max),        FOPT("tower-min", tower_height_min), FOPT("tower-max", tower_height_max),
    FOPT("cars", cars_per_km),             FOPT("trees", trees_per_ha),         FOPT("street-trees", street_tree_spacing),
    FOPT("lamps", lamp_spacing),           FOPT("relief", relief),              FOPT("meander", meander),
    FOPT("meander-wavelength", meander_wavelength), FOPT("traffic-speed", traffic_speed),
};

static void print_summary(const char *cmd, const sl_city_options *o, sl_scene s, const char *output, double t_gen,
                          double t_save, uint64_t file_bytes, bool json, const sl_city_stats *cs)
{
    (void)cmd;
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    const char *blocks = sl_scene_meta(s, "city.blocks"), *buildings = sl_scene_meta(s, "city.buildings");
    uint64_t peak = cli_peak_rss();
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "generator", "city");
        cli_json_string(&j, "preset", sl_city_preset_name(o->preset));
        cli_json_string(&j, "style", sl_city_style_name(o->style));
        cli_json_uint(&j, "seed", o->seed);
        cli_json_string(&j, "output", output);
        cli_json_uint(&j, "detail", o->detail);
        cli_json_bool(&j, "river", o->river);
        cli_json_bool(&j, "terrain", st.has_terrain);
        cli_json_array_begin(&j, "extent");
        cli_json_double(&j, NULL, o->extent_x), cli_json_double(&j, NULL, o->extent_y);
        cli_json_array_end(&j);
        cli_json_uint(&j, "objects", st.object_count);
        cli_json_uint(&j, "meshes", st.mesh_count);
        cli_json_uint(&j, "vertices", st.vertex_count);
        cli_json_uint(&j, "triangles_stored", st.triangle_count);
        cli_json_uint(&j, "triangles_instanced", st.instanced_triangle_count);
        cli_json_uint(&j, "blocks", blocks ? strtoull(blocks, NULL, 10) : 0);
        cli_json_uint(&j, "buildings", buildings ? strtoull(buildings, NULL, 10) : 0);
        cli_json_uint(&j, "footprints", st.footprint_count);
        cli_json_uint(&j, "street_polygons", st.street_polygon_count);
        cli_json_uint(&j, "street_nodes", st.street_node_count);
        cli_json_uint(&j, "street_edges", st.street_edge_count);
        cli_json_object_begin(&j, "kinds");
        for (uint32_t k = 0; k < SL_KIND_COUNT; k++) {
            if (!st.objects_per_kind[k])
                continue;
            cli_json_object_begin(&j, sl_object_kind_name(k));
            cli_json_uint(&j, "objects", st.objects_per_kind[k]);
            cli_json_uint(&j, "triangles", st.triangles_per_kind[k]);
            cli_json_object_end(&j);
        }
        cli_json_object_end(&j);
        cli_json_array_begin(&j, "bounds_min");
        cli_json_double(&j, NULL, st.bounds.min.x), cli_json_double(&j, NULL, st.bounds.min.y), cli_json_double(&j, NULL, st.bounds.min.z);
        cli_json_array_end(&j);
        cli_json_array_begin(&j, "bounds_max");
        cli_json_double(&j, NULL, st.bounds.max.x), cli_json_double(&j, NULL, st.bounds.max.y), cli_json_double(&j, NULL, st.bounds.max.z);
        cli_json_array_end(&j);
        cli_json_uint(&j, "memory_bytes", st.memory_bytes);
        cli_json_double(&j, "seconds_generate", t_gen);
        cli_json_double(&j, "seconds_save", t_save);
        cli_json_uint(&j, "file_bytes", file_bytes);
        cli_json_uint(&j, "peak_rss_bytes", peak);
        if (cs) {
            cli_json_object_begin(&j, "stats");
            cli_json_uint(&j, "objects", cs->object_count);
            cli_json_uint(&j, "buildings", cs->building_count);
            cli_json_double(&j, "mean_building_height", cs->mean_building_height);
            cli_json_double(&j, "street_area", cs->street_area);
            cli_json_double(&j, "street_fraction", cs->street_fraction);
            cli_json_double(&j, "street_length", cs->street_length);
            cli_json_double(&j, "sight_mean", cs->sight_mean);
            cli_json_double(&j, "sight_p90", cs->sight_p90);
            cli_json_uint(&j, "sight_rays", cs->sight_rays);
            cli_json_object_end(&j);
        }
        cli_json_end(&j);
        return;
    }
    char b1[32], b2[32], b3[32];
    printf("city %s, style %s, seed %" PRIu64 ", detail %u%s%s\n", sl_city_preset_name(o->preset),
           sl_city_style_name(o->style), o->seed, o->detail, o->river ? ", river" : "", st.has_terrain ? ", terrain" : "");
    printf("  objects        %u (meshes %u), %s blocks, %s buildings\n", st.object_count, st.mesh_count,
           blocks ? blocks : "?", buildings ? buildings : "?");
    printf("  triangles      %llu instanced, %llu stored (vertices %llu)\n", (unsigned long long)st.instanced_triangle_count,
           (unsigned long long)st.triangle_count, (unsigned long long)st.vertex_count);
    printf("  per kind       %-10s %10s %12s\n", "kind", "objects", "triangles");
    for (uint32_t k = 0; k < SL_KIND_COUNT; k++)
        if (st.objects_per_kind[k])
            printf("                 %-10s %10u %12llu\n", sl_object_kind_name(k), st.objects_per_kind[k],
                   (unsigned long long)st.triangles_per_kind[k]);
    printf("  occluders      %u footprints\n", st.footprint_count);
    printf("  streets        %u polygons, graph %u nodes / %u edges\n", st.street_polygon_count, st.street_node_count,
           st.street_edge_count);
    printf("  bounds         (%.1f, %.1f, %.1f) .. (%.1f, %.1f, %.1f) m\n", st.bounds.min.x, st.bounds.min.y,
           st.bounds.min.z, st.bounds.max.x, st.bounds.max.y, st.bounds.max.z);
    if (output)
        printf("  output         %s (%s), generated in %.2f s, saved in %.2f s\n", output,
               cli_bytes(file_bytes, b1, sizeof b1), t_gen, t_save);
    else
        printf("  output         none (--dry-run), generated in %.2f s\n", t_gen);
    printf("  memory         %s in the scene, %s peak resident\n", cli_bytes(st.memory_bytes, b2, sizeof b2),
           cli_bytes(peak, b3, sizeof b3));
    if (cs) {
        printf("  stats          extent %.0f x %.0f m, %u objects, %u buildings, mean building height %.2f m\n",
               cs->extent_x, cs->extent_y, cs->object_count, cs->building_count, cs->mean_building_height);
        printf("                 street area %.0f m² (%.2f%% of the extent), street graph %.1f km\n",
               cs->street_area, 100.0 * cs->street_fraction, cs->street_length * 1e-3);
        printf("                 sight lines along the streets: mean %.0f m, 90th percentile %.0f m (%u rays)\n",
               cs->sight_mean, cs->sight_p90, cs->sight_rays);
    }
}

/* ---- gen edit ---- */

static void usage_edit(FILE *out)
{
    fprintf(out,
            "usage: sightline gen edit SCENE --region X0,Y0,X1,Y1 [--seed N] [-o OUT.slscene] [options]\n\n"
            "Copy SCENE (a .slscene or city:PRESET[:SEED]) with seeded random edits of the buildings (objects\n"
            "with a footprint) whose footprint box centre lies in the region: each one is removed, moved\n"
            "(shifted towards the middle of its row of touching buildings, its height scaled by 1..GROW),\n"
            "given a new building inside it (TOWER times as high) or kept. The edits\n"
            "`sightline pvs update` is tested and measured on. The same inputs give the same file.\n\n"
            "options:\n"
            "  --region X0,Y0,X1,Y1  the region (metres)\n"
            "  --seed N          the draws (default 1)\n"
            "  --remove P        probability a building is removed (0.25)\n"
            "  --move P          ... moved (0.25)\n"
            "  --add P           ... given a new building (0.2); the three sum to at most 1\n"
            "  --shift M         largest shift of a moved building (1 m)\n"
            "  --grow F          a moved building's height is scaled by a factor in [1, F] (1)\n"
            "  --tower F         a new building is F times as high as its host (1)\n"
            "  -o FILE           output (default edited.slscene)\n"
            "  --json            summary on stdout as JSON\n"
            "  --help            this text\n\n"
            "example:\n"
            "  sightline gen edit city:vienna --region 0,0,100,100 --seed 3 -o edited.slscene\n");
}

static int run_edit(int argc, char **argv, const char *cmd)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = cmd;
    const char *name, *val, *region = NULL;
    cli_common com = {0};
    sl_city_edit_options eo = sl_city_edit_defaults();
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_OUTPUT | CLI_JSON | CLI_QUIET, &com))
            continue;
        if (!strcmp(name, "region"))
            region = cli_value(&a, name, val);
        else if (!strcmp(name, "seed"))
            cli_parse_u64(&a, name, cli_value(&a, name, val), &eo.seed);
        else if (!strcmp(name, "remove"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &eo.remove);
        else if (!strcmp(name, "move"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &eo.move);
        else if (!strcmp(name, "add"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &eo.add);
        else if (!strcmp(name, "shift"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &eo.shift);
        else if (!strcmp(name, "grow"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &eo.grow);
        else if (!strcmp(name, "tower"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &eo.tower);
        else
            cli_unknown(&a, name);
    }
    int parsed = cli_parse_done(&a, &com, usage_edit);
    if (parsed >= 0)
        return parsed;
    if (!com.input || !region) {
        cli_error(cmd, "%s (see sightline gen edit --help)", !com.input ? "missing SCENE" : "missing --region X0,Y0,X1,Y1");
        return 2;
    }
    if (!sl_parse_floats(region, eo.region, 4)) {
        cli_error(cmd, "--region: '%s' is not 4 comma-separated finite numbers", region);
        return 2;
    }
    const char *output = com.output ? com.output : "edited.slscene";
    const char *inputs[] = {com.input};
    if (!cli_output_not_input(cmd, output, inputs, 1))
        return 2;
    sl_error err;
    sl_scene scene = NULL, edited = NULL;
    sl_import_options io = sl_import_defaults();
    if (cli_open_scene(com.input, NULL, &io, NULL, &scene, NULL, 0, &err) != SL_OK)
        return cli_fail(cmd, &err);
    sl_city_edit_stats es;
    sl_status st = sl_city_edit(scene, &eo, NULL, &edited, &es, &err);
    sl_scene_destroy(scene);
    if (st == SL_OK)
        st = sl_scene_save(edited, output, &err);
    sl_scene_destroy(edited);
    if (st != SL_OK)
        return cli_fail(cmd, &err);
    if (com.json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", output);
        cli_json_uint(&j, "removed", es.removed);
        cli_json_uint(&j, "moved", es.moved);
        cli_json_uint(&j, "added", es.added);
        cli_json_end(&j);
    } else if (!com.quiet) {
        printf("%s: %u buildings removed, %u moved, %u added\n", output, es.removed, es.moved, es.added);
    }
    return 0;
}

int sl_cmd_gen(int argc, char **argv)
{
    const char *cmd = argv[0];
    if (argc >= 2 && !strcmp(argv[1], "edit"))
        return run_edit(argc - 1, argv + 1, "gen edit");
    if (argc < 2) {
        cli_error(cmd, "missing the generator: only 'city' exists (see sightline gen --help)");
        return 2;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        usage(stdout);
        return 0;
    }
    if (strcmp(argv[1], "city") != 0) {
        cli_error(cmd, "unknown generator '%s': only 'city' exists (see sightline gen --help)", argv[1]);
        return 2;
    }
    /* the preset first, so that every other option overrides its defaults in any order */
    sl_city_preset preset = SL_CITY_VIENNA;
    for (int i = 2; i < argc; i++) {
        const char *v = NULL;
        if (!strcmp(argv[i], "--preset"))
            v = i + 1 < argc ? argv[i + 1] : NULL;
        else if (!strncmp(argv[i], "--preset=", 9))
            v = argv[i] + 9;
        else
            continue;
        sl_error err;
        if (!v) {
            cli_error(cmd, "option --preset needs a value");
            return 2;
        }
        if (sl_city_preset_from_name(v, &preset, &err) != SL_OK) {
            cli_error(cmd, "%s", err.message);
            return 2;
        }
    }
    sl_city_options o = sl_city_defaults(preset);
    cli_args a;
    cli_args_init(&a, argc - 1, argv + 1);
    a.cmd = cmd;
    const char *name, *val;
    bool dry_run = false, stats = false;
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_OUTPUT | CLI_JSON | CLI_QUIET, &com))
            continue;
        if (!name) {
            cli_unknown(&a, NULL);
            break;
        }
        if (!strcmp(name, "preset")) {
            cli_value(&a, name, val); /* handled above */
        } else if (!strcmp(name, "seed")) {
            cli_parse_u64(&a, name, cli_value(&a, name, val), &o.seed);
        } else if (!strcmp(name, "dry-run")) {
            dry_run = true;
        } else if (!strcmp(name, "stats")) {
            stats = true;
        } else if (!strcmp(name, "style")) {
            const char *v = cli_value(&a, name, val);
            sl_error serr;
            if (v && sl_city_style_from_name(v, &o.style, &serr) != SL_OK) {
                cli_error(cmd, "%s", serr.message);
                return 2;
            }
        } else if (!strcmp(name, "district")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &o.district);
        } else if (!strcmp(name, "extent")) {
            parse_extent(&a, cli_value(&a, name, val), &o);
        } else if (!strcmp(name, "detail")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &o.detail);
        } else if (!strcmp(name, "river") || !strcmp(name, "no-river")) {
            o.river = name[0] == 'r';
        } else if (!strcmp(name, "terrain") || !strcmp(name, "no-terrain")) {
            o.terrain = name[0] == 't';
        } else {
            size_t k = 0;
            while (k < TOOL_COUNTOF(float_opts) && strcmp(name, float_opts[k].name))
                k++;
            if (k == TOOL_COUNTOF(float_opts)) {
                cli_unknown(&a, name);
                break;
            }
            cli_parse_float(&a, name, cli_value(&a, name, val), (float *)((char *)&o + float_opts[k].offset));
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    const char *output = com.output;
    bool json = com.json, quiet = com.quiet;
    sl_error err;
    if (sl_city_options_validate(&o, &err) != SL_OK) {
        cli_error(cmd, "%s", err.message);
        return 2;
    }
    char defname[96];
    if (!output && !dry_run) {
        snprintf(defname, sizeof defname, "city-%s-%" PRIu64 ".slscene", sl_city_preset_name(o.preset), o.seed);
        output = defname;
    }
    if (dry_run)
        output = NULL;

    cli_progress_state ps;
    o.progress = cli_progress(&ps, quiet || json);
    sl_scene scene = NULL;
    double t0 = tool_now();
    sl_status st = sl_gen_city(&o, NULL, &scene, &err);
    double t_gen = tool_now() - t0;
    cli_progress_done(&ps);
    if (st != SL_OK)
        return cli_fail(cmd, &err);
    double t_save = 0;
    uint64_t bytes = 0;
    if (output) {
        t0 = tool_now();
        st = sl_scene_save(scene, output, &err);
        t_save = tool_now() - t0;
        if (st != SL_OK) {
            sl_scene_destroy(scene);
            return cli_fail(cmd, &err);
        }
        struct stat sb;
        if (stat(output, &sb) == 0)
            bytes = (uint64_t)sb.st_size;
    }
    sl_city_stats cs;
    if (stats && (st = sl_city_measure(scene, &cs, &err)) != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(cmd, &err);
    }
    print_summary(cmd, &o, scene, output, t_gen, t_save, bytes, json, stats ? &cs : NULL);
    sl_scene_destroy(scene);
    return 0;
}

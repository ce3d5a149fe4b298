/* `sightline import`: read any format assimp reads, a Quake III .bsp / .pk3, or a GIS file, and
 * save it as a .slscene. The extension chooses the importer: .bsp and .pk3 go to the Quake III
 * reader, .geojson/.json/.shp/.osm/.pbf/.gml to the GIS importer, every other file to assimp. */
#include "cli.h"

#include "tool.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <ctype.h>
#include <string.h>
#include <sys/stat.h>

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline import INPUT [-o OUT.slscene] [--map NAME] [--list-maps] [--scale S] [--up y|z]\n"
            "                        [--split N] [--bezier N] [--allow-external PATH] [--no-occluders]\n"
            "                        [synthesis options] [GIS options] [--json] [--quiet]\n\n"
            "Import a 3D file into a Sightline scene (.slscene): OBJ, glTF 2.0 (.gltf/.glb), PLY, FBX,\n"
            "COLLADA, 3DS and every other format assimp reads, or a Quake III map (.bsp, or a .pk3\n"
            "archive). Each node with meshes becomes one object; meshes shared by several nodes stay\n"
            "one instanced mesh. Coordinates become metres, Z up (docs/import-export.md).\n"
            "GIS files (GeoJSON .geojson/.json, Shapefile .shp, OpenStreetMap .osm/.pbf, GML/CityGML\n"
            "  .gml) become a city: building footprints extruded to their heights, streets with their\n"
            "  graph, flat ground, in a local metric frame (docs/gis-import.md).\n\n"
            "options:\n"
            "  -o, --output FILE  output .slscene (default: the input's name with .slscene, in the\n"
            "                     current directory; for a .pk3, the map's name)\n"
            "  --map NAME         map inside a .pk3 (\"oa_dm1\" or \"maps/oa_dm1.bsp\"); may be left out\n"
            "                     when the archive holds a single map\n"
            "  --list-maps        list the maps inside a .pk3 and exit (control bytes and non-UTF-8\n"
            "                     in entry names are printed as \\xNN)\n"
            "  --scale S          metres per file unit (default 1 for assimp formats, 1/32 for Quake III)\n"
            "  --up y|z           up axis of an assimp file (default y: rotated to Z-up)\n"
            "  --split N          split meshes larger than N triangles into spatially compact objects of\n"
            "                     about N triangles (0: one object per node; Quake III has its own default)\n"
            "  --bezier N         Quake III patch tessellation level (default 8)\n"
            "  --no-occluders     do not synthesise occluders (by default every closed, opaque, static\n"
            "                     object without occluders of its own gets boxes lying inside it, so\n"
            "                     that the occlusion methods cull the model: docs/occluder-synthesis.md;\n"
            "                     `sightline occluders` does it for an existing scene). Synthesis options:\n"
            CLI_SYNTH_HELP
            CLI_ALLOW_EXTERNAL_HELP
            "                     Without it, a reference leaving the model's folder (a '../' path,\n"
            "                     an absolute path, a symlink pointing out) fails the import.\n");
    fprintf(out,
            "GIS options:\n"
            "  --height-attr LIST attribute names of a building's height, tried in order (default\n"
            "                     height,building:height,measuredHeight,HEIGHT,Height)\n"
            "  --levels-attr LIST attribute names of its storeys (default building:levels,levels,storeys)\n"
            "  --default-height M height of a building with neither (default 10; a counted warning)\n"
            "  --level-height M   metres per storey (default 3)\n"
            "  --crs SRS          the file's CRS (\"EPSG:25832\", WKT, PROJ), replacing what it declares\n"
            "  --metric           the coordinates are metres in a local frame (whatever CRS is declared)\n"
            "  --layers LIST      read only these layers (comma-separated)\n"
            "  --no-streets       lines are not streets     --no-ground   no ground tiles\n"
            "  --max-extent M     drop features farther than M from the data's centre (default 50000)\n"
            "  --json             machine-readable summary on stdout\n"
            "  --quiet            no progress output\n"
            "  --help             this text\n\n"
            "examples:\n"
            "  sightline import sponza.gltf --split 2000 -o sponza.slscene\n"
            "  sightline import building.obj --up z --scale 0.01\n"
            "  sightline import pak0.pk3 --list-maps\n"
            "  sightline import pak0.pk3 --map q3dm17 --json\n"
            "  sightline import district.osm.pbf -o district.slscene\n"
            "  sightline import footprints.shp --crs EPSG:25832 --height-attr HOEHE\n");
}

/* Lowercase extension of the last path component, without the dot ("" if none). */
static void extension_of(const char *path, char *buf, size_t size)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t k = 0;
    if (dot && dot != base)
        for (const char *p = dot + 1; *p && k + 1 < size; p++)
            buf[k++] = (char)tolower((unsigned char)*p);
    buf[k] = 0;
}

/* Default output: "<stem>.slscene" in the current directory, where stem is the map name for a
 * .pk3 with --map and the input's file name without its extension otherwise. */
static void default_output(const char *input, const char *map, char *buf, size_t size)
{
    const char *name = map ? map : input;
    const char *base = strrchr(name, '/');
    base = base ? base + 1 : name;
    const char *dot = strrchr(base, '.');
    size_t len = dot && dot != base ? (size_t)(dot - base) : strlen(base);
    snprintf(buf, size, "%.*s.slscene", (int)TOOL_MIN(len, size - 9), base);
}

typedef struct map_list {
    bool json;
    cli_json *j;
    uint32_t count;
} map_list;

static void print_map(void *user, const char *entry)
{
    map_list *l = user;
    l->count++;
    if (l->json) {
        cli_json_string(l->j, NULL, entry);
    } else {
        /* entry names come from the archive: escape control bytes and non-UTF-8 (\xNN) so that
         * nothing in a name reaches the terminal as a control sequence */
        char buf[4096];
        printf("%s\n", sl_escape_text(entry, SIZE_MAX, buf, sizeof buf));
    }
}

static int list_maps(const char *cmd, const char *input, bool json)
{
    sl_error err;
    cli_json j;
    map_list l = {json, &j, 0};
    if (json) {
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "archive", input);
        cli_json_array_begin(&j, "maps");
    }
    sl_status st = sl_pk3_list_maps(input, print_map, &l, &err);
    if (json) {
        cli_json_array_end(&j);
        cli_json_uint(&j, "count", l.count);
        if (st != SL_OK)
            cli_json_string(&j, "error", err.message);
        cli_json_end(&j);
    }
    return st == SL_OK ? 0 : cli_fail(cmd, &err);
}

int sl_cmd_import(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_import imp = {0};
    const char *name, *val, *up = NULL;
    bool listing = false, have_bezier = false, synth = true;
    sl_synth_options syo = sl_synth_defaults();
    cli_common com = {0};
    sl_import_options opt = sl_import_defaults();
    sl_gis_options go = sl_gis_defaults();
    bool gis_opt = false, other_opt = false;
    while (cli_next(&a, &name, &val)) {
        bool is_gis = name != NULL; /* NULL: a positional argument */
        if (!name) {
        } else if (!strcmp(name, "height-attr")) {
            go.height_fields = cli_value(&a, name, val);
        } else if (!strcmp(name, "levels-attr")) {
            go.levels_fields = cli_value(&a, name, val);
        } else if (!strcmp(name, "default-height")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &go.default_height);
        } else if (!strcmp(name, "level-height")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &go.level_height);
        } else if (!strcmp(name, "max-extent")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &go.max_extent);
        } else if (!strcmp(name, "crs")) {
            go.crs = cli_value(&a, name, val);
        } else if (!strcmp(name, "layers")) {
            go.layers = cli_value(&a, name, val);
        } else if (!strcmp(name, "metric")) {
            go.metric = true;
        } else if (!strcmp(name, "no-streets")) {
            go.no_streets = true;
        } else if (!strcmp(name, "no-ground")) {
            go.no_ground = true;
        } else {
            is_gis = false;
        }
        if (is_gis) {
            gis_opt = true;
            continue;
        }
        if (name && (!strcmp(name, "scale") || !strcmp(name, "up") || !strcmp(name, "split") || !strcmp(name, "bezier")))
            other_opt = true;
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_OUTPUT | CLI_MAP | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!strcmp(name, "list-maps")) {
            listing = true;
        } else if (!strcmp(name, "scale")) {
            if (cli_parse_float(&a, name, cli_value(&a, name, val), &opt.unit_scale) && !(opt.unit_scale > 0)) {
                cli_error(a.cmd, "--scale must be positive");
                a.error = true;
            }
        } else if (!strcmp(name, "up")) {
            up = cli_value(&a, name, val);
            if (up && strcmp(up, "y") && strcmp(up, "z")) {
                cli_error(a.cmd, "--up: '%s' is not y or z", up);
                a.error = true;
            }
        } else if (!strcmp(name, "split")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &opt.split_triangles);
        } else if (!strcmp(name, "bezier")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &opt.bezier_level);
            have_bezier = true;
        } else if (!strcmp(name, "no-occluders")) {
            synth = false;
        } else if (cli_synth_option(&a, name, val, &syo)) {
        } else if (!cli_import_option(&a, name, val, &imp)) {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    const char *input = com.input, *output = com.output, *map = com.map;
    bool json = com.json, quiet = com.quiet;
    if (!input) {
        cli_error(a.cmd, "missing INPUT (see sightline import --help)");
        return 2;
    }
    char ext[16];
    extension_of(input, ext, sizeof ext);
    bool pk3 = !strcmp(ext, "pk3"), q3 = pk3 || !strcmp(ext, "bsp");
    /* options that only one family understands are mistakes with the other, not silently ignored */
    if (listing && !pk3) {
        cli_error(a.cmd, "--list-maps needs a .pk3 archive");
        return 2;
    }
    if (map && !pk3) {
        cli_error(a.cmd, "--map only applies to .pk3 archives");
        return 2;
    }
    if (q3 && up) {
        cli_error(a.cmd, "--up applies to assimp formats only (Quake III maps are Z-up)");
        return 2;
    }
    if (!q3 && have_bezier) {
        cli_error(a.cmd, "--bezier applies to Quake III maps only");
        return 2;
    }
    bool gis = sl_gis_path(input);
    if (gis && (other_opt || map)) {
        cli_error(a.cmd, "--scale, --up, --split, --bezier and --map do not apply to GIS files (see docs/gis-import.md)");
        return 2;
    }
    if (!gis && gis_opt) {
        cli_error(a.cmd, "the GIS options (--crs, --metric, --height-attr, ...) apply to GIS files only "
                         "(.geojson, .json, .shp, .osm, .pbf, .gml)");
        return 2;
    }
    if (listing)
        return list_maps(a.cmd, input, json);
    opt.up_axis = up && !strcmp(up, "z") ? SL_UP_Z : SL_UP_Y;
    cli_import_apply(&imp, &opt);

    char outbuf[1024];
    if (!output) {
        default_output(input, map, outbuf, sizeof outbuf);
        output = outbuf;
    }
    struct stat si, so;
    if (stat(input, &si) == 0 && stat(output, &so) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino) {
        cli_error(a.cmd, "the output %s is the input file", output);
        return 2;
    }

    cli_progress_state ps;
    opt.progress = cli_progress(&ps, quiet || json);
    sl_error err;
    sl_scene scene;
    double t0 = tool_now();
    sl_gis_stats gs;
    memset(&gs, 0, sizeof gs);
    go.progress = opt.progress;
    sl_status st = gis  ? sl_import_gis(input, &go, NULL, &scene, &gs, &err)
                   : q3 ? sl_import_q3bsp(input, map, &opt, NULL, &scene, &err)
                        : sl_import_assimp(input, &opt, NULL, &scene, &err);
    double t1 = tool_now();
    cli_progress_done(&ps);
    if (st != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_synth_stats ss;
    memset(&ss, 0, sizeof ss);
    if (synth && sl_synth_occluders(scene, &syo, NULL, &ss, &err) != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    double ts = tool_now();
    if (sl_scene_save(scene, output, &err) != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    double t2 = tool_now();

    sl_scene_stats s;
    sl_scene_get_stats(scene, &s);
    /* textures the importer could not keep (docs/import-export.md, "Materials") */
    const char *dropped = sl_scene_meta(scene, "assimp.textures_dropped"),
               *embedded = sl_scene_meta(scene, "assimp.textures_embedded");
    if (dropped || embedded)
        fprintf(stderr, "%s: warning: textures not kept: %s outside the model's folder or invalid, %s embedded (not supported); first: %s\n",
                a.cmd, dropped ? dropped : "0", embedded ? embedded : "0",
                sl_scene_meta(scene, "assimp.textures_dropped.first") ? sl_scene_meta(scene, "assimp.textures_dropped.first") : "?");
    uint32_t gis_warnings = gs.default_height + gs.bad_height + gs.unclosed_rings + gs.repaired + gs.dropped_invalid +
                            gs.dropped_far + gs.dropped_small + gs.dropped_transform;
    if (gis && gis_warnings) {
        char w[320];
        fprintf(stderr,
                "%s: warning: %u GIS problems: %u default heights, %u unusable heights, %u unclosed rings, %u repaired "
                "polygons, %u dropped (invalid), %u dropped (too far), %u polygons dropped (too small), %u dropped "
                "(reprojection); first: %s\n",
                a.cmd, gis_warnings, gs.default_height, gs.bad_height, gs.unclosed_rings, gs.repaired, gs.dropped_invalid,
                gs.dropped_far, gs.dropped_small, gs.dropped_transform, sl_escape_text(gs.first_warning, SIZE_MAX, w, sizeof w));
    }
    struct stat fs;
    uint64_t bytes = stat(output, &fs) == 0 ? (uint64_t)fs.st_size : 0;
    const char *format = sl_scene_meta(scene, gis ? "gis.driver" : q3 ? "importer" : "assimp.format");
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "input", input);
        cli_json_string(&j, "output", output);
        cli_json_string(&j, "importer", gis ? "gis" : q3 ? "quake3" : "assimp");
        cli_json_string(&j, "format", format);
        cli_json_uint(&j, "objects", s.object_count);
        cli_json_uint(&j, "meshes", s.mesh_count);
        cli_json_uint(&j, "vertices", s.vertex_count);
        cli_json_uint(&j, "triangles_stored", s.triangle_count);
        cli_json_uint(&j, "triangles_instanced", s.instanced_triangle_count);
        cli_json_uint(&j, "materials", s.material_count);
        cli_json_uint(&j, "see_through_objects", s.see_through_count);
        cli_json_uint(&j, "meshes_with_uvs", s.uv_mesh_count);
        cli_json_array_begin(&j, "bounds_min");
        cli_json_double(&j, NULL, s.bounds.min.x), cli_json_double(&j, NULL, s.bounds.min.y), cli_json_double(&j, NULL, s.bounds.min.z);
        cli_json_array_end(&j);
        cli_json_array_begin(&j, "bounds_max");
        cli_json_double(&j, NULL, s.bounds.max.x), cli_json_double(&j, NULL, s.bounds.max.y), cli_json_double(&j, NULL, s.bounds.max.z);
        cli_json_array_end(&j);
        if (gis) {
            cli_json_object_begin(&j, "gis");
            cli_json_string(&j, "crs", gs.crs);
            cli_json_string(&j, "frame", sl_scene_meta(scene, "gis.frame"));
            cli_json_uint(&j, "layers", gs.layers);
            cli_json_uint(&j, "features", gs.features);
            cli_json_uint(&j, "buildings", gs.buildings);
            cli_json_uint(&j, "building_parts", gs.building_parts);
            cli_json_uint(&j, "footprints", gs.footprints);
            cli_json_uint(&j, "streets", gs.streets);
            cli_json_uint(&j, "street_segments", gs.street_segments);
            cli_json_uint(&j, "street_nodes", gs.street_nodes);
            cli_json_uint(&j, "ground_tiles", gs.ground_tiles);
            cli_json_uint(&j, "other_features", gs.other);
            cli_json_uint(&j, "default_height", gs.default_height);
            cli_json_uint(&j, "bad_height", gs.bad_height);
            cli_json_uint(&j, "unclosed_rings", gs.unclosed_rings);
            cli_json_uint(&j, "repaired", gs.repaired);
            cli_json_uint(&j, "dropped_invalid", gs.dropped_invalid);
            cli_json_uint(&j, "dropped_far", gs.dropped_far);
            cli_json_uint(&j, "dropped_small", gs.dropped_small);
            cli_json_uint(&j, "dropped_transform", gs.dropped_transform);
            cli_json_uint(&j, "warnings", gis_warnings);
            if (gs.first_warning[0])
                cli_json_string(&j, "first_warning", gs.first_warning);
            cli_json_object_end(&j);
        }
        if (s.has_bsp) {
            cli_json_uint(&j, "bsp_leaves", s.bsp_leaf_count);
            cli_json_uint(&j, "bsp_clusters", s.bsp_cluster_count);
        }
        cli_json_double(&j, "import_seconds", t1 - t0);
        cli_json_double(&j, "save_seconds", t2 - ts);
        if (synth)
            cli_synth_json(&j, &ss);
        cli_json_uint(&j, "output_bytes", bytes);
        cli_json_uint(&j, "peak_rss_bytes", cli_peak_rss());
        cli_json_end(&j);
    } else {
        char b1[32], b2[32];
        printf("%s -> %s\n", input, output);
        if (format)
            printf("  format         %s\n", format);
        printf("  objects        %u (meshes %u)\n", s.object_count, s.mesh_count);
        printf("  triangles      %llu stored, %llu instanced (vertices %llu)\n", (unsigned long long)s.triangle_count,
               (unsigned long long)s.instanced_triangle_count, (unsigned long long)s.vertex_count);
        printf("  bounds         (%.2f, %.2f, %.2f) .. (%.2f, %.2f, %.2f) m\n", s.bounds.min.x, s.bounds.min.y, s.bounds.min.z,
               s.bounds.max.x, s.bounds.max.y, s.bounds.max.z);
        if (s.material_count || s.see_through_count || s.uv_mesh_count)
            printf("  materials      %u (%u see-through objects, %u meshes with UVs)\n", s.material_count, s.see_through_count,
                   s.uv_mesh_count);
        if (s.has_bsp)
            printf("  bsp            %u leaves, %u clusters\n", s.bsp_leaf_count, s.bsp_cluster_count);
        if (gis) {
            printf("  crs            %s -> %s\n", gs.crs, sl_scene_meta(scene, "gis.frame"));
            printf("  buildings      %u (%u polygons, %u footprints) of %u features in %u layers\n", gs.buildings,
                   gs.building_parts, gs.footprints, gs.features, gs.layers);
            printf("  streets        %u (%u segments, %u graph nodes), %u ground tiles\n", gs.streets, gs.street_segments,
                   gs.street_nodes, gs.ground_tiles);
        }
        if (synth)
            cli_synth_print(&ss);
        else
            printf("  occluders      none synthesised (--no-occluders)\n");
        printf("  time           %.3f s import, %.3f s save\n", t1 - t0, t2 - ts);
        printf("  output         %s (%s peak resident)\n", cli_bytes(bytes, b1, sizeof b1), cli_bytes(cli_peak_rss(), b2, sizeof b2));
    }
    sl_scene_destroy(scene);
    return 0;
}

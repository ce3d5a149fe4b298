/* `sightline info`: what a scene holds — counts, bounds, memory, per-kind statistics, occluders,
 * streets, terrain, BSP leaves/clusters and the map's own PVS, metadata. */
#include "cli.h"

#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <string.h>

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline info SCENE [--map NAME] [--objects] [--allow-external PATH] [--json] [--quiet]\n\n"
            "Print what a scene holds: objects, meshes and triangles (stored and instanced), per-kind\n"
            "counts, bounds, memory, footprints, occluders, street network, terrain, Quake III BSP\n"
            "leaves and clusters with statistics of the map's own cluster PVS, and metadata.\n\n"
            "SCENE is a .slscene file, a Quake III .bsp, a .pk3 archive (with --map), any file assimp\n"
            "reads, or city:tiny|small|vienna[:SEED] (the generated city, made on the fly).\n\n"
            "options:\n"
            "  --map NAME   map inside a .pk3 (\"oa_dm1\" or \"maps/oa_dm1.bsp\")\n"
            CLI_ALLOW_EXTERNAL_HELP
            "  --objects    list every object: id, name (the importer's node name, or none), kind,\n"
            "               triangles, flags and world bounds (ids are stable: the same input gives\n"
            "               the same objects in the same order)\n"
            "  --json       machine-readable output on stdout\n"
            "  --quiet      no progress output\n"
            "  --help       this text\n\n"
            "examples:\n"
            "  sightline info city-vienna-1.slscene\n"
            "  sightline info /usr/share/games/openarena/baseoa/pak1-maps.pk3 --map oa_dm1 --json\n");
}

typedef struct pvs_summary {
    uint32_t clusters;
    double avg_visible;        /* clusters visible per cluster */
    uint32_t min_visible, max_visible;
    double avg_fraction;       /* average visible fraction */
} pvs_summary;

static bool summarize_pvs(const sl_bsp_view *b, pvs_summary *out)
{
    memset(out, 0, sizeof *out);
    out->clusters = b->cluster_count;
    if (!b->pvs || !b->cluster_count)
        return false;
    uint64_t total = 0;
    out->min_visible = UINT32_MAX;
    for (uint32_t c = 0; c < b->cluster_count; c++) {
        const uint8_t *row = b->pvs + (size_t)c * b->cluster_bytes;
        uint32_t n = 0;
        for (uint32_t k = 0; k < b->cluster_count; k++)
            n += (row[k >> 3] >> (k & 7)) & 1;
        total += n;
        out->min_visible = n < out->min_visible ? n : out->min_visible;
        out->max_visible = n > out->max_visible ? n : out->max_visible;
    }
    out->avg_visible = (double)total / b->cluster_count;
    out->avg_fraction = out->avg_visible / b->cluster_count;
    return true;
}

int sl_cmd_info(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_import imp = {0};
    const char *name, *val;
    cli_common com = {0};
    bool list_objects = false;
    while (cli_next(&a, &name, &val))
        if (name && !strcmp(name, "objects"))
            list_objects = true;
        else if (!cli_common_option(&a, name, val, CLI_INPUT | CLI_MAP | CLI_JSON | CLI_QUIET, &com) &&
                 !cli_import_option(&a, name, val, &imp))
            cli_unknown(&a, name);
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    const char *input = com.input, *map = com.map;
    bool json = com.json, quiet = com.quiet;
    if (!input) {
        cli_error(a.cmd, "missing SCENE (see sightline info --help)");
        return 2;
    }
    (void)quiet;
    sl_error err;
    sl_scene scene;
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&imp, &io);
    if (cli_open_scene(input, map, &io, NULL, &scene, NULL, 0, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_scene_stats st;
    sl_scene_get_stats(scene, &st);
    sl_bsp_view bsp;
    bool has_bsp = sl_scene_bsp(scene, &bsp);
    pvs_summary pvs;
    bool has_pvs = has_bsp && summarize_pvs(&bsp, &pvs);
    sl_terrain_view terrain;
    bool has_terrain = sl_scene_terrain(scene, &terrain);
    uint64_t footprint_edges = 0;
    for (uint32_t i = 0; i < st.footprint_count; i++)
        footprint_edges += sl_scene_footprint(scene, i).vertex_count;
    char b1[32], b2[32];

    if (list_objects) {
        uint32_t n = sl_scene_object_count(scene);
        cli_json j;
        if (json) {
            cli_json_begin(&j, stdout);
            cli_json_string(&j, "file", input);
            cli_json_array_begin(&j, "objects");
        } else {
            printf("%-7s %-10s %9s %-22s %-52s %s\n", "id", "kind", "triangles", "flags", "bounds (m)", "name");
        }
        for (uint32_t i = 0; i < n; i++) {
            sl_object_view o = sl_scene_object(scene, i);
            const char *nm = sl_scene_object_name(scene, i);
            char flags[64];
            snprintf(flags, sizeof flags, "%s%s%s%s", o.flags & SL_OBJECT_OCCLUDER ? "occluder " : "",
                     o.flags & SL_OBJECT_SEE_THROUGH ? "see-through " : "",
                     o.flags & SL_OBJECT_CLOSED_CONVEX ? "convex " : "", o.flags & SL_OBJECT_DYNAMIC ? "dynamic" : "");
            size_t fl = strlen(flags);
            if (fl && flags[fl - 1] == ' ')
                flags[fl - 1] = 0;
            if (json) {
                cli_json_object_begin(&j, NULL);
                cli_json_uint(&j, "id", i);
                cli_json_string(&j, "name", nm);
                cli_json_string(&j, "kind", sl_object_kind_name(o.kind));
                cli_json_uint(&j, "triangles", o.triangle_count);
                cli_json_string(&j, "flags", flags);
                cli_json_array_begin(&j, "bounds");
                const float bb[6] = {o.bounds.min.x, o.bounds.min.y, o.bounds.min.z,
                                     o.bounds.max.x, o.bounds.max.y, o.bounds.max.z};
                for (int k = 0; k < 6; k++)
                    cli_json_double(&j, NULL, bb[k]);
                cli_json_array_end(&j);
                cli_json_object_end(&j);
            } else {
                char box[128];
                snprintf(box, sizeof box, "(%.2f, %.2f, %.2f) .. (%.2f, %.2f, %.2f)", o.bounds.min.x, o.bounds.min.y,
                         o.bounds.min.z, o.bounds.max.x, o.bounds.max.y, o.bounds.max.z);
                printf("%-7u %-10s %9u %-22s %-52s %s\n", i, sl_object_kind_name(o.kind), o.triangle_count,
                       flags[0] ? flags : "-", box, nm[0] ? nm : "-");
            }
        }
        if (json) {
            cli_json_array_end(&j);
            cli_json_end(&j);
        }
        sl_scene_destroy(scene);
        return 0;
    }
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", input);
        cli_json_uint(&j, "objects", st.object_count);
        cli_json_uint(&j, "meshes", st.mesh_count);
        cli_json_uint(&j, "vertices", st.vertex_count);
        cli_json_uint(&j, "triangles_stored", st.triangle_count);
        cli_json_uint(&j, "triangles_instanced", st.instanced_triangle_count);
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
        cli_json_uint(&j, "peak_rss_bytes", cli_peak_rss());
        cli_json_uint(&j, "footprints", st.footprint_count);
        cli_json_uint(&j, "materials", st.material_count);
        cli_json_uint(&j, "see_through_objects", st.see_through_count);
        cli_json_uint(&j, "meshes_with_uvs", st.uv_mesh_count);
        cli_json_uint(&j, "facades", footprint_edges);
        cli_json_uint(&j, "occluder_meshes", st.occluder_count);
        cli_json_uint(&j, "street_polygons", st.street_polygon_count);
        cli_json_uint(&j, "street_nodes", st.street_node_count);
        cli_json_uint(&j, "street_edges", st.street_edge_count);
        if (has_terrain) {
            cli_json_object_begin(&j, "terrain");
            cli_json_uint(&j, "nx", terrain.nx);
            cli_json_uint(&j, "ny", terrain.ny);
            cli_json_double(&j, "cell", terrain.cell);
            cli_json_object_end(&j);
        }
        if (has_bsp) {
            cli_json_object_begin(&j, "bsp");
            cli_json_uint(&j, "planes", bsp.plane_count);
            cli_json_uint(&j, "nodes", bsp.node_count);
            cli_json_uint(&j, "leaves", bsp.leaf_count);
            cli_json_uint(&j, "clusters", bsp.cluster_count);
            cli_json_bool(&j, "has_pvs", has_pvs);
            if (has_pvs) {
                cli_json_double(&j, "pvs_avg_visible_clusters", pvs.avg_visible);
                cli_json_uint(&j, "pvs_min_visible_clusters", pvs.min_visible);
                cli_json_uint(&j, "pvs_max_visible_clusters", pvs.max_visible);
                cli_json_double(&j, "pvs_avg_visible_fraction", pvs.avg_fraction);
            }
            cli_json_object_end(&j);
        }
        cli_json_object_begin(&j, "meta");
        for (uint32_t i = 0; i < sl_scene_meta_count(scene); i++) {
            const char *k, *v;
            sl_scene_meta_at(scene, i, &k, &v);
            cli_json_string(&j, k, v);
        }
        cli_json_object_end(&j);
        cli_json_end(&j);
    } else {
        printf("%s%s%s\n", input, map ? " map " : "", map ? map : "");
        printf("  objects        %u (meshes %u)\n", st.object_count, st.mesh_count);
        printf("  triangles      %llu stored, %llu instanced (vertices %llu)\n", (unsigned long long)st.triangle_count,
               (unsigned long long)st.instanced_triangle_count, (unsigned long long)st.vertex_count);
        printf("  bounds         (%.2f, %.2f, %.2f) .. (%.2f, %.2f, %.2f) m\n", st.bounds.min.x, st.bounds.min.y,
               st.bounds.min.z, st.bounds.max.x, st.bounds.max.y, st.bounds.max.z);
        printf("  memory         %s in the scene, %s peak resident\n", cli_bytes(st.memory_bytes, b1, sizeof b1),
               cli_bytes(cli_peak_rss(), b2, sizeof b2));
        printf("  per kind       %-10s %10s %12s\n", "kind", "objects", "triangles");
        for (uint32_t k = 0; k < SL_KIND_COUNT; k++)
            if (st.objects_per_kind[k])
                printf("                 %-10s %10u %12llu\n", sl_object_kind_name(k), st.objects_per_kind[k],
                       (unsigned long long)st.triangles_per_kind[k]);
        printf("  occluders      %u footprints (%llu façades), %u 3D occluder meshes\n", st.footprint_count,
               (unsigned long long)footprint_edges, st.occluder_count);
        if (st.material_count || st.see_through_count || st.uv_mesh_count)
            printf("  materials      %u (%u see-through objects, %u meshes with UVs)\n", st.material_count,
                   st.see_through_count, st.uv_mesh_count);
        printf("  streets        %u polygons, graph %u nodes / %u edges\n", st.street_polygon_count, st.street_node_count,
               st.street_edge_count);
        if (has_terrain)
            printf("  terrain        %u x %u samples, %.2f m spacing\n", terrain.nx, terrain.ny, terrain.cell);
        if (has_bsp) {
            printf("  bsp            %u planes, %u nodes, %u leaves, %u clusters\n", bsp.plane_count, bsp.node_count,
                   bsp.leaf_count, bsp.cluster_count);
            if (has_pvs)
                printf("  reference pvs  %.1f clusters visible per cluster on average (min %u, max %u), %.1f%% of the map\n",
                       pvs.avg_visible, pvs.min_visible, pvs.max_visible, 100.0 * pvs.avg_fraction);
            else
                printf("  reference pvs  none (the map has no vis data)\n");
        }
        for (uint32_t i = 0; i < sl_scene_meta_count(scene); i++) {
            const char *k, *v;
            sl_scene_meta_at(scene, i, &k, &v);
            if (strlen(v) > 80)
                printf("  meta %-9s %.77s...\n", k, v);
            else
                printf("  meta %-9s %s\n", k, v);
        }
    }
    sl_scene_destroy(scene);
    return 0;
}

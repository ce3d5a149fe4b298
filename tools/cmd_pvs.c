/* `sightline pvs`: bake, inspect, query and verify precomputed from-region visibility (.slpvs).
 * The format is in docs/pvs.md; the library calls in include/sightline/pvs.h and region.h. */
#include "cli.h"
#include "pvs_cli.h"

#include "tool.h"

#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"
#include "sightline/truth.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void usage_main(FILE *out)
{
    fprintf(out,
            "usage: sightline pvs <action> [options]   (sightline pvs <action> --help for details)\n\n"
            "Precomputed from-region visibility: the objects visible from anywhere in each view cell.\n\n"
            "actions:\n"
            "  build SCENE -o OUT.slpvs      bake a PVS (view cells + a method), on all cores or under mpiexec\n"
            "  info FILE.slpvs               header figures, cells, sizes, build metadata\n"
            "  query FILE.slpvs --point X,Y,Z | --cell N    the cell of a point and its visible set\n"
            "  verify FILE.slpvs [--scene SCENE --cells N]  checksums and sets; with a scene, zero misses\n"
            "                                against the region oracle on N random cells\n"
            "  update FILE.slpvs --old-scene OLD --scene EDITED [-o OUT.slpvs]   after an edit, re-bake only\n"
            "                                the cells it can affect: the same bytes as a full bake of EDITED\n\n"
            "examples:\n"
            "  sightline pvs build city.slscene -o city.slpvs --method sample --options eps=1.5,cell=2\n"
            "  mpiexec -n 4 sightline pvs build city.slscene -o city.slpvs\n"
            "  sightline pvs info city.slpvs --json\n"
            "  sightline pvs query city.slpvs --point 10,-4,1.7\n"
            "  sightline pvs verify city.slpvs --scene city.slscene --cells 200\n");
}

static void usage_build(FILE *out)
{
    fprintf(out,
            "usage: sightline pvs build SCENE -o OUT.slpvs [options]\n"
            "       sightline pvs build --city PRESET -o OUT.slpvs [options]\n\n"
            "Make view cells for SCENE and bake the set of objects visible from each cell. The file is\n"
            "byte-identical whatever the thread or process count. A checkpoint journal (OUT.slpvs.ckpt)\n"
            "records every finished cell: an interrupted bake continues with --resume.\n\n"
            "SCENE is a .slscene, a Quake III .bsp or .pk3 (with --map), any file assimp reads, or\n"
            "city:tiny|small|vienna|oldtown|oldtown-small[:SEED]; --city PRESET (with --seed) is the same as\n"
            "city:PRESET:SEED.\n\n"
            "view cells:\n"
            "  --cells KIND      streets: constrained triangulation of the street space (default with\n"
            "                    streets); grid: squares over the streets; bsp: the map's own clusters\n"
            "                    (default for Quake III maps); adaptive: subdivision of --volume\n"
            "  --cell-size M     streets: longest triangle edge (12); grid: square side (8); adaptive:\n"
            "                    largest box (16)\n"
            "  --eye-min H       lowest eye above the ground (1.0 m)\n"
            "  --eye-max H       highest eye above the ground (2.0 m)\n"
            "  --volume X0,Y0,Z0,X1,Y1,Z1   adaptive: the navigable box\n"
            "  --along PATH      only the cells whose bounds come within --radius of a camera of the path\n"
            "                    file (docs/paths.md): a PVS for one walk; elsewhere the pvs culler finds\n"
            "                    no cell and falls back to frustum culling\n"
            "  --radius M        with --along: distance from the cameras (default 2 m)\n\n"
            "method:\n"
            "  --method NAME[:key=value...]  baking method (with its options, as --options takes them);\n"
            "                    default: the one that suits the scene, named on stderr\n"
            "                    (portal for Quake III cluster cells, adjustable for scenes with building\n"
            "                    footprints all at one base height, extproj when their bases differ, as over\n"
            "                    terrain; for other scenes none is conservative: give --method gvs for an\n"
            "                    aggressive PVS); available:\n");
    for (uint32_t i = 0; i < sl_pvs_method_count(); i++) {
        sl_pvs_method_desc d;
        if (sl_pvs_method_info(i, &d, NULL) != SL_OK)
            continue;
        fprintf(out, "                    %s (%s): %s\n", d.name, sl_cull_guarantee_name(d.guarantee), d.summary);
        const char *h = d.options_help;
        while (h && *h) {
            const char *e = strchr(h, '\n');
            int n = e ? (int)(e - h) : (int)strlen(h);
            fprintf(out, "                      %.*s\n", n, h);
            h += n + (e ? 1 : 0);
        }
    }
    fprintf(out,
            "  --options K=V,... the method's options\n\n"
            "running:\n"
            "  --threads N       OpenMP threads per process, 1..%u (SL_MAX_THREADS, or the OpenMP\n"
            "                    runtime's lower OMP_THREAD_LIMIT; default: all cores)\n"
            "  --mpi             distribute cells over MPI processes (automatic under mpiexec)\n"
            "  --lease S         MPI: a process holding a chunk S seconds without a result (stopped, hung)\n"
            "                    has its cells handed to an idle process too; the first result wins, the\n"
            "                    file is the same (default %g; 0: never)\n"
            "  --resume          continue an interrupted bake from its checkpoint\n"
            "  --checkpoint F    journal path (default OUT.slpvs.ckpt), created with the first finished\n"
            "                    cell; a bake that fails before leaves none, one that fails later keeps\n"
            "                    its cells for --resume. A bake holds the lock F.lock while it runs: a\n"
            "                    second bake of the same output is refused (\"another bake ... (pid N)\")\n"
            "  --keep-checkpoint keep the journal after success\n"
            "  --no-regions      leave out the motion regions (by default, when the scene's dynamic\n"
            "                    objects have motion records, a box hierarchy over their regions is\n"
            "                    marked per cell and stored, .slpvs 1.2; docs/motion.md)\n"
            "  --stop-after N    testing: stop after N newly baked cells (exit 3), leaving the journal\n"
            "  --map NAME        map inside a .pk3\n"
            "  --allow-external PATH  an assimp model's references may resolve inside PATH too\n"
            "  --import-timeout S  stop reading an assimp model after S seconds\n"
            "  --seed N          --city: generator seed (default 1)\n"
            "  --json            machine-readable summary on stdout\n"
            "  --quiet           no progress bar\n"
            "  --help            this text\n\n"
            "examples:\n"
            "  sightline pvs build city.slscene -o city.slpvs\n"
            "  sightline pvs build --city tiny -o tiny.slpvs --cell-size 8 --options eps=1,cell=1\n"
            "  mpiexec -n 2 sightline pvs build city.slscene -o city.slpvs --threads 1\n"
            "  sightline pvs build --city small --along walk.txt --method adjustable -o walk.slpvs\n"
            "  sightline pvs build oa_dm1.pk3 --map oa_dm1 --cells bsp --method portal -o dm1.slpvs\n",
            SL_MAX_THREADS, CLI_PVS_LEASE_DEFAULT);
}

static void usage_info(FILE *out)
{
    fprintf(out, "usage: sightline pvs info FILE.slpvs [--json]\n\n"
                 "Print the header figures (cells, objects, set sizes, fraction culled, bytes) and the build\n"
                 "metadata of a PVS file. The compressed sets are not decoded (see verify).\n\n"
                 "options:\n  --json   machine-readable output\n  --help   this text\n\n"
                 "example:\n  sightline pvs info city.slpvs --json\n");
}

static void usage_query(FILE *out)
{
    fprintf(out, "usage: sightline pvs query FILE.slpvs (--point X,Y,Z | --cell N) [options]\n\n"
                 "Find the view cell holding a point (or take a cell by number) and print its visible set\n"
                 "and, for a file with motion regions, how many of them the cell marks visible.\n\n"
                 "options:\n"
                 "  --point X,Y,Z  a position (metres)\n"
                 "  --cell N       a cell number, 0..cells-1 (others are refused)\n"
                 "  --scene SCENE  the scene the file was baked for (checked against its scene key);\n"
                 "                 required with --point for Quake III cluster cells, whose leaves only\n"
                 "                 the map's BSP tree can find\n"
                 "  --map NAME     map inside a .pk3\n"
                 "  --allow-external PATH  an assimp model's references may resolve inside PATH too\n"
                 "  --import-timeout S  stop reading an assimp model after S seconds\n"
                 "  --ids          print the object ids (and the marked region nodes) too\n"
                 "  --json         machine-readable output\n"
                 "  --help         this text\n\n"
                 "examples:\n  sightline pvs query city.slpvs --point 10,-4,1.7 --ids\n"
                 "  sightline pvs query city.slpvs --cell 12 --json\n");
}

static void usage_verify(FILE *out)
{
    fprintf(out,
            "usage: sightline pvs verify FILE.slpvs [--scene SCENE | --city PRESET] [options]\n\n"
            "Check every checksum and decode every set. With a scene, also check that the file belongs to\n"
            "it and hold the sets to the region oracle (dense cube-map sampling of each cell, a lower\n"
            "bound of the exact visible set): every object the oracle sees must be in the cell's set.\n"
            "Misses are listed with the cell and the object, and make the exit status 1. For Quake III\n"
            "cluster cells the map's own PVS is checked the same way and the sizes compared; objects\n"
            "farther from the cell than the map's vis far plane (_farplanedist, fog maps) are told apart\n"
            "and do not fail a mappvs file, and clusters without a point to sample are skipped. Samples in\n"
            "solid or void space of a map are outside the domain (docs/oracle.md) and skipped; a cell with\n"
            "no other sample is skipped and counted.\n\n"
            "options:\n"
            "  --scene SCENE   the scene the PVS was baked for; --city PRESET [--seed N] generates it\n"
            "  --map NAME      map inside a .pk3\n"
            "  --allow-external PATH  an assimp model's references may resolve inside PATH too\n"
            "  --import-timeout S  stop reading an assimp model after S seconds\n"
            "  --cells N       random cells to check with the oracle (default 20 with a scene)\n"
            "  --all           every cell\n"
            "  --seed N        cell choice and oracle sampling seed (default 1); with --city also the\n"
            "                  city's seed: for another sample of the same city give --scene city:PRESET:SEED\n"
            "  --face-size N   oracle cube-map face resolution (default 256)\n"
            "  --spacing M     oracle sample spacing along cell edges (default 1 m)\n"
            "  --samples N     oracle random points on the faces and inside, each (default 24)\n"
            "  --json          machine-readable output\n"
            "  --quiet         no progress bar\n"
            "  --help          this text\n\n"
            "examples:\n  sightline pvs verify city.slpvs\n"
            "  sightline pvs verify city.slpvs --scene city.slscene --cells 200 --json\n");
}

/* ---- shared helpers ---- */

/* --allow-external of the subcommand being run (one per process; read by load_scene). */
static cli_import pvs_import;

static sl_status load_scene(const char *path, const char *map, const char *city, uint64_t seed, sl_scene *out,
                            sl_error *err)
{
    if (city) {
        sl_city_preset p;
        sl_status st = sl_city_preset_from_name(city, &p, err);
        if (st != SL_OK)
            return st;
        sl_city_options o = sl_city_defaults(p);
        o.seed = seed;
        return sl_gen_city(&o, NULL, out, err);
    }
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&pvs_import, &io);
    return cli_open_scene(path, map, &io, NULL, out, NULL, 0, err);
}

static bool parse_floats(cli_args *a, const char *name, const char *text, float *out, int n)
{
    if (!text)
        return false;
    if (!sl_parse_floats(text, out, n)) { /* src/core/text_parse.c */
        cli_error(a->cmd, "--%s: '%s' is not %d comma-separated finite numbers", name, text, n);
        a->error = true;
        return false;
    }
    return true;
}

/* ---- build ---- */

/* --along PATH --radius R of build and update: *cells becomes the cells near the path's cameras
 * (destroyed and NULL on failure); far / cameras: the cameras no cell comes near, of how many. */
static sl_status keep_cells_along(sl_viewcells *cells, const char *along, float radius, uint32_t *far,
                                  uint32_t *cameras, sl_error *err)
{
    sl_path path = NULL;
    sl_viewcells near = NULL;
    sl_status st = sl_path_load(along, NULL, &path, err);
    if (st != SL_OK)
        tool_error_prefix(err, "--along");
    if (st == SL_OK)
        st = cli_viewcells_along(*cells, path, radius, &near, far, err);
    *cameras = path ? sl_path_count(path) : 0;
    sl_path_destroy(path);
    sl_viewcells_destroy(*cells);
    *cells = near;
    return st;
}

/* Said before the bake, not after it: cameras of --along that no cell comes near (a path of the
 * wrong scene, or above the streets). */
static void warn_far_cameras(const char *cmd, uint32_t far, uint32_t cameras, const char *along, float radius)
{
    if (far && cameras)
        fprintf(stderr,
                "sightline %s: WARNING: %u of the %u cameras of %s are farther than %g m from every view cell "
                "(%.1f%%): the PVS holds no set for them, and the pvs culler falls back to frustum culling there "
                "(a path above the streets, or of another scene? --radius widens the reach)\n",
                cmd, far, cameras, along, (double)radius, 100.0 * far / cameras);
}

static int run_build(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = "pvs build";
    const char *name, *val, *cells_kind = NULL, *city = NULL;
    const char *along = NULL;
    cli_common com = {0};
    float radius = 2.0f, lease = (float)CLI_PVS_LEASE_DEFAULT;
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    sl_viewcell_options vo;
    memset(&vo, 0, sizeof vo);
    float volume[6];
    bool has_volume = false, mpi = false;
    uint64_t seed = 1;
    while (cli_next(&a, &name, &val)) {
        if (cli_import_option(&a, name, val, &pvs_import) ||
            cli_common_option(&a, name, val, CLI_INPUT | CLI_OUTPUT | CLI_MAP | CLI_JSON | CLI_QUIET, &com))
            continue;
        if (!strcmp(name, "cells")) {
            cells_kind = cli_value(&a, name, val);
        } else if (!strcmp(name, "cell-size")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &vo.max_edge);
        } else if (!strcmp(name, "eye-min")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &vo.eye_min);
        } else if (!strcmp(name, "eye-max")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &vo.eye_max);
        } else if (!strcmp(name, "volume")) {
            has_volume = parse_floats(&a, name, cli_value(&a, name, val), volume, 6);
        } else if (!strcmp(name, "along")) {
            along = cli_value(&a, name, val);
        } else if (!strcmp(name, "radius")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &radius);
        } else if (!strcmp(name, "method")) {
            bo.method = cli_value(&a, name, val);
        } else if (!strcmp(name, "options")) {
            bo.method_options = cli_value(&a, name, val);
        } else if (!strcmp(name, "threads")) {
            cli_parse_threads(&a, name, cli_value(&a, name, val), true, &bo.threads);
        } else if (!strcmp(name, "mpi")) {
            mpi = true;
        } else if (!strcmp(name, "lease")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &lease);
        } else if (!strcmp(name, "resume")) {
            bo.resume = true;
        } else if (!strcmp(name, "checkpoint")) {
            bo.checkpoint = cli_value(&a, name, val);
        } else if (!strcmp(name, "keep-checkpoint")) {
            bo.keep_checkpoint = true;
        } else if (!strcmp(name, "no-regions")) {
            bo.no_regions = true;
        } else if (!strcmp(name, "stop-after")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &bo.stop_after);
        } else if (!strcmp(name, "city")) {
            city = cli_value(&a, name, val);
        } else if (!strcmp(name, "seed")) {
            cli_parse_u64(&a, name, cli_value(&a, name, val), &seed);
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage_build);
    if (parsed >= 0)
        return parsed;
    const char *scene_path = com.input, *output = com.output, *map = com.map;
    bool json = com.json, quiet = com.quiet;
    if ((!scene_path && !city) || (scene_path && city) || !output) {
        cli_error(a.cmd, "%s (see sightline pvs build --help)",
                  !output ? "missing -o OUT.slpvs" : scene_path && city ? "give SCENE or --city, not both" : "missing SCENE");
        return 2;
    }
    const char *inputs[] = {scene_path, along};
    if (!cli_output_not_input(a.cmd, output, inputs, 2) || !cli_output_not_input(a.cmd, bo.checkpoint, inputs, 2))
        return 2;
    if (cells_kind && strcmp(cells_kind, "streets") && strcmp(cells_kind, "grid") && strcmp(cells_kind, "bsp") &&
        strcmp(cells_kind, "adaptive")) {
        cli_error(a.cmd, "--cells: '%s' is not streets, grid, bsp or adaptive", cells_kind);
        return 2;
    }
    if (!(lease >= 0) || lease > 1e6f) {
        cli_error(a.cmd, "--lease must be 0 (never hand a chunk out twice) or up to 1e6 seconds");
        return 2;
    }
    if (!(radius >= 0) || !isfinite(radius)) {
        cli_error(a.cmd, "--radius must be a finite distance >= 0");
        return 2;
    }
    if (cells_kind && !strcmp(cells_kind, "adaptive") && !has_volume) {
        cli_error(a.cmd, "--cells adaptive needs --volume X0,Y0,Z0,X1,Y1,Z1");
        return 2;
    }
    sl_error err;
    /* --method NAME:key=value[:key=value...]: the grammar of --methods elsewhere */
    char method_buf[512];
    if (bo.method && strchr(bo.method, ':')) {
        if (bo.method_options) {
            cli_error(a.cmd, "--method %s carries options: give them there or in --options, not both", bo.method);
            return 2;
        }
        if (snprintf(method_buf, sizeof method_buf, "%s", bo.method) >= (int)sizeof method_buf) {
            cli_error(a.cmd, "--method: too long");
            return 2;
        }
        char *colon = strchr(method_buf, ':');
        *colon++ = 0;
        for (char *c = colon; *c; c++)
            if (*c == ':')
                *c = ',';
        bo.method = method_buf;
        bo.method_options = colon;
    }
    if (bo.method && sl_pvs_method_check_options(bo.method, bo.method_options, &err) != SL_OK) {
        cli_error(a.cmd, "%s", err.message);
        return 2;
    }
    /* under mpiexec every process runs this; only rank 0 talks */
    const char *pmi = getenv("PMI_SIZE");
    if (pmi && atoi(pmi) > 1)
        mpi = true;
    sl_scene scene;
    if (load_scene(scene_path, map, city, seed, &scene, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_viewcells cells = NULL;
    sl_status st;
    if (!cells_kind) {
        sl_bsp_view bv;
        cells_kind = sl_scene_street_polygon_count(scene) > 0 ? "streets" : sl_scene_bsp(scene, &bv) ? "bsp" : NULL;
        if (!cells_kind) {
            sl_scene_destroy(scene);
            cli_error(a.cmd, "the scene has neither streets nor BSP clusters: choose --cells grid or --cells adaptive "
                             "--volume ...");
            return 2;
        }
    }
    /* no --method: the one that suits the scene, said on stderr */
    if (!bo.method) {
        const char *why;
        if (!strcmp(cells_kind, "bsp")) {
            bo.method = "portal";
            why = "the conservative method for Quake III cluster cells";
        } else if (sl_scene_footprint_count(scene) > 0) {
            /* footprints at different heights (terrain, bridges): adjustable and sample use for a
             * cell only those at or below its lowest eye, and keep little there */
            bool level = true;
            const float b0 = sl_scene_footprint(scene, 0).base_z;
            for (uint32_t f = 1; f < sl_scene_footprint_count(scene) && level; f++)
                level = sl_scene_footprint(scene, f).base_z == b0;
            if (level) {
                bo.method = "adjustable";
                why = "the conservative method for scenes with building footprints: sample culls about 0.6% more "
                      "objects in about 6 times the time, BENCHMARKS.md";
            } else {
                bo.method = "extproj";
                why = "the conservative method for building footprints at different heights (terrain, bridges): "
                      "adjustable and sample occlude only with footprints at or below a cell's lowest eye, which "
                      "over relief leaves little culled (docs/pvs.md, \"Footprints above the ground\"); pvs update "
                      "cannot update an extproj bake: give --method adjustable for that";
            }
        } else {
            sl_scene_destroy(scene);
            cli_error(a.cmd, "no conservative from-region method applies to this scene: it has no building "
                             "footprints (adjustable, sample) and no BSP clusters (portal); bake an aggressive PVS "
                             "with --method gvs, or give --method to choose");
            return 2;
        }
        if (sl_pvs_method_check_options(bo.method, bo.method_options, &err) != SL_OK) {
            sl_scene_destroy(scene);
            cli_error(a.cmd, "%s", err.message);
            return 2;
        }
        const char *pmi_rank = getenv("PMI_RANK");
        if (!json && (!pmi_rank || atoi(pmi_rank) == 0)) /* --quiet removes the progress only */
            fprintf(stderr, "sightline pvs build: method %s (%s; --method NAME to choose)\n", bo.method, why);
    }
    if (!strcmp(cells_kind, "streets"))
        st = sl_viewcells_from_streets(scene, &vo, &cells, &err);
    else if (!strcmp(cells_kind, "grid"))
        st = sl_viewcells_grid(scene, &vo, &cells, &err);
    else if (!strcmp(cells_kind, "bsp"))
        st = sl_viewcells_from_bsp(scene, &vo, &cells, &err);
    else {
        sl_aabb box = {{volume[0], volume[1], volume[2]}, {volume[3], volume[4], volume[5]}};
        st = sl_viewcells_adaptive(scene, &box, SL_NONE, &vo, &cells, &err);
    }
    uint32_t far_cameras = 0, path_cameras = 0;
    if (st == SL_OK && along)
        st = keep_cells_along(&cells, along, radius, &far_cameras, &path_cameras, &err);
    if (st != SL_OK) {
        sl_viewcells_destroy(cells);
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    const char *rank0 = getenv("PMI_RANK");
    if (!rank0 || atoi(rank0) == 0)
        warn_far_cameras(a.cmd, far_cameras, path_cameras, along, radius);
    cli_progress_state ps;
    sl_pvs_build_stats stats;
    int rank = 0;
    if (mpi) {
        bo.progress = cli_progress(&ps, true); /* the MPI driver reports nothing per cell */
        st = cli_pvs_build_mpi(scene, cells, output, &bo, (double)lease, &stats, &rank, &err);
    } else {
        bo.progress = json && !quiet ? cli_progress_json(&ps) : cli_progress(&ps, quiet || json);
        st = sl_pvs_build(scene, cells, output, &bo, &stats, &err);
        cli_progress_done(&ps);
    }
    sl_viewcells_destroy(cells);
    sl_scene_destroy(scene);
    if (rank != 0)
        return st == SL_OK ? 0 : 1;
    if (stats.notice[0])
        fprintf(stderr, "sightline pvs build: WARNING: %s\n", stats.notice);
    if (st != SL_OK) {
        if (st == SL_ERROR_CANCELLED && bo.stop_after) {
            fprintf(stderr, "sightline pvs build: %s\n", err.message);
            return 3;
        }
        return cli_fail(a.cmd, &err);
    }
    double per_cell = stats.cells_baked ? stats.cell_seconds / stats.cells_baked : 0;
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", output);
        cli_json_string(&j, "cells_kind", cells_kind);
        cli_json_string(&j, "method", stats.method);
        cli_json_string(&j, "options", stats.options);
        cli_json_uint(&j, "cells", stats.cells);
        cli_json_uint(&j, "cells_baked", stats.cells_baked);
        cli_json_uint(&j, "cells_resumed", stats.cells_resumed);
        cli_json_uint(&j, "processes", stats.processes);
        cli_json_uint(&j, "threads", stats.threads);
        cli_json_double(&j, "seconds", stats.seconds);
        cli_json_double(&j, "seconds_per_cell", per_cell);
        cli_json_double(&j, "max_cell_seconds", stats.max_cell_seconds);
        cli_json_uint(&j, "visible_total", stats.visible_total);
        cli_json_double(&j, "mean_culled", stats.mean_culled);
        cli_json_uint(&j, "file_bytes", stats.file_bytes);
        cli_json_uint(&j, "occluders_removed", stats.occluders_removed);
        cli_json_uint(&j, "regions", stats.regions);
        cli_json_double(&j, "region_seconds", stats.region_seconds);
        cli_json_string(&j, "notice", stats.notice);
        cli_json_end(&j);
    } else {
        char b[32];
        printf("%s: %u %s cells, method %s (%s)\n", output, stats.cells, cells_kind, stats.method, stats.options);
        printf("  baked %u cells (%u resumed) in %.2f s on %u process(es) x %u thread(s); %.4f s per cell (max %.4f)\n",
               stats.cells_baked, stats.cells_resumed, stats.seconds, stats.processes, stats.threads, per_cell,
               stats.max_cell_seconds);
        printf("  mean visible %.1f objects, mean culled %.4f%%, %s on disk, %llu occluders vanished under shrinking\n",
               stats.cells ? (double)stats.visible_total / stats.cells : 0.0, 100.0 * stats.mean_culled,
               cli_bytes(stats.file_bytes, b, sizeof b), (unsigned long long)stats.occluders_removed);
        if (stats.regions)
            printf("  motion regions: %u nodes, marked for every cell in %.2f s\n", stats.regions, stats.region_seconds);
    }
    return 0;
}

/* ---- info ---- */

/* The motion-region hierarchy's leaves (the distinct regions) and, for `row` (a cell's marks;
 * NULL: none), how many nodes and leaves it marks visible. */
typedef struct region_counts {
    uint32_t leaves, marked, leaves_marked;
} region_counts;

static region_counts count_regions(sl_pvs p, const uint8_t *row)
{
    region_counts rc = {0, 0, 0};
    const sl_pvs_region *nodes = sl_pvs_region_nodes(p);
    uint32_t n = sl_pvs_region_count(p);
    for (uint32_t k = 0; nodes && k < n; k++) {
        bool leaf = nodes[k].child_count == 0, mark = row && (row[k >> 3] >> (k & 7) & 1u);
        rc.leaves += leaf;
        rc.marked += mark;
        rc.leaves_marked += leaf && mark;
    }
    return rc;
}

static int run_info(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = "pvs info";
    const char *name, *val;
    cli_common com = {0};
    while (cli_next(&a, &name, &val))
        if (!cli_common_option(&a, name, val, CLI_INPUT | CLI_JSON, &com))
            cli_unknown(&a, name);
    int parsed = cli_parse_done(&a, &com, usage_info);
    if (parsed >= 0)
        return parsed;
    const char *file = com.input;
    bool json = com.json;
    if (!file) {
        cli_error(a.cmd, "missing FILE.slpvs (see sightline pvs info --help)");
        return 2;
    }
    sl_error err;
    sl_pvs p;
    if (sl_pvs_load(file, NULL, &p, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    sl_viewcells_stats cs;
    sl_viewcells_get_stats(sl_pvs_cells(p), &cs);
    /* the hierarchy and every cell's row of marks, as the open handle holds them */
    region_counts rcount = count_regions(p, NULL);
    uint64_t region_bytes = (uint64_t)in.region_count * sizeof(sl_pvs_region) +
                            (uint64_t)in.cell_count * ((in.region_count + 7) / 8);
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", file);
        char ver[32];
        snprintf(ver, sizeof ver, "%u.%u", in.version_major, in.version_minor);
        cli_json_string(&j, "version", ver);
        cli_json_uint(&j, "cells", in.cell_count);
        cli_json_uint(&j, "prisms", cs.prisms);
        cli_json_uint(&j, "boxes", cs.boxes);
        cli_json_uint(&j, "clusters", cs.clusters);
        cli_json_double(&j, "cell_area_m2", cs.area);
        cli_json_uint(&j, "objects", in.object_count);
        cli_json_uint(&j, "visible_total", in.visible_total);
        cli_json_uint(&j, "min_visible", in.min_visible);
        cli_json_uint(&j, "max_visible", in.max_visible);
        cli_json_double(&j, "mean_visible", in.mean_visible);
        cli_json_double(&j, "mean_culled", in.mean_culled);
        cli_json_uint(&j, "file_bytes", in.file_size);
        cli_json_uint(&j, "data_bytes", in.data_bytes);
        cli_json_uint(&j, "raw_bytes", in.raw_bytes);
        cli_json_uint(&j, "blocks", in.block_count);
        char key[32];
        snprintf(key, sizeof key, "%016llx", (unsigned long long)in.scene_key);
        cli_json_string(&j, "scene_key", key);
        cli_json_uint(&j, "scene_key_format", in.scene_key_version);
        cli_json_uint(&j, "regions", in.region_count);
        cli_json_uint(&j, "region_leaves", rcount.leaves);
        cli_json_double(&j, "mean_regions_visible", in.mean_regions_visible);
        cli_json_uint(&j, "region_memory_bytes", region_bytes);
        cli_json_object_begin(&j, "meta");
        const char *m = sl_pvs_meta_text(p);
        while (*m) {
            const char *eol = strchr(m, '\n');
            size_t n = eol ? (size_t)(eol - m) : strlen(m);
            const char *eq = memchr(m, '=', n);
            if (eq) {
                char k[128], v[1100];
                snprintf(k, sizeof k, "%.*s", (int)(eq - m), m);
                snprintf(v, sizeof v, "%.*s", (int)(n - (size_t)(eq - m) - 1), eq + 1);
                cli_json_string(&j, k, v);
            }
            m += n + (eol ? 1 : 0);
        }
        cli_json_object_end(&j);
        cli_json_end(&j);
    } else {
        char b1[32], b2[32], b3[32];
        printf("%s: .slpvs %u.%u, %u cells (%u prisms, %u boxes, %u clusters, %.0f m^2), %u objects\n", file,
               in.version_major, in.version_minor, in.cell_count, cs.prisms, cs.boxes, cs.clusters, cs.area,
               in.object_count);
        printf("  visible per cell: min %u, mean %.1f, max %u; mean culled %.4f%%\n", in.min_visible, in.mean_visible,
               in.max_visible, 100.0 * in.mean_culled);
        printf("  %s on disk: sets %s compressed from %s in %u blocks of %u cells\n",
               cli_bytes(in.file_size, b1, sizeof b1), cli_bytes(in.data_bytes, b2, sizeof b2),
               cli_bytes(in.raw_bytes, b3, sizeof b3), in.block_count, in.block_cells);
        printf("  scene key %016llx (format %u%s)\n", (unsigned long long)in.scene_key, in.scene_key_version,
               in.scene_key_version < SL_PVS_SCENE_KEY_VERSION ? ", older than this build's: bake it again" : "");
        if (in.region_count)
            printf("  motion regions (where dynamic objects can be): %u nodes over %u regions, %.1f nodes marked "
                   "visible per cell on average; %s in memory once open\n",
                   in.region_count, rcount.leaves, in.mean_regions_visible, cli_bytes(region_bytes, b1, sizeof b1));
        else
            printf("  motion regions: none (with this file the pvs culler frustum-culls dynamic objects)\n");
        const char *m = sl_pvs_meta_text(p);
        while (*m) {
            const char *eol = strchr(m, '\n');
            size_t n = eol ? (size_t)(eol - m) : strlen(m);
            printf("  %.*s\n", (int)n, m);
            m += n + (eol ? 1 : 0);
        }
    }
    sl_pvs_destroy(p);
    return 0;
}

/* ---- query ---- */

static int run_query(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = "pvs query";
    const char *name, *val, *scene_path = NULL;
    float point[3];
    bool has_point = false, has_cell = false, ids = false;
    uint32_t cell = 0;
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_import_option(&a, name, val, &pvs_import) ||
            cli_common_option(&a, name, val, CLI_INPUT | CLI_MAP | CLI_JSON, &com))
            continue;
        if (!strcmp(name, "point")) {
            has_point = parse_floats(&a, name, cli_value(&a, name, val), point, 3);
        } else if (!strcmp(name, "cell")) {
            has_cell = cli_parse_u32(&a, name, cli_value(&a, name, val), &cell);
        } else if (!strcmp(name, "scene")) {
            scene_path = cli_value(&a, name, val);
        } else if (!strcmp(name, "ids")) {
            ids = true;
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage_query);
    if (parsed >= 0)
        return parsed;
    const char *file = com.input, *map = com.map;
    bool json = com.json;
    if (!file || has_point == has_cell) {
        cli_error(a.cmd, "%s (see sightline pvs query --help)",
                  !file ? "missing FILE.slpvs" : "give exactly one of --point X,Y,Z and --cell N");
        return 2;
    }
    sl_error err;
    sl_pvs p;
    if (sl_pvs_load(file, NULL, &p, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_viewcells cells = sl_pvs_cells(p);
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    uint32_t ncells = sl_viewcells_count(cells);
    if (has_cell && cell >= ncells) {
        /* SL_NONE too: it is no cell number, and would read as "no cell holds the point" */
        if (ncells)
            cli_error(a.cmd, "cell %u is out of range: %s has %u cells, numbered 0..%u", cell, file, ncells, ncells - 1);
        else
            cli_error(a.cmd, "cell %u is out of range: %s has no cells", cell, file);
        sl_pvs_destroy(p);
        return 1;
    }
    bool clusters = false;
    for (uint32_t i = 0; i < ncells && !clusters; i++)
        clusters = sl_viewcells_data(cells)[i].shape == SL_CELL_CLUSTER;
    if (has_point && clusters && !scene_path) {
        /* a cluster cell is a set of BSP leaves: only the map's tree tells which leaf holds a point */
        cli_error(a.cmd,
                  "%s holds Quake III cluster cells: locating a point needs the map's BSP tree, which the file does "
                  "not keep; give the scene it was baked for with --scene MAP.bsp (or --scene MAPS.pk3 --map NAME)",
                  file);
        sl_pvs_destroy(p);
        return 2;
    }
    sl_scene scene = NULL;
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&pvs_import, &io);
    if (scene_path && cli_open_scene(scene_path, map, &io, NULL, &scene, NULL, 0, &err) != SL_OK) {
        sl_pvs_destroy(p);
        return cli_fail(a.cmd, &err);
    }
    if (scene && (in.object_count != sl_scene_object_count(scene) || in.scene_key != sl_pvs_scene_key(scene))) {
        cli_error(a.cmd,
                  "%s was not baked for the scene %s%s%s (the file: %u objects, scene key %016llx; the scene: %u "
                  "objects, key %016llx): give the scene it was baked for, or bake it again",
                  file, scene_path, map ? " map " : "", map ? map : "", in.object_count,
                  (unsigned long long)in.scene_key, sl_scene_object_count(scene),
                  (unsigned long long)sl_pvs_scene_key(scene));
        sl_scene_destroy(scene);
        sl_pvs_destroy(p);
        return 1;
    }
    if (has_point)
        cell = sl_viewcells_locate(cells, scene, (sl_vec3){point[0], point[1], point[2]});
    int rc = 0;
    /* a point in no cell: the nearest one, and a non-zero exit */
    uint32_t nearest = SL_NONE;
    double nearest_dist = INFINITY;
    if (has_point && cell == SL_NONE) {
        nearest = sl_viewcells_nearest(cells, (sl_vec3){point[0], point[1], point[2]}, &nearest_dist);
        rc = 1;
    }
    uint32_t *set = malloc(((size_t)in.object_count + 1) * sizeof *set), n = 0;
    if (!set) {
        cli_error(a.cmd, "out of memory");
        rc = 1;
    } else if (cell != SL_NONE && cell >= sl_viewcells_count(cells)) {
        cli_error(a.cmd, "cell %u does not exist (%u cells)", cell, sl_viewcells_count(cells));
        rc = 1;
    } else if (cell != SL_NONE && sl_pvs_cell_set(p, cell, set, in.object_count, &n, &err) != SL_OK) {
        rc = cli_fail(a.cmd, &err);
    } else if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", file);
        if (cell == SL_NONE) {
            cli_json_key(&j, "cell"), fputs("null", stdout);
            if (nearest != SL_NONE) {
                cli_json_uint(&j, "nearest_cell", nearest);
                cli_json_double(&j, "nearest_distance", nearest_dist);
            }
        } else
            cli_json_uint(&j, "cell", cell);
        cli_json_uint(&j, "visible", n);
        cli_json_uint(&j, "objects", in.object_count);
        if (ids) {
            cli_json_array_begin(&j, "ids");
            for (uint32_t i = 0; i < n; i++)
                cli_json_uint(&j, NULL, set[i]);
            cli_json_array_end(&j);
        }
        if (in.region_count) {
            const uint8_t *row = cell != SL_NONE ? sl_pvs_region_row(p, cell) : NULL;
            region_counts rq = count_regions(p, row);
            cli_json_uint(&j, "regions", in.region_count);
            cli_json_uint(&j, "region_leaves", rq.leaves);
            if (row) {
                cli_json_uint(&j, "regions_marked", rq.marked);
                cli_json_uint(&j, "region_leaves_marked", rq.leaves_marked);
                if (ids) {
                    cli_json_array_begin(&j, "region_ids");
                    for (uint32_t k = 0; k < in.region_count; k++)
                        if (row[k >> 3] >> (k & 7) & 1u)
                            cli_json_uint(&j, NULL, k);
                    cli_json_array_end(&j);
                }
            }
        }
        cli_json_end(&j);
    } else if (cell == SL_NONE) {
        bool outside = scene && !sl_oracle_in_domain(scene, (sl_vec3){point[0], point[1], point[2]}, NULL);
        char near[200] = "";
        if (nearest != SL_NONE) {
            const sl_viewcell *c = &sl_viewcells_data(cells)[nearest];
            snprintf(near, sizeof near, "; the nearest is cell %u, %.2f m away (box %.2f,%.2f,%.2f .. %.2f,%.2f,%.2f)",
                     nearest, nearest_dist, (double)c->bounds.min.x, (double)c->bounds.min.y,
                     (double)c->bounds.min.z, (double)c->bounds.max.x, (double)c->bounds.max.y,
                     (double)c->bounds.max.z);
        }
        cli_error(a.cmd, "no view cell holds (%g, %g, %g)%s%s: a renderer falls back to view-frustum culling",
                  (double)point[0], (double)point[1], (double)point[2],
                  outside ? " (it lies in solid or void space of the map: outside the domain, docs/oracle.md)" : "",
                  near);
    } else {
        const sl_viewcell *c = &sl_viewcells_data(cells)[cell];
        printf("cell %u (%s, box %.2f,%.2f,%.2f .. %.2f,%.2f,%.2f): %u of %u objects visible\n", cell,
               c->shape == SL_CELL_PRISM ? "prism" : c->shape == SL_CELL_BOX ? "box" : "cluster",
               (double)c->bounds.min.x, (double)c->bounds.min.y, (double)c->bounds.min.z, (double)c->bounds.max.x,
               (double)c->bounds.max.y, (double)c->bounds.max.z, n, in.object_count);
        if (ids) {
            for (uint32_t i = 0; i < n; i++)
                printf("%s%u", i ? " " : "  ", set[i]);
            if (n)
                printf("\n");
        }
        const uint8_t *row = sl_pvs_region_row(p, cell);
        if (row) {
            region_counts rq = count_regions(p, row);
            printf("  motion regions: %u of %u nodes marked visible, %u of %u regions (a dynamic object is drawn "
                   "when the deepest node holding its box is marked)\n",
                   rq.marked, in.region_count, rq.leaves_marked, rq.leaves);
            if (ids) {
                uint32_t shown = 0;
                for (uint32_t k = 0; k < in.region_count; k++)
                    if (row[k >> 3] >> (k & 7) & 1u)
                        printf("%s%u", shown++ ? " " : "  nodes: ", k);
                if (shown)
                    printf("\n");
            }
        }
    }
    free(set);
    sl_scene_destroy(scene);
    sl_pvs_destroy(p);
    return rc;
}

/* ---- verify ---- */

static int cmp_u32(const void *x, const void *y)
{
    uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return (a > b) - (a < b);
}

/* The map's own PVS as an object set: objects of the leaves of every cluster visible from c. */
static uint32_t bsp_set(sl_scene scene, int32_t cluster, uint8_t *mark, uint32_t *out)
{
    sl_bsp_view bv;
    if (!sl_scene_bsp(scene, &bv))
        return 0;
    uint32_t no = sl_scene_object_count(scene), n = 0;
    memset(mark, 0, no);
    for (uint32_t l = 0; l < bv.leaf_count; l++) {
        int32_t c = bv.leaves[l].cluster;
        if (c < 0 || (uint32_t)c >= bv.cluster_count)
            continue;
        bool vis = !bv.pvs || bv.cluster_bytes == 0 ||
                   (bv.pvs[(size_t)cluster * bv.cluster_bytes + ((uint32_t)c >> 3)] >> (c & 7)) & 1;
        if (!vis)
            continue;
        for (uint32_t k = 0; k < bv.leaves[l].object_count; k++) {
            uint32_t id = bv.leaf_objects[bv.leaves[l].first_object + k];
            if (id < no && !mark[id]) {
                mark[id] = 1;
                out[n++] = id;
            }
        }
    }
    /* objects in no leaf (models, props) are always drawn by the map's renderer */
    uint8_t *in_leaf = mark + no;
    memset(in_leaf, 0, no);
    for (uint32_t k = 0; k < bv.leaf_object_count; k++)
        if (bv.leaf_objects[k] < no)
            in_leaf[bv.leaf_objects[k]] = 1;
    for (uint32_t id = 0; id < no; id++)
        if (!in_leaf[id] && !mark[id]) {
            mark[id] = 1;
            out[n++] = id;
        }
    qsort(out, n, sizeof *out, cmp_u32);
    return n;
}

static bool contains(const uint32_t *set, uint32_t n, uint32_t id)
{
    uint32_t lo = 0, hi = n;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (set[mid] < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && set[lo] == id;
}

static int run_verify(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = "pvs verify";
    const char *name, *val, *scene_path = NULL, *city = NULL;
    bool all = false;
    cli_common com = {0};
    uint32_t ncheck = 20, face = 256, samples = 24;
    float spacing = 1.0f;
    uint64_t seed = 1;
    while (cli_next(&a, &name, &val)) {
        if (cli_import_option(&a, name, val, &pvs_import) ||
            cli_common_option(&a, name, val, CLI_INPUT | CLI_MAP | CLI_JSON | CLI_QUIET, &com))
            continue;
        if (!strcmp(name, "scene")) {
            scene_path = cli_value(&a, name, val);
        } else if (!strcmp(name, "city")) {
            city = cli_value(&a, name, val);
        } else if (!strcmp(name, "cells")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &ncheck);
        } else if (!strcmp(name, "all")) {
            all = true;
        } else if (!strcmp(name, "seed")) {
            cli_parse_u64(&a, name, cli_value(&a, name, val), &seed);
        } else if (!strcmp(name, "face-size")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &face);
        } else if (!strcmp(name, "spacing")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &spacing);
        } else if (!strcmp(name, "samples")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &samples);
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage_verify);
    if (parsed >= 0)
        return parsed;
    const char *file = com.input, *map = com.map;
    bool json = com.json, quiet = com.quiet;
    if (!file || (scene_path && city)) {
        cli_error(a.cmd, "%s (see sightline pvs verify --help)", !file ? "missing FILE.slpvs" : "give --scene or --city, not both");
        return 2;
    }
    sl_error err;
    sl_pvs p;
    if (sl_pvs_load(file, NULL, &p, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    if (sl_pvs_verify(p, &err) != SL_OK) {
        sl_pvs_destroy(p);
        return cli_fail(a.cmd, &err);
    }
    sl_pvs_info in;
    sl_pvs_get_info(p, &in);
    if (!scene_path && !city) {
        if (json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            cli_json_string(&j, "file", file);
            cli_json_bool(&j, "valid", true);
            cli_json_uint(&j, "cells", in.cell_count);
            cli_json_end(&j);
        } else {
            printf("%s: ok, %u cells, every checksum and set checked\n", file, in.cell_count);
        }
        sl_pvs_destroy(p);
        return 0;
    }
    sl_scene scene;
    if (load_scene(scene_path, map, city, seed, &scene, &err) != SL_OK) {
        sl_pvs_destroy(p);
        return cli_fail(a.cmd, &err);
    }
    int rc = 0;
    if (sl_pvs_check_scene(p, scene, &err) != SL_OK) {
        sl_scene_destroy(scene);
        sl_pvs_destroy(p);
        return cli_fail(a.cmd, &err);
    }
    sl_viewcells cells = sl_pvs_cells(p);
    uint32_t nc = sl_viewcells_count(cells), no = in.object_count;
    if (all || ncheck > nc)
        ncheck = nc;
    /* a deterministic random choice of cells: a partial Fisher-Yates shuffle of 0..nc-1 */
    uint32_t *order = malloc(((size_t)nc + 1) * sizeof *order);
    uint32_t *set = malloc(((size_t)no + 1) * sizeof *set);
    uint32_t *bset = malloc(((size_t)no + 1) * sizeof *bset);
    uint8_t *mark = malloc(2 * (size_t)no + 1);
    if (!order || !set || !bset || !mark) {
        free(order), free(set), free(bset), free(mark);
        sl_scene_destroy(scene);
        sl_pvs_destroy(p);
        cli_error(a.cmd, "out of memory");
        return 1;
    }
    for (uint32_t i = 0; i < nc; i++)
        order[i] = i;
    uint64_t r = seed * 0x9e3779b97f4a7c15ull + 1;
    for (uint32_t i = 0; i < ncheck; i++) {
        r ^= r << 13, r ^= r >> 7, r ^= r << 17;
        uint32_t j = i + (uint32_t)(r % (nc - i));
        uint32_t t = order[i];
        order[i] = order[j];
        order[j] = t;
    }
    sl_region_oracle_options oo;
    memset(&oo, 0, sizeof oo);
    oo.face_size = face;
    oo.edge_spacing = spacing;
    oo.face_samples = samples;
    oo.interior_samples = samples;
    oo.seed = seed;
    sl_region_oracle ro;
    if (sl_region_oracle_create(scene, &oo, NULL, &ro, &err) != SL_OK) {
        rc = cli_fail(a.cmd, &err);
        ncheck = 0;
    }
    bool bsp = sl_viewcells_data(cells)[0].shape == SL_CELL_CLUSTER;
    uint64_t misses = 0, bsp_misses = 0, oracle_total = 0, set_total = 0, bsp_total = 0, added_total = 0;
    uint32_t checked = 0, cells_with_miss = 0;
    /* A Quake III map compiled with "_farplanedist" (fog maps) has a PVS that drops clusters beyond
     * that distance by design (q3map2's vis compares portal distances, less their radii, with it):
     * a miss whose object lies farther than that from the whole cell is told apart, and does not
     * fail a file that holds the map's own PVS. */
    const char *far_meta = bsp ? sl_scene_meta(scene, "q3.farplanedist") : NULL;
    double far_plane = far_meta ? strtod(far_meta, NULL) : 0;
    const char *file_method = sl_pvs_meta(p, "method");
    bool file_is_map = file_method && !strcmp(file_method, "mappvs");
    uint64_t misses_far = 0, bsp_misses_far = 0;
    uint32_t unsampled = 0, outside = 0;
    double over_sum = 0;
    cli_progress_state ps;
    sl_progress prog = cli_progress(&ps, quiet || json);
    /* misses kept for the JSON report (the first 10000) */
    typedef struct miss {
        uint32_t cell, object, pixels;
        bool in_pvs, in_map, beyond_far;
    } miss;
    size_t miss_cap = 10000, miss_n = 0;
    miss *list = json ? malloc(miss_cap * sizeof *list) : NULL;
    for (uint32_t i = 0; i < ncheck; i++) {
        uint32_t c = order[i];
        uint32_t n, npts = 0;
        const sl_vec3 *pts;
        sl_region_visibility v;
        if (sl_region_oracle_points(ro, cells, c, &pts, &npts, &err) == SL_OK && npts == 0) {
            /* a cluster whose leaves hold no point the BSP puts back in it (a leaf without volume):
             * no viewer can stand there, and there is nothing to sample */
            unsampled++;
            continue;
        }
        if (sl_pvs_cell_set(p, c, set, no, &n, &err) != SL_OK || sl_region_oracle_cell(ro, cells, c, &v, &err) != SL_OK) {
            cli_progress_done(&ps);
            rc = cli_fail(a.cmd, &err);
            break;
        }
        if (v.out_of_domain) {
            /* every sample in solid or void space: outside the domain, nothing to judge (docs/oracle.md) */
            outside++;
            continue;
        }
        uint32_t nb = bsp ? bsp_set(scene, sl_viewcells_data(cells)[c].cluster, mark, bset) : 0;
        uint32_t cell_miss = 0;
        for (uint32_t k = 0; k < v.visible_count; k++) {
            uint32_t id = v.visible[k];
            bool in_set = contains(set, n, id);
            bool in_bsp = !bsp || contains(bset, nb, id);
            bool beyond = false;
            if ((!in_set || !in_bsp) && far_plane > 0) {
                sl_aabb ob = sl_scene_object_bounds(scene, id);
                beyond = cli_box_gap(&sl_viewcells_data(cells)[c].bounds, &ob) > far_plane;
            }
            if (!in_set) {
                misses++;
                misses_far += beyond && file_is_map;
                cell_miss += !(beyond && file_is_map);
            }
            if (!in_bsp) {
                bsp_misses++;
                bsp_misses_far += beyond;
            }
            if (!in_set || !in_bsp) {
                if (json) {
                    if (list && miss_n < miss_cap)
                        list[miss_n++] = (miss){c, id, v.max_pixels[k], in_set, in_bsp, beyond};
                } else {
                    fprintf(stderr, "MISS: cell %u, object %u (%u pixels at most): %s%s%s\n", c, id, v.max_pixels[k],
                            in_set ? "" : "not in the PVS", !in_bsp ? (in_set ? "not in the map's PVS" : ", nor in the map's PVS") : "",
                            beyond ? " (farther than the map's vis far plane)" : "");
                }
            }
        }
        cells_with_miss += cell_miss > 0;
        oracle_total += v.visible_count;
        set_total += n;
        bsp_total += nb;
        added_total += v.added_last_tenth;
        over_sum += (double)n / (v.visible_count ? v.visible_count : 1);
        checked++;
        if (prog.fn)
            prog.fn(prog.user, "oracle cells", checked, ncheck);
    }
    cli_progress_done(&ps);
    sl_region_oracle_destroy(ro);
    if (rc == 0 && misses > misses_far)
        rc = 1;
    double over = checked ? over_sum / checked : 0;
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", file);
        cli_json_bool(&j, "valid", true);
        cli_json_uint(&j, "cells", nc);
        cli_json_uint(&j, "checked", checked);
        cli_json_uint(&j, "unsampled", unsampled);
        cli_json_uint(&j, "out_of_domain", outside);
        cli_json_uint(&j, "misses", misses);
        cli_json_uint(&j, "cells_with_misses", cells_with_miss);
        cli_json_double(&j, "oracle_visible_mean", checked ? (double)oracle_total / checked : 0);
        cli_json_double(&j, "pvs_visible_mean", checked ? (double)set_total / checked : 0);
        cli_json_double(&j, "overestimation_mean", over);
        cli_json_double(&j, "oracle_added_last_tenth_mean", checked ? (double)added_total / checked : 0);
        if (bsp) {
            cli_json_double(&j, "map_pvs_visible_mean", checked ? (double)bsp_total / checked : 0);
            cli_json_uint(&j, "map_pvs_misses", bsp_misses);
            cli_json_double(&j, "map_far_plane", far_plane);
            cli_json_uint(&j, "map_pvs_misses_beyond_far_plane", bsp_misses_far);
            cli_json_uint(&j, "misses_beyond_far_plane", misses_far);
        }
        cli_json_array_begin(&j, "missed");
        for (size_t m = 0; m < miss_n; m++) {
            cli_json_object_begin(&j, NULL);
            cli_json_uint(&j, "cell", list[m].cell);
            cli_json_uint(&j, "object", list[m].object);
            cli_json_uint(&j, "pixels", list[m].pixels);
            cli_json_bool(&j, "in_pvs", list[m].in_pvs);
            cli_json_bool(&j, "in_map_pvs", list[m].in_map);
            cli_json_bool(&j, "beyond_far_plane", list[m].beyond_far);
            cli_json_object_end(&j);
        }
        cli_json_array_end(&j);
        cli_json_end(&j);
    } else {
        printf("%s: checksums and sets ok; %u of %u cells held to the region oracle: %llu missed objects in %u cells",
               file, checked, nc, (unsigned long long)(misses - misses_far), cells_with_miss);
        if (misses_far)
            printf(" (and %llu beyond the map's vis far plane)", (unsigned long long)misses_far);
        printf("\n");
        if (unsampled)
            printf("  %u chosen cells were skipped: no sample point lies in them (BSP leaves without volume)\n",
                   unsampled);
        if (outside)
            printf("  %u chosen cells were skipped: outside the domain (every sample in a BSP leaf without a "
                   "cluster, docs/oracle.md)\n",
                   outside);
        printf("  mean per cell: oracle %.1f, PVS %.1f objects (over-estimation %.2fx); oracle convergence: %.2f "
               "objects first seen in the last 10%% of samples\n",
               checked ? (double)oracle_total / checked : 0, checked ? (double)set_total / checked : 0, over,
               checked ? (double)added_total / checked : 0);
        if (bsp)
            printf("  map's own cluster PVS: %.1f objects per cell (%.2fx the baked PVS), %llu objects the oracle sees "
                   "missing from it\n",
                   checked ? (double)bsp_total / checked : 0, set_total ? (double)bsp_total / set_total : 0,
                   (unsigned long long)bsp_misses);
        if (far_plane > 0)
            printf("  the map's vis far plane (_farplanedist) is %.1f m: %llu of the map PVS's misses lie beyond it "
                   "(dropped by design)%s\n",
                   far_plane, (unsigned long long)bsp_misses_far,
                   file_is_map ? "; they do not fail this mappvs file" : "");
    }
    free(list);
    free(order), free(set), free(bset), free(mark);
    sl_scene_destroy(scene);
    sl_pvs_destroy(p);
    return rc;
}

/* ---- update ---- */

static void usage_update(FILE *out)
{
    fprintf(out,
            "usage: sightline pvs update FILE.slpvs --old-scene OLD --scene EDITED [-o OUT.slpvs] [options]\n\n"
            "FILE.slpvs was baked for OLD; EDITED is OLD with objects and building footprints added, removed\n"
            "or moved. Re-bake only the view cells the edit can affect, with the file's method and options,\n"
            "and copy the other cells' sets: OUT.slpvs (default: FILE.slpvs, replaced) is byte-identical to\n"
            "`sightline pvs build EDITED` with that method, those options and the same cell options.\n"
            "A cell is re-baked when its old set holds a removed or moved object (or one touching the\n"
            "edit, for methods that join touching footprints), or when the edited zone's boxes cannot be\n"
            "shown hidden from the cell by the unchanged occluders alone (docs/pvs.md, \"Updating a bake\").\n\n"
            "Refused (exit 1, nothing written): a FILE not baked for OLD; a method other than adjustable\n"
            "and sample; an edit that changes the view cells (the streets, or footprints over them:\n"
            "every set may change, so bake EDITED with pvs build), the terrain or the streets. The .slpvs\n"
            "keeps no per-object record, so the old scene must be given.\n\n"
            "options:\n"
            "  --old-scene OLD   the scene FILE.slpvs was baked for (checked against its scene key)\n"
            "  --scene EDITED    the edited scene (a .slscene or city:PRESET[:SEED] as for build)\n"
            "  --cells KIND      streets (default) or grid: the view cells of EDITED, as pvs build makes them\n"
            "  --cell-size M, --eye-min H, --eye-max H   as for pvs build (they must be the bake's)\n"
            "  --along PATH, --radius M   for a bake made with --along: the same path and radius (the\n"
            "                    cells near the path's cameras; they must be the bake's)\n"
            "  --threads N       OpenMP threads (default: all cores)\n"
            "  --checkpoint F    journal of the re-baked cells (default OUT.slpvs.ckpt)\n"
            "  --json            machine-readable summary on stdout\n"
            "  --quiet           no progress bar\n"
            "  --help            this text\n\n"
            "example:\n"
            "  sightline gen edit city.slscene --region 0,0,100,100 --seed 3 -o edited.slscene\n"
            "  sightline pvs update city.slpvs --old-scene city.slscene --scene edited.slscene -o edited.slpvs\n");
}

static int run_update(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = "pvs update";
    const char *name, *val, *old_path = NULL, *new_path = NULL, *cells_kind = "streets", *along = NULL;
    float radius = 2.0f;
    bool has_radius = false;
    cli_common com = {0};
    sl_viewcell_options vo;
    memset(&vo, 0, sizeof vo);
    sl_pvs_update_options uo;
    memset(&uo, 0, sizeof uo);
    while (cli_next(&a, &name, &val)) {
        if (cli_import_option(&a, name, val, &pvs_import) ||
            cli_common_option(&a, name, val, CLI_INPUT | CLI_OUTPUT | CLI_JSON | CLI_QUIET, &com))
            continue;
        if (!strcmp(name, "old-scene"))
            old_path = cli_value(&a, name, val);
        else if (!strcmp(name, "scene"))
            new_path = cli_value(&a, name, val);
        else if (!strcmp(name, "cells"))
            cells_kind = cli_value(&a, name, val);
        else if (!strcmp(name, "cell-size"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &vo.max_edge);
        else if (!strcmp(name, "eye-min"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &vo.eye_min);
        else if (!strcmp(name, "eye-max"))
            cli_parse_float(&a, name, cli_value(&a, name, val), &vo.eye_max);
        else if (!strcmp(name, "threads"))
            cli_parse_threads(&a, name, cli_value(&a, name, val), true, &uo.threads);
        else if (!strcmp(name, "checkpoint"))
            uo.checkpoint = cli_value(&a, name, val);
        else if (!strcmp(name, "along"))
            along = cli_value(&a, name, val);
        else if (!strcmp(name, "radius")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &radius);
            has_radius = true;
        } else
            cli_unknown(&a, name);
    }
    int parsed = cli_parse_done(&a, &com, usage_update);
    if (parsed >= 0)
        return parsed;
    const char *file = com.input, *output = com.output ? com.output : com.input;
    if (!file || !old_path || !new_path) {
        cli_error(a.cmd, "%s (see sightline pvs update --help)",
                  !file ? "missing FILE.slpvs" : !old_path ? "missing --old-scene OLD" : "missing --scene EDITED");
        return 2;
    }
    if (cells_kind && strcmp(cells_kind, "streets") && strcmp(cells_kind, "grid")) {
        cli_error(a.cmd, "--cells: '%s' is not streets or grid (an update handles 2.5D street scenes)", cells_kind);
        return 2;
    }
    if (has_radius && !along) {
        cli_error(a.cmd, "--radius needs --along PATH");
        return 2;
    }
    if (!(radius >= 0) || !isfinite(radius)) {
        cli_error(a.cmd, "--radius must be a finite distance >= 0");
        return 2;
    }
    const char *inputs[] = {old_path, new_path, along};
    if (!cli_output_not_input(a.cmd, output, inputs, along ? 3 : 2))
        return 2;
    sl_error err;
    sl_pvs old = NULL;
    if (sl_pvs_load(file, NULL, &old, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_scene olds = NULL, news = NULL;
    sl_viewcells cells = NULL;
    sl_status st = load_scene(old_path, NULL, NULL, 1, &olds, &err);
    if (st != SL_OK)
        tool_error_prefix(&err, "--old-scene");
    if (st == SL_OK && (st = load_scene(new_path, NULL, NULL, 1, &news, &err)) != SL_OK)
        tool_error_prefix(&err, "--scene");
    if (st == SL_OK)
        st = !strcmp(cells_kind, "grid") ? sl_viewcells_grid(news, &vo, &cells, &err)
                                         : sl_viewcells_from_streets(news, &vo, &cells, &err);
    uint32_t far_cameras = 0, path_cameras = 0;
    if (st == SL_OK && along) /* a bake made with --along: the same cells along the same path */
        st = keep_cells_along(&cells, along, radius, &far_cameras, &path_cameras, &err);
    if (st == SL_OK && along)
        warn_far_cameras(a.cmd, far_cameras, path_cameras, along, radius);
    cli_progress_state ps;
    sl_pvs_update_stats us;
    memset(&us, 0, sizeof us);
    if (st == SL_OK) {
        uo.progress = com.json && !com.quiet ? cli_progress_json(&ps) : cli_progress(&ps, com.quiet || com.json);
        st = sl_pvs_update(old, olds, news, cells, output, &uo, &us, &err);
        cli_progress_done(&ps);
    }
    sl_viewcells_destroy(cells);
    sl_scene_destroy(olds);
    sl_scene_destroy(news);
    sl_pvs_destroy(old);
    if (st != SL_OK)
        return cli_fail(a.cmd, &err);
    if (com.json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", output);
        cli_json_string(&j, "method", us.method);
        cli_json_string(&j, "options", us.options);
        cli_json_uint(&j, "cells", us.cells);
        cli_json_uint(&j, "cells_affected", us.cells_affected);
        cli_json_uint(&j, "cells_by_set", us.cells_by_set);
        cli_json_uint(&j, "cells_by_probe", us.cells_by_probe);
        cli_json_uint(&j, "cells_by_base", us.cells_by_base);
        cli_json_uint(&j, "objects_removed", us.objects_removed);
        cli_json_uint(&j, "objects_added", us.objects_added);
        cli_json_uint(&j, "footprints_changed", us.footprints_changed);
        cli_json_uint(&j, "zone_footprints", us.zone_footprints);
        cli_json_bool(&j, "zone_closed", us.zone_closed);
        cli_json_double(&j, "seconds", us.seconds);
        cli_json_double(&j, "cpu_seconds", us.cpu_seconds);
        cli_json_double(&j, "probe_seconds", us.probe_seconds);
        cli_json_double(&j, "bake_seconds", us.bake_seconds);
        cli_json_uint(&j, "regions", us.regions);
        cli_json_uint(&j, "region_rows_copied", us.region_rows_copied);
        cli_json_end(&j);
    } else {
        printf("%s: %u of %u cells re-baked (%.2f%%), method %s (%s)\n", output, us.cells_affected, us.cells,
               us.cells ? 100.0 * us.cells_affected / us.cells : 0.0, us.method, us.options);
        printf("  edit: %u objects without a match in the edited scene (removed or moved), %u new (added or "
               "moved), %u footprints changed, zone of %u footprints\n",
               us.objects_removed, us.objects_added, us.footprints_changed, us.zone_footprints);
        printf("  re-baked because the old set held a changed object: %u; because the zone may be seen: %u\n",
               us.cells_by_set, us.cells_by_probe);
        if (us.cells_by_base)
            printf("  re-baked because the edit changed the highest footprint base below the cell's eyes: %u\n",
                   us.cells_by_base);
        printf("  %.2f s (%.2f s CPU): probe %.2f s, method preparation %.2f s, re-bake %.2f s\n", us.seconds,
               us.cpu_seconds, us.probe_seconds, us.prepare_seconds, us.bake_seconds);
        if (us.regions)
            printf("  motion regions: %u nodes; the marks of %u kept cells copied, the others marked again\n", us.regions,
                   us.region_rows_copied);
    }
    return 0;
}

int sl_cmd_pvs(int argc, char **argv)
{
    static const char *const actions[] = {"build", "info", "query", "verify", "update"};
    static int (*const run[])(int, char **) = {run_build, run_info, run_query, run_verify, run_update};
    int status, k = cli_action(argc, argv, "pvs", usage_main, actions, (int)TOOL_COUNTOF(actions), &status);
    return k < 0 ? status : run[k](argc - 1, argv + 1);
}

/* `sightline bench`: culling methods x scenes x camera paths, every frame judged by the exact point
 * oracle. Writes per-frame CSV/JSON, a Markdown summary, SVG plots and top-down visibility maps
 * (library side: include/sightline/bench.h; formats: docs/bench.md), prints the summary table,
 * and fails loudly when a conservative method drops a visible object. */
#include "cli.h"
#include "pvs_cli.h"

#include "tool.h"
#include "sightline/bench.h"
#include "sightline/import.h"
#include "sightline/path.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define DEG (M_PI / 180.0)
#define MAX_SCENES 16
#define MAX_OPTS 64

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline bench SCENE... (--walk N | --path FILE | --random street|flyover\n"
            "                               | --view-matrix M --proj-matrix M [--clip-depth D]) [options]\n\n"
            "Run culling methods over scenes and camera views against the exact point oracle. For every\n"
            "frame the oracle renders once (shared by all methods), then each method culls the same\n"
            "camera; its time, what it keeps and draws, and its misses against the oracle are recorded.\n\n"
            "SCENE is city:tiny|small|vienna[:SEED] (generated on the fly), or a file: .slscene, a Quake\n"
            "III .bsp or .pk3 (with --map), or any format assimp reads.\n\n"
            "views (one of):\n"
            "  --walk N             a street-level walk of N frames (sl_path_generate walk; --fps, --seed)\n"
            "  --path FILE          a path file (docs/paths.md); --frames A:B picks frames A..B-1\n"
            "  --random KIND        random street or flyover viewpoints (--count N, --seed S)\n"
            "  --count N            random viewpoints (default 100)\n"
            "  --seed S             seed of the walk or the random views (default 1)\n"
            "  --altitude A         flyover views: height above the scene's lowest point in metres\n"
            "                       (default from the scene's size, as path gen)\n"
            "  --fps F              walk frames per second (default 30; 1.4 m/s, so 30 fps = 4.7 cm a frame)\n"
            "  --frames A:B         with --path: frames A to B-1 (A:, :B and A also work)\n"
            "  --view-matrix M --proj-matrix M [--clip-depth gl|zero-one|reversed]\n"
            "                       one frame from an engine's column-major world-to-eye and eye-to-clip\n"
            "                       matrices (16 comma-separated numbers each; as `sightline render`):\n"
            "                       off-axis, left-handed, x/y-flipped, reversed-z, infinite far\n\n"
            "methods:\n"
            "  --methods LIST       comma-separated NAME[:key=value[:key=value...]] (options of a method\n"
            "                       separated by colons: hzb:res=culling,vfc; the same grammar in\n"
            "                       render, view and pvs build --method; default: every registered method that\n"
            "                       runs with its default options, and pvs; one that needs an option is\n"
            "                       reported as not run unless given --method-options; `sightline\n"
            "                       methods` lists them all)\n"
            "                       pvs without file=PATH: the bench first bakes, per scene, the PVS of\n"
            "                       the street cells within %g m of the cameras of the frames it runs\n"
            "                       (with --path, only those of --frames A:B; like `sightline pvs build\n"
            "                       --along PATH --radius %g`, method %s) into OUT/LABEL.slpvs, names\n"
            "                       the file and its number of cells on stderr (not with --quiet or\n"
            "                       --json) and runs pvs on it; where the eye is in none of the cells,\n"
            "                       pvs culls by the frustum. A scene without streets, views near no\n"
            "                       cell (--random flyover) or an OUT holding a comma or space: pvs is\n"
            "                       reported as not run (an error when --methods names it)\n"
            "  --method-options NAME:key=value,...   options for one method (repeatable)\n"
            "  --repeat R           cull calls per frame and method; the median time is kept (default 1)\n"
            "  --sets csv|json      also write every frame's sets (the oracle's and each method's, ids\n"
            "                       with the objects' names) to OUT/sets.csv or OUT/sets.json\n"
            "  --max-overestimation X  the recommendation's tightness bound: the fastest conservative\n"
            "                       method passing at most X times the exact visible set (default 2)\n"
            "  --max-ms T           its time bound: the tightest method culling in at most T ms median\n"
            "                       (default 2)\n\n",
            (double)CLI_PVS_ALONG_RADIUS, (double)CLI_PVS_ALONG_RADIUS, CLI_PVS_ALONG_METHOD);
    /* two calls: one string literal would pass the 4095 characters C11 compilers must support */
    fputs("rendering:\n"
          "  --width W --height H viewport of every camera and oracle resolution (default 1024x768,\n"
          "                       replacing a path file's)\n"
          "  --threads T          oracle threads (default 2); methods always run on one thread\n"
          "  --map NAME           map inside a .pk3\n"
          CLI_ALLOW_EXTERNAL_HELP "\n"
          "output:\n"
          "  --out DIR            output folder (default bench-out): frames.csv, frames.json,\n"
          "                       summary.md, summary.json, and per scene LABEL-cull-time.svg,\n"
          "                       LABEL-triangles.svg, LABEL-missed-pixels.svg, LABEL-map-METHOD.png;\n"
          "                       moved in only when all are written (a failed run changes nothing),\n"
          "                       other files in DIR are left alone\n"
          "  --map-eye X,Y,Z      top-down maps of visibility from this point in all directions\n"
          "                       (default: from the first frame's camera)\n"
          "  --map-size N         map pixels along its longer side (default 1024)\n"
          "  --no-plots           no plots and no maps\n"
          "  --json               print the summary as JSON instead of the table\n"
          "  --strict             exit 1 when a conservative method misses a visible object (default)\n"
          "  --no-strict          report such misses loudly but exit 0\n"
          "  --allow-empty        accept a run where the oracle sees nothing in most frames (else a\n"
          "                       warning and exit status 1: such views measure nothing)\n"
          "  --quiet              no progress bar (nor the lines about the PVS bake)\n"
          "  --help               this text\n\n"
          "A conservative method that drops a visible object prints a CONSERVATIVENESS VIOLATION line\n"
          "naming the scene, frame, method and objects, and the command exits 1 (unless --no-strict).\n"
          "A frame whose eye lies in solid or void space of a map (a BSP leaf without a cluster) is\n"
          "outside the domain: it is counted and skipped, no method is judged on it (docs/oracle.md).\n"
          "Exit status: 0 ok, 1 failure or violation, 2 usage error.\n\n"
          "examples:\n"
          "  sightline bench city:small --walk 300\n"
          "  sightline bench city:vienna:1 --walk 600 --fps 10 --methods vfc --out vienna-bench\n"
          "  sightline bench city.slscene --random street --count 200 --seed 3 --repeat 5\n"
          "  sightline bench city.slscene --path walk.txt --frames 0:100 --method-options vfc:coherence=off\n"
          "  sightline bench city:tiny --walk 60 --methods vfc,pvs\n"
          "  sightline bench city:small --walk 60 --methods pvs --method-options pvs:file=city.slpvs\n",
          out);
}

typedef struct bench_args {
    const char *scenes[MAX_SCENES];
    uint32_t scene_count;
    const char *path_file, *random_kind, *methods, *out_dir, *map, *frames, *sets;
    const char *view_text, *proj_text, *depth_text; /* --view-matrix, --proj-matrix, --clip-depth */
    sl_view view;               /* made of them (at --width x --height) */
    const char *mopt_name[MAX_OPTS], *mopt_value[MAX_OPTS];
    uint32_t mopt_count;
    uint32_t walk, count, width, height, threads, repeat, map_size;
    uint64_t seed;
    float fps, altitude, max_over, max_ms;
    bool has_walk, has_eye, no_plots, json, quiet, strict, allow_empty;
    sl_vec3 eye;
    cli_import import;          /* --allow-external */
} bench_args;

/* "x,y,z" into three finite floats. */
static bool parse_vec3(const char *text, sl_vec3 *out)
{
    float v[3];
    if (!sl_parse_floats(text, v, 3)) /* src/core/text_parse.c */
        return false;
    *out = (sl_vec3){v[0], v[1], v[2]};
    return true;
}

/* --frames into a first frame and a count (UINT32_MAX: to the end); sl_parse_range reads it. */
static bool parse_frames(const char *text, uint32_t *first, uint32_t *count)
{
    uint32_t end;
    if (!sl_parse_range(text, first, &end)) /* src/core/text_parse.c */
        return false;
    *count = end == UINT32_MAX ? UINT32_MAX : end - *first;
    return true;
}

static int parse(int argc, char **argv, bench_args *g)
{
    memset(g, 0, sizeof *g);
    g->count = 100;
    g->seed = 1;
    g->width = 1024;
    g->height = 768;
    g->threads = 2;
    g->repeat = 1;
    g->fps = 30;
    g->strict = true;
    g->out_dir = "bench-out";
    cli_args a;
    cli_args_init(&a, argc, argv);
    const char *name, *val;
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_MAP | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!name) {
            if (g->scene_count == MAX_SCENES) {
                cli_error(argv[0], "at most %d scenes", MAX_SCENES);
                return 2;
            }
            g->scenes[g->scene_count++] = val;
        } else if (!strcmp(name, "walk")) {
            g->has_walk = cli_parse_u32(&a, name, cli_value(&a, name, val), &g->walk);
        } else if (!strcmp(name, "path")) {
            g->path_file = cli_value(&a, name, val);
        } else if (!strcmp(name, "view-matrix")) {
            g->view_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "proj-matrix")) {
            g->proj_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "clip-depth")) {
            g->depth_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "random")) {
            g->random_kind = cli_value(&a, name, val);
        } else if (!strcmp(name, "count")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &g->count);
        } else if (!strcmp(name, "seed")) {
            cli_parse_u64(&a, name, cli_value(&a, name, val), &g->seed);
        } else if (!strcmp(name, "fps")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &g->fps);
        } else if (!strcmp(name, "frames")) {
            g->frames = cli_value(&a, name, val);
        } else if (!strcmp(name, "methods")) {
            g->methods = cli_value(&a, name, val);
        } else if (!strcmp(name, "method-options")) {
            const char *v = cli_value(&a, name, val);
            const char *colon = v ? strchr(v, ':') : NULL;
            if (v && (!colon || colon == v)) {
                cli_error(argv[0], "--method-options '%s': expected NAME:key=value,...", v);
                return 2;
            }
            if (v && g->mopt_count == MAX_OPTS) {
                cli_error(argv[0], "too many --method-options");
                return 2;
            }
            if (v) {
                g->mopt_name[g->mopt_count] = v;
                g->mopt_value[g->mopt_count++] = colon + 1;
            }
        } else if (!strcmp(name, "altitude")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &g->altitude);
        } else if (!strcmp(name, "max-overestimation")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &g->max_over);
        } else if (!strcmp(name, "max-ms")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &g->max_ms);
        } else if (!strcmp(name, "sets")) {
            g->sets = cli_value(&a, name, val);
        } else if (!strcmp(name, "allow-empty")) {
            g->allow_empty = true;
        } else if (!strcmp(name, "repeat")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &g->repeat);
        } else if (!strcmp(name, "width")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &g->width);
        } else if (!strcmp(name, "height")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &g->height);
        } else if (!strcmp(name, "threads")) {
            cli_parse_threads(&a, name, cli_value(&a, name, val), false, &g->threads);
        } else if (!strcmp(name, "out")) {
            g->out_dir = cli_value(&a, name, val);
        } else if (!strcmp(name, "map-eye")) {
            const char *v = cli_value(&a, name, val);
            if (v && !parse_vec3(v, &g->eye)) {
                cli_error(argv[0], "--map-eye '%s': expected X,Y,Z (three finite numbers)", v);
                return 2;
            }
            g->has_eye = true;
        } else if (!strcmp(name, "map-size")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &g->map_size);
        } else if (!strcmp(name, "no-plots")) {
            g->no_plots = true;
        } else if (!strcmp(name, "strict")) {
            g->strict = true;
        } else if (!strcmp(name, "no-strict")) {
            g->strict = false;
        } else if (!cli_import_option(&a, name, val, &g->import)) {
            cli_unknown(&a, name);
        }
    }
    if (com.help) {
        usage(stdout);
        return -1;
    }
    if (a.error) {
        if (a.unknown[0])
            cli_suggest_option(a.cmd, a.unknown, usage);
        return 2;
    }
    g->map = com.map;
    g->json = com.json;
    g->quiet = com.quiet;
    const char *cmd = argv[0];
    bool matrices = g->view_text || g->proj_text;
    int kinds = (g->has_walk ? 1 : 0) + (g->path_file ? 1 : 0) + (g->random_kind ? 1 : 0) + (matrices ? 1 : 0);
    if (!g->scene_count) {
        cli_error(cmd, "missing SCENE (a file or city:tiny|small|vienna[:SEED]; see --help)");
        return 2;
    }
    if (kinds != 1) {
        cli_error(cmd, kinds ? "give only one of --walk, --path, --random and --view-matrix/--proj-matrix"
                             : "missing views: --walk N, --path FILE or --random street|flyover");
        return 2;
    }
    if (g->depth_text && !matrices) {
        cli_error(cmd, "--clip-depth applies to --view-matrix and --proj-matrix only");
        return 2;
    }
    if (g->random_kind && strcmp(g->random_kind, "street") && strcmp(g->random_kind, "flyover")) {
        cli_error(cmd, "--random '%s' is not street or flyover", g->random_kind);
        return 2;
    }
    if ((g->has_walk && g->walk == 0) || (g->random_kind && g->count == 0)) {
        cli_error(cmd, "no frames to run (--walk/--count must be at least 1)");
        return 2;
    }
    if (g->frames && !g->path_file) {
        cli_error(cmd, "--frames applies to --path only");
        return 2;
    }
    if (!g->width || !g->height || g->width > 16384 || g->height > 16384) {
        cli_error(cmd, "--width/--height must be 1..16384");
        return 2;
    }
    if (g->sets && strcmp(g->sets, "csv") && strcmp(g->sets, "json")) {
        cli_error(cmd, "--sets '%s': expected csv or json", g->sets);
        return 2;
    }
    if (g->altitude < 0 || g->altitude > 1e6f) {
        cli_error(cmd, "--altitude must be 0..1e6 m (0: the default, from the scene's size)");
        return 2;
    }
    if (g->max_over < 0 || g->max_ms < 0 || (g->max_over > 0 && g->max_over < 1)) {
        cli_error(cmd, "--max-overestimation must be at least 1 and --max-ms positive");
        return 2;
    }
    if (g->repeat < 1 || g->repeat > 1000) {
        cli_error(cmd, "--repeat must be 1..1000");
        return 2;
    }
    if (g->map_size && (g->map_size < 16 || g->map_size > 8192)) {
        cli_error(cmd, "--map-size must be 16..8192");
        return 2;
    }
    if (!(g->fps >= 0.001f && g->fps <= 1000)) {
        cli_error(cmd, "--fps must be in 0.001..1000");
        return 2;
    }
    if (matrices) {
        float vm[16], pm[16];
        sl_clip_depth depth = SL_CLIP_DEPTH_GL;
        sl_error verr;
        if (!g->view_text || !g->proj_text) {
            cli_error(cmd, "--view-matrix and --proj-matrix go together");
            return 2;
        }
        if (g->depth_text && !sl_clip_depth_parse(g->depth_text, &depth)) {
            cli_error(cmd, "--clip-depth '%s': expected gl, zero-one or reversed", g->depth_text);
            return 2;
        }
        bool vok = sl_parse_floats(g->view_text, vm, 16);
        if (!vok || !sl_parse_floats(g->proj_text, pm, 16)) {
            cli_error(cmd, "--%s '%s': expected 16 comma-separated finite numbers (column-major)",
                      vok ? "proj-matrix" : "view-matrix", vok ? g->proj_text : g->view_text);
            return 2;
        }
        if (sl_view_from_matrices(vm, pm, depth, g->width, g->height, &g->view, &verr) != SL_OK) {
            cli_error(cmd, "%s", verr.message);
            return 2;
        }
    }
    return 0;
}

/* The --method-options text given for a method, or NULL. */
static const char *options_for(const bench_args *g, const char *name)
{
    for (uint32_t i = 0; i < g->mopt_count; i++) {
        size_t len = (size_t)(g->mopt_value[i] - 1 - g->mopt_name[i]);
        if (strlen(name) == len && !strncmp(name, g->mopt_name[i], len))
            return g->mopt_value[i];
    }
    return NULL;
}

/* Whether the bench bakes a file for this method: pvs given no file= option. */
static bool bakes_pvs(const char *name, const char *options)
{
    if (strcmp(name, "pvs") != 0)
        return false;
    for (const char *p = options; p && *p; p = strchr(p, ',') ? strchr(p, ',') + 1 : NULL) {
        p += strspn(p, " \t");
        size_t len = strcspn(p, "=, \t");
        if (len == 4 && !strncmp(p, "file", 4))
            return false;
    }
    return true;
}

/* The methods to run with their options: --methods (default: every registered method that runs
 * with its default options or was given --method-options, and pvs; the rest go to skipped with
 * the reason) and --method-options. Names and options point into argv, names[] or the registry.
 * *bake_index receives the index of a pvs that needs a baked file (-1: none). Returns the count,
 * or -1 after printing a usage error. */
static int method_specs(const bench_args *g, const char *cmd, char *names, size_t names_size,
                        sl_bench_method_spec *specs, sl_bench_skip *skipped, uint32_t *skipped_count, int *bake_index)
{
    int n = 0;
    sl_error err;
    *skipped_count = 0;
    *bake_index = -1;
    for (uint32_t i = 0; i < g->mopt_count; i++)
        for (uint32_t j = 0; j < i; j++) {
            size_t li = (size_t)(g->mopt_value[i] - 1 - g->mopt_name[i]);
            size_t lj = (size_t)(g->mopt_value[j] - 1 - g->mopt_name[j]);
            if (li == lj && !strncmp(g->mopt_name[i], g->mopt_name[j], li)) {
                cli_error(cmd, "--method-options: options for '%.*s' are given twice", (int)li, g->mopt_name[i]);
                return -1;
            }
        }
    if (g->methods) {
        if ((n = cli_method_list(cmd, g->methods, names, names_size, specs, SL_BENCH_MAX_METHODS)) < 0)
            return -1;
        for (int k = 0; k < n; k++) {
            if (specs[k].options && options_for(g, specs[k].name)) {
                cli_error(cmd, "--methods: options for '%s' are given twice (in --methods and in --method-options)",
                          specs[k].name);
                return -1;
            }
            if (!specs[k].options)
                specs[k].options = options_for(g, specs[k].name);
        }
    } else {
        uint32_t count = sl_cull_method_count();
        for (uint32_t i = 0; i < count && n < (int)SL_BENCH_MAX_METHODS; i++) {
            sl_cull_method_desc d;
            if (sl_cull_method_info(i, &d, &err) != SL_OK)
                continue;
            const char *opts = options_for(g, d.name);
            if (!opts && !bakes_pvs(d.name, NULL) && sl_cull_method_check_options(d.name, NULL, &err) != SL_OK) {
                if (*skipped_count < SL_BENCH_MAX_METHODS) {
                    skipped[*skipped_count].name = d.name;
                    snprintf(skipped[*skipped_count].reason, sizeof skipped[0].reason, "%s", err.message);
                    (*skipped_count)++;
                }
                continue;
            }
            specs[n++] = (sl_bench_method_spec){d.name, opts};
        }
    }
    /* options for a method that is not run, and options (or their absence) a method rejects */
    for (uint32_t i = 0; i < g->mopt_count; i++) {
        size_t len = (size_t)(g->mopt_value[i] - 1 - g->mopt_name[i]);
        int k = 0;
        while (k < n && (strlen(specs[k].name) != len || strncmp(specs[k].name, g->mopt_name[i], len)))
            k++;
        if (k == n) {
            cli_error(cmd, "--method-options: '%.*s' is not among the methods run", (int)len, g->mopt_name[i]);
            return -1;
        }
    }
    for (int k = 0; k < n; k++) {
        const char *opts = specs[k].options;
        char with_file[4200];
        if (bakes_pvs(specs[k].name, opts)) {
            /* the other options are checked now, with a stand-in for the file baked later */
            *bake_index = k;
            if (snprintf(with_file, sizeof with_file, "file=baked%s%s", opts ? "," : "", opts ? opts : "") >=
                (int)sizeof with_file) {
                cli_error(cmd, "--method-options: options for pvs too long");
                return -1;
            }
            opts = with_file;
        }
        if (sl_cull_method_check_options(specs[k].name, opts, &err) != SL_OK) {
            uintptr_t o = (uintptr_t)specs[k].options, b = (uintptr_t)names; /* options inside --methods' copy */
            bool inline_opts = o && o >= b && o < b + names_size;
            cli_error(cmd, "%s%s", inline_opts ? "--methods: " : specs[k].options ? "--method-options: " : "",
                      err.message);
            return -1;
        }
    }
    return n;
}

/* The views of one scene; first and count select the frames to run. */
static sl_status make_views(const bench_args *g, sl_scene scene, sl_path *out, uint32_t *first, uint32_t *count,
                            sl_error *err)
{
    *first = 0;
    *count = UINT32_MAX;
    sl_status st;
    if (g->view_text) {
        /* one pose at the view's eye, looking along its forward axis: what the PVS bake along the
         * frames and the maps read; the frame itself is culled from the view */
        sl_camera in = sl_camera_default();
        in.width = g->width;
        in.height = g->height;
        st = sl_path_create(&in, NULL, out, err);
        const sl_vec3 f = g->view.forward;
        sl_pose pose = {0, g->view.eye, atan2f(f.y, f.x), asinf(f.z > 1 ? 1 : f.z < -1 ? -1 : f.z), 0};
        if (st == SL_OK && (st = sl_path_append(*out, &pose, err)) != SL_OK) {
            sl_path_destroy(*out);
            *out = NULL;
        }
        return st;
    }
    if (g->path_file) {
        st = sl_path_load(g->path_file, NULL, out, err);
        if (st != SL_OK)
            tool_error_prefix(err, "--path");
        if (st == SL_OK && g->frames) {
            parse_frames(g->frames, first, count);
            if (*first >= sl_path_count(*out)) {
                st = tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: --frames %s starts beyond its %u frames",
                             g->path_file, g->frames, sl_path_count(*out));
                sl_path_destroy(*out);
                *out = NULL;
            }
        }
        return st;
    }
    bool aerial = g->random_kind && !strcmp(g->random_kind, "flyover");
    sl_path_options po = sl_path_options_default(aerial ? SL_PATH_FLYOVER : SL_PATH_WALK);
    po.intrinsics.width = g->width;
    po.intrinsics.height = g->height;
    po.seed = g->seed;
    po.altitude = g->altitude;
    if (g->has_walk) {
        po.frames = g->walk;
        po.fps = g->fps;
        return sl_path_generate(scene, &po, NULL, out, err);
    }
    sl_view_kind kind = !strcmp(g->random_kind, "street") ? SL_VIEWS_STREET : SL_VIEWS_FLYOVER;
    return sl_path_random_views(scene, kind, g->count, g->seed, &po, NULL, out, err);
}

static void json_summary(cli_json *j, const sl_bench *benches, uint32_t count, uint64_t violations,
                         const char *out_dir, const sl_bench_skip *skipped, uint32_t nskipped)
{
    cli_json_string(j, "out", out_dir);
    cli_json_uint(j, "violations", violations);
    cli_json_array_begin(j, "skipped");
    for (uint32_t i = 0; i < nskipped; i++) {
        cli_json_object_begin(j, NULL);
        cli_json_string(j, "name", skipped[i].name);
        cli_json_string(j, "reason", skipped[i].reason);
        cli_json_object_end(j);
    }
    cli_json_array_end(j);
    cli_json_array_begin(j, "scenes");
    for (uint32_t bi = 0; bi < count; bi++) {
        sl_bench b = benches[bi];
        sl_scene_stats ss;
        sl_scene_get_stats(sl_bench_scene(b), &ss);
        uint32_t nf = sl_bench_frame_count(b);
        double *oms = malloc((nf ? nf : 1) * sizeof *oms);
        sl_series_summary os;
        memset(&os, 0, sizeof os);
        double vis = 0, tv = 0;
        uint32_t outside = 0;
        for (uint32_t f = 0; f < nf; f++) {
            sl_bench_frame fr;
            sl_bench_get_frame(b, f, &fr, NULL);
            if (oms)
                oms[f] = fr.oracle_ms;
            if (fr.out_of_domain) {
                outside++;
                continue;
            }
            vis += fr.visible_count;
            tv += (double)fr.triangles_visible;
        }
        if (oms)
            sl_series_summarize(oms, nf, NULL, &os, NULL);
        free(oms);
        cli_json_object_begin(j, NULL);
        cli_json_string(j, "scene", sl_bench_label(b));
        cli_json_uint(j, "objects", ss.object_count);
        cli_json_uint(j, "triangles", ss.instanced_triangle_count);
        cli_json_uint(j, "frames", nf);
        cli_json_uint(j, "frames_out_of_domain", outside);
        cli_json_double(j, "visible_mean", nf > outside ? vis / (nf - outside) : 0);
        cli_json_double(j, "triangles_visible_mean", nf > outside ? tv / (nf - outside) : 0);
        cli_json_object_begin(j, "oracle_ms");
        cli_json_double(j, "median", os.median);
        cli_json_double(j, "p95", os.p95);
        cli_json_double(j, "max", os.max);
        cli_json_object_end(j);
        cli_json_array_begin(j, "methods");
        for (uint32_t mi = 0; mi < sl_bench_method_count(b); mi++) {
            sl_bench_method_info info;
            sl_bench_summary s;
            if (sl_bench_method(b, mi, &info, NULL) != SL_OK || sl_bench_summarize(b, mi, &s, NULL) != SL_OK)
                continue;
            cli_json_object_begin(j, NULL);
            cli_json_string(j, "name", info.name);
            cli_json_string(j, "options", info.options);
            cli_json_string(j, "guarantee", sl_cull_guarantee_name(info.guarantee));
            cli_json_uint(j, "frames", s.frames);
            cli_json_double(j, "objects_drawn_mean", s.objects_drawn_mean);
            cli_json_double(j, "triangles_drawn_mean", s.triangles_drawn_mean);
            cli_json_double(j, "visible_mean", s.visible_mean);
            cli_json_double(j, "triangles_visible_mean", s.triangles_visible_mean);
            cli_json_double(j, "overestimation", s.overestimation);
            cli_json_double(j, "overestimation_mean", s.overestimation_mean);
            cli_json_uint(j, "frames_empty", s.frames_empty);
            cli_json_double(j, "extra_mean", s.extra_mean);
            cli_json_uint(j, "missed_objects", s.missed_objects_total);
            cli_json_uint(j, "missed_pixels", s.missed_pixels_total);
            cli_json_uint(j, "frames_with_misses", s.frames_with_misses);
            cli_json_object_begin(j, "cull_ms");
            cli_json_double(j, "median", s.cull_ms.median);
            cli_json_double(j, "p95", s.cull_ms.p95);
            cli_json_double(j, "max", s.cull_ms.max);
            cli_json_double(j, "mean", s.cull_ms.mean);
            cli_json_double(j, "min", s.cull_ms.min);
            cli_json_object_end(j);
            cli_json_object_end(j);
        }
        cli_json_array_end(j);
        sl_bench_recommendation rec;
        if (sl_bench_recommend(b, &rec, NULL) == SL_OK) {
            cli_json_object_begin(j, "recommendation");
            cli_json_double(j, "max_overestimation", rec.max_overestimation);
            cli_json_double(j, "max_ms", rec.max_ms);
            sl_bench_method_info fi, ti;
            if (rec.fastest >= 0 && sl_bench_method(b, (uint32_t)rec.fastest, &fi, NULL) == SL_OK)
                cli_json_string(j, "fastest", fi.name);
            else
                cli_json_key(j, "fastest"), fputs("null", j->out);
            if (rec.tightest >= 0 && sl_bench_method(b, (uint32_t)rec.tightest, &ti, NULL) == SL_OK)
                cli_json_string(j, "tightest", ti.name);
            else
                cli_json_key(j, "tightest"), fputs("null", j->out);
            cli_json_string(j, "text", rec.text);
            cli_json_object_end(j);
        }
        cli_json_object_end(j);
    }
    cli_json_array_end(j);
}

/* --sets: every frame's sets with names, written while the frame's results are there */
typedef struct sets_writer {
    FILE *fp;
    bool json, first;
} sets_writer;

static void sets_put_name(FILE *fp, const char *s, bool json)
{
    fputc('"', fp);
    for (; *s; s++) {
        if (*s == '"')
            fputs(json ? "\\\"" : "\"\"", fp);
        else if (json && *s == '\\')
            fputs("\\\\", fp);
        else
            fputc(*s, fp);
    }
    fputc('"', fp);
}

static void sets_put(sets_writer *w, sl_bench b, uint32_t frame, uint32_t source, const char *who, const uint32_t *ids,
                     uint32_t n)
{
    sl_scene s = sl_bench_scene(b);
    if (!w->json) {
        for (uint32_t k = 0; k < n; k++) {
            fprintf(w->fp, "%s,%u,%u,%s,%u,", sl_bench_label(b), frame, source, who, ids[k]);
            sets_put_name(w->fp, sl_scene_object_name(s, ids[k]), false);
            fputc('\n', w->fp);
        }
        return;
    }
    fprintf(w->fp, "%s{\"scene\":", w->first ? "" : ",\n");
    w->first = false;
    sets_put_name(w->fp, sl_bench_label(b), true);
    fprintf(w->fp, ",\"frame\":%u,\"source\":%u,\"by\":\"%s\",\"objects\":[", frame, source, who);
    for (uint32_t k = 0; k < n; k++) {
        fprintf(w->fp, "%s{\"id\":%u,\"name\":", k ? "," : "", ids[k]);
        sets_put_name(w->fp, sl_scene_object_name(s, ids[k]), true);
        fputc('}', w->fp);
    }
    fputs("]}", w->fp);
}

static bool sets_frame(void *user, sl_bench b, uint32_t frame)
{
    sets_writer *w = user;
    sl_bench_frame fr;
    if (sl_bench_get_frame(b, frame, &fr, NULL) != SL_OK)
        return false;
    sl_oracle_frame of;
    if (!fr.out_of_domain && sl_bench_last_truth(b, &of, NULL) == SL_OK)
        sets_put(w, b, frame, fr.source, "oracle", of.visible, of.visible_count);
    for (uint32_t m = 0; m < sl_bench_method_count(b); m++) {
        sl_bench_method_info info;
        const uint32_t *ids;
        uint32_t n;
        if (sl_bench_method(b, m, &info, NULL) == SL_OK && sl_bench_last_result(b, m, &ids, &n, NULL) == SL_OK)
            sets_put(w, b, frame, fr.source, info.name, ids, n);
    }
    return !ferror(w->fp);
}

/* Make every label distinct by appending -2, -3 ... */
static void unique_label(char *label, size_t size, char labels[][128], uint32_t count)
{
    char base[128];
    snprintf(base, sizeof base, "%s", label);
    for (uint32_t k = 2;; k++) {
        bool clash = false;
        for (uint32_t i = 0; i < count; i++)
            clash |= !strcmp(labels[i], label);
        if (!clash)
            return;
        snprintf(label, size, "%.100s-%u", base, k);
    }
}

/* pvs without a file: bake the PVS of the cells along the frames first..first+count-1 of this
 * scene's views (those the bench runs) into WORK/LABEL.slpvs (WORK: the run's folder, OUT/ at the end) and give its name to run[index] (in
 * opts_buf, before the user's other options). When nothing can be baked: an error (*status = 1) if
 * --methods named pvs, else pvs leaves run[] for this scene and joins skipped with the reason. A
 * failed bake returns its status. */
static sl_status bake_pvs(const bench_args *g, const char *cmd, const char *work, sl_scene scene, sl_path views, uint32_t first,
                          uint32_t count, const char *label, const sl_progress *prog, cli_progress_state *ps,
                          sl_bench_method_spec *run, uint32_t *nrun, uint32_t index, char *opts_buf, size_t opts_size,
                          sl_bench_skip *skipped, uint32_t *nskipped, int *status, sl_error *err)
{
    char file[4400], shown[4400];
    snprintf(file, sizeof file, "%s/%s.slpvs", work, label);
    snprintf(shown, sizeof shown, "%s/%s.slpvs", g->out_dir, label);
    bool talk = !g->quiet && !g->json;
    if (talk)
        fprintf(stderr, "sightline bench: %s: baking the PVS of the street cells within %g m of the views (%s) for "
                        "pvs...\n", label, (double)CLI_PVS_ALONG_RADIUS, CLI_PVS_ALONG_METHOD);
    cli_pvs_along pa;
    sl_status st = cli_pvs_bake_along(scene, views, first, count, file, prog, &pa, err);
    cli_progress_done(ps);
    if (st != SL_OK)
        return st;
    if (pa.why[0]) {
        if (g->methods) {
            cli_error(cmd, "cannot run pvs on %s: %s", label, pa.why);
            *status = 1;
            return SL_OK;
        }
        cli_error(cmd, "not running pvs on %s: %s", label, pa.why);
        if (*nskipped < SL_BENCH_MAX_METHODS) {
            skipped[*nskipped].name = "pvs";
            snprintf(skipped[*nskipped].reason, sizeof skipped[0].reason, "%.120s: %.380s", label, pa.why);
            (*nskipped)++;
        }
        memmove(run + index, run + index + 1, (*nrun - index - 1) * sizeof run[0]);
        (*nrun)--;
        return SL_OK;
    }
    const char *user = run[index].options;
    snprintf(opts_buf, opts_size, "%s%s%s", pa.options, user ? "," : "", user ? user : "");
    run[index].options = opts_buf;
    if (talk)
        fprintf(stderr, "sightline bench: %s: %u cells, %.1f%% of the objects culled per cell, %.1f s\n", shown,
                pa.cells, 100.0 * pa.culled, pa.seconds);
    return SL_OK;
}

int sl_cmd_bench(int argc, char **argv)
{
    const char *cmd = argv[0];
    bench_args g;
    int rc = parse(argc, argv, &g);
    if (rc)
        return rc < 0 ? 0 : rc;
    char names[4096];
    sl_bench_method_spec specs[SL_BENCH_MAX_METHODS];
    sl_bench_skip skipped[SL_BENCH_MAX_METHODS];
    uint32_t nskipped = 0;
    int bake_index;
    int nm = method_specs(&g, cmd, names, sizeof names, specs, skipped, &nskipped, &bake_index);
    if (nm < 0)
        return 2;
    if (g.frames) {
        uint32_t f0, fc;
        if (!parse_frames(g.frames, &f0, &fc)) {
            cli_error(cmd, "--frames '%s': expected A:B with A < B (or A:, :B, A)", g.frames);
            return 2;
        }
    }
    if (!nm) {
        cli_error(cmd, "no registered method runs with its default options; name them with --methods and "
                       "--method-options");
        return 2;
    }
    for (uint32_t i = 0; i < nskipped; i++)
        cli_error(cmd, "not running %s: %s (give it --method-options %s:...)", skipped[i].name, skipped[i].reason,
                  skipped[i].name);
    /* everything goes to a new folder first, moved into OUT only when the run has written it all */
    cli_outdir od;
    if (!cli_outdir_begin(cmd, g.out_dir, &od))
        return 1;
    const char *work = od.stage;
    const char *inputs[MAX_SCENES + 1];
    for (uint32_t i = 0; i < g.scene_count; i++)
        inputs[i] = g.scenes[i];
    inputs[g.scene_count] = g.path_file;
    od.inputs = inputs;
    od.input_count = g.scene_count + 1;

    sl_scene scenes[MAX_SCENES] = {0};
    sl_bench benches[MAX_SCENES] = {0};
    char labels[MAX_SCENES][128];
    uint32_t nb = 0;
    cli_progress_state ps;
    sl_progress prog = cli_progress(&ps, g.quiet || g.json);
    sl_error err;
    int status = 0;
    char path[4600];
    sets_writer sets = {NULL, g.sets && !strcmp(g.sets, "json"), true};
    sl_output sets_out = NULL;
    if (g.sets) {
        snprintf(path, sizeof path, "%s/sets.%s", work, g.sets);
        if (sl_output_open(path, NULL, &sets_out, &err) != SL_OK) {
            cli_outdir_abort(&od);
            return cli_fail(cmd, &err);
        }
        sets.fp = sl_output_stream(sets_out);
        fputs(sets.json ? "{\"sets\":[\n" : "scene,frame,source,by,object,name\n", sets.fp);
    }
    for (uint32_t si = 0; si < g.scene_count && !status; si++) {
        sl_scene s = NULL;
        char label[128];
        sl_import_options io = sl_import_defaults();
        cli_import_apply(&g.import, &io);
        sl_status st = cli_open_scene(g.scenes[si], g.map, &io, &prog, &s, label, sizeof label, &err);
        cli_progress_done(&ps);
        if (st != SL_OK) {
            status = cli_fail(cmd, &err);
            break;
        }
        scenes[si] = s;
        unique_label(label, sizeof label, labels, nb);
        sl_path views = NULL;
        uint32_t first, count;
        st = make_views(&g, s, &views, &first, &count, &err);
        if (st != SL_OK) {
            status = cli_fail(cmd, &err);
            break;
        }
        sl_bench_method_spec run[SL_BENCH_MAX_METHODS];
        uint32_t nrun = (uint32_t)nm;
        memcpy(run, specs, nrun * sizeof run[0]);
        char pvs_options[8800];
        if (bake_index >= 0) {
            st = bake_pvs(&g, cmd, work, s, views, first, count, label, &prog, &ps, run, &nrun, (uint32_t)bake_index,
                          pvs_options, sizeof pvs_options, skipped, &nskipped, &status, &err);
            if (status || st != SL_OK) {
                sl_path_destroy(views);
                if (!status)
                    status = cli_fail(cmd, &err);
                break;
            }
        }
        cli_drop_not_applicable(cmd, s, label, run, &nrun, skipped, &nskipped, SL_BENCH_MAX_METHODS, g.quiet || g.json);
        if (!nrun) {
            cli_error(cmd, "no method to run on %s: every one named is not applicable to it", label);
            sl_path_destroy(views);
            status = 2;
            break;
        }
        sl_bench_options bo = sl_bench_default_options();
        bo.width = g.width;
        bo.height = g.height;
        bo.threads = g.threads;
        bo.repeat = g.repeat;
        bo.max_overestimation = g.max_over;
        bo.max_ms = g.max_ms;
        if (sets.fp) {
            bo.frame_done = sets_frame;
            bo.frame_user = &sets;
        }
        bo.label = label;
        bo.progress = prog;
        sl_bench b = NULL;
        st = sl_bench_create(s, run, nrun, &bo, NULL, &b, &err);
        if (st == SL_OK && (st = cli_outdir_show_bench(b, work, g.out_dir, &err)) != SL_OK) {
            sl_bench_destroy(b);
            b = NULL;
        }
        if (st == SL_OK) {
            benches[nb] = b;
            snprintf(labels[nb], sizeof labels[nb], "%s", label);
            nb++;
            st = g.view_text ? sl_bench_run_view(b, &g.view, &err) : sl_bench_run_path(b, views, first, count, &err);
        }
        cli_progress_done(&ps);
        if (st == SL_OK && !g.no_plots) {
            snprintf(path, sizeof path, "%s/%s-", work, label);
            st = sl_bench_write_plots(b, path, &err);
            sl_bench_map_options mo;
            memset(&mo, 0, sizeof mo);
            mo.size = g.map_size;
            mo.use_eye = g.has_eye;
            mo.eye = g.eye;
            sl_bench_frame f0;
            if (st == SL_OK && !g.has_eye && sl_bench_get_frame(b, 0, &f0, NULL) == SL_OK)
                mo.camera = f0.camera;
            snprintf(path, sizeof path, "%s/%s-map-", work, label);
            if (st == SL_OK && (g.has_eye || sl_bench_frame_count(b)))
                st = sl_bench_write_maps(b, &mo, path, NULL, &err);
        }
        sl_path_destroy(views);
        if (st != SL_OK)
            status = cli_fail(cmd, &err);
    }
    if (sets_out) {
        if (!status) {
            fputs(sets.json ? "\n]}\n" : "", sets.fp);
            if (sl_output_commit(sets_out, &err) != SL_OK)
                status = cli_fail(cmd, &err);
        } else {
            sl_output_abort(sets_out);
        }
    }
    if (!status) {
        const char *files[] = {"frames.csv", "frames.json", "summary.md"};
        for (int k = 0; k < 3 && !status; k++) {
            snprintf(path, sizeof path, "%s/%s", work, files[k]);
            sl_status st = k == 0   ? sl_bench_write_csv(benches, nb, path, &err)
                           : k == 1 ? sl_bench_write_json(benches, nb, path, &err)
                                    : sl_bench_write_summary(benches, nb, path, &err);
            if (st != SL_OK)
                status = cli_fail(cmd, &err);
        }
    }
    if (!status) {
        uint64_t total_violations = 0;
        for (uint32_t i = 0; i < nb; i++)
            total_violations += sl_bench_violations(benches[i]);
        snprintf(path, sizeof path, "%s/summary.json", work);
        sl_output f;
        if (sl_output_open(path, NULL, &f, &err) != SL_OK) {
            status = cli_fail(cmd, &err);
        } else {
            cli_json j;
            cli_json_begin(&j, sl_output_stream(f));
            json_summary(&j, benches, nb, total_violations, g.out_dir, skipped, nskipped);
            cli_json_end(&j);
            if (sl_output_commit(f, &err) != SL_OK) /* a write error too */
                status = cli_fail(cmd, &err);
        }
    }
    /* the run's files take their places in OUT only when all are written */
    if (status)
        cli_outdir_abort(&od);
    else if (!cli_outdir_commit(cmd, &od))
        status = 1;
    if (!status) {
        uint64_t violations = sl_bench_print_violations(benches, nb, 20, stderr);
        if (g.json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            json_summary(&j, benches, nb, violations, g.out_dir, skipped, nskipped);
            cli_json_end(&j);
        } else {
            sl_bench_print_summary(benches, nb, stdout);
            for (uint32_t i = 0; i < nskipped; i++)
                printf("not run: %s (%s)\n", skipped[i].name, skipped[i].reason);
            printf("results in %s/ (frames.csv, frames.json, summary.md, summary.json%s)\n", g.out_dir,
                   g.no_plots ? "" : ", plots (.svg), maps (-map-METHOD.png)");
        }
        /* views that see nothing measure nothing: say so loudly */
        for (uint32_t i = 0; i < nb; i++) {
            uint32_t nf = sl_bench_frame_count(benches[i]), empty = 0, judged = 0;
            for (uint32_t f = 0; f < nf; f++) {
                sl_bench_frame fr;
                if (sl_bench_get_frame(benches[i], f, &fr, NULL) != SL_OK || fr.out_of_domain)
                    continue;
                judged++;
                empty += fr.visible_count == 0;
            }
            if (judged && 2 * empty > judged) {
                fprintf(stderr,
                        "sightline bench: WARNING: in %u of the %u frames of %s the oracle sees no object: those "
                        "views miss the scene and measure nothing (a flyover too high or too far for the scene? "
                        "--altitude sets its height; cameras facing away?)%s\n",
                        empty, judged, sl_bench_label(benches[i]),
                        g.allow_empty ? "; --allow-empty: exit status 0" : "; exit status 1 (--allow-empty to accept)");
                if (!g.allow_empty)
                    status = 1;
            }
        }
        if (violations) {
            fprintf(stderr,
                    "sightline bench: CONSERVATIVENESS VIOLATION: conservative methods missed %llu visible "
                    "object(s) in total (see above)%s\n",
                    (unsigned long long)violations, g.strict ? "" : "; --no-strict: exit status 0");
            if (g.strict)
                status = 1;
        }
    }
    for (uint32_t i = 0; i < nb; i++)
        sl_bench_destroy(benches[i]);
    for (uint32_t i = 0; i < g.scene_count; i++)
        sl_scene_destroy(scenes[i]);
    return status;
}

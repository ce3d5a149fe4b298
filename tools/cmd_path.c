/* `sightline path`: generate camera paths (walk, drive, flyover, random viewpoints) for a scene,
 * and inspect or validate path files. The file format is in docs/paths.md and in `--help`. */
#include "cli.h"

#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DEG (M_PI / 180.0)

static const char format_help[] =
    "path file format (plain text, UTF-8/ASCII, \\n or \\r\\n line ends):\n"
    "  # sightline-path 1                       first line, exactly\n"
    "  camera fov=60 near=0.1 far=5000 width=1024 height=768 projection=perspective [ortho_height=100]\n"
    "                                           optional, before the poses; fov in degrees\n"
    "  t x y z yaw pitch roll                   one pose per line: seconds, metres (Z up), degrees\n"
    "  # comments and blank lines are allowed; times never decrease\n"
    "  yaw 0 looks along +X, 90 along +Y; pitch > 0 looks up, in [-90, 90]; roll > 0 turns the\n"
    "  camera clockwise as the viewer sees it. See docs/paths.md.\n";

static void usage_main(FILE *out)
{
    fprintf(out,
            "usage: sightline path <action> [options]   (sightline path <action> --help for details)\n\n"
            "Generate, inspect or validate camera paths.\n\n"
            "actions:\n"
            "  gen SCENE --kind walk|drive|flyover -o PATH.txt    walkthrough along the streets, or a flyover loop\n"
            "  random SCENE --kind street|flyover -o PATH.txt     independent random viewpoints (benchmarks)\n"
            "  info PATH.txt [--json]                             frames, duration, length, bounds, speeds\n"
            "  check PATH.txt [--json]                            validate a path file only\n\n"
            "%s\n"
            "examples:\n"
            "  sightline path gen city.slscene --kind walk --frames 1800 --seed 7 -o walk.txt\n"
            "  sightline path random city.slscene --kind street --count 1000 --seed 1 -o views.txt\n"
            "  sightline path info walk.txt --json\n",
            format_help);
}

static void usage_gen(FILE *out)
{
    fprintf(out,
            "usage: sightline path gen SCENE --kind walk|drive|flyover -o PATH.txt [options]\n\n"
            "Generate a deterministic camera path for SCENE (same scene, options and seed: same file).\n"
            "  walk     a pedestrian on the sidewalk (0.4 of the street width right of the centre line),\n"
            "           eye 1.7 m above the ground, 1.4 m/s, along the street centre-line graph, turning\n"
            "           at random at intersections (never straight back unless at a dead end), easing\n"
            "           the view into each turn\n"
            "  drive    the same in the middle of the right lane (0.25 of the width), eye 1.2 m, 50 km/h\n"
            "  flyover  a closed elliptic loop over the scene's bounds, the camera aimed at the loop's\n"
            "           centre and tilted 30 degrees down; works for any scene, with or without streets\n"
            "Walk and drive need a street network: on a scene without one they fail with \"scene has\n"
            "no street network: use flyover, or a path file\".\n\n"
            "SCENE is a .slscene file, a Quake III .bsp, a .pk3 archive (with --map), any file assimp\n"
            "reads, or city:tiny|small|vienna[:SEED] (the generated city, made on the fly).\n\n"
            "options:\n"
            "  --kind K          walk, drive or flyover (default walk)\n"
            "  -o, --output F    path file to write (required; written atomically)\n"
            "  --frames N        poses to generate (default 600)\n"
            "  --fps F           frames per second (default 30)\n"
            "  --speed S         metres per second (default 1.4 walk, 13.89 drive; flyover: one loop over\n"
            "                    the path's duration)\n"
            "  --seed N          random seed (default 1)\n"
            "  --eye-height H    walk/drive: eye above the ground in metres (1.7 / 1.2)\n"
            "  --lane-offset F   walk/drive: offset right of the centre line as a fraction of the street\n"
            "                    width, 0..0.5 (0.4 / 0.25)\n"
            "  --head-bob        walk: 2.5 cm vertical bob and 0.4 degree nod per 0.7 m step\n"
            "  --altitude A      flyover: flight height in metres above the scene's lowest point\n"
            "                    (default from the scene's size w across and height h:\n"
            "                    max(min(150, w/2), 1.5 h + min(50, w/2)); 150 m over a city)\n"
            "  --look-down DEG   flyover: angle below the horizon (default 30)\n"
            "  --fov DEG         vertical field of view (default 60)\n"
            "  --width W         viewport width in pixels (default 1024)\n"
            "  --height H        viewport height in pixels (default 768)\n"
            "  --near N          near plane in metres (default 0.1)\n"
            "  --far F           far plane in metres (default 5000)\n"
            "  --ortho H         orthographic projection with a view volume H metres high\n"
            "  --map NAME        map inside a .pk3\n"
            "  --allow-external PATH  an assimp model's references may resolve inside PATH too (sightline import --help)\n"
            "  --import-timeout S  stop reading an assimp model after S seconds (sightline import --help)\n"
            "  --json            print the path's statistics as JSON on stdout\n"
            "  --quiet           no progress output\n"
            "  --help            this text\n\n"
            "examples:\n"
            "  sightline path gen city.slscene --kind walk --frames 1800 --seed 7 -o walk.txt\n"
            "  sightline path gen city.slscene --kind drive --speed 8.3 --fps 60 -o drive.txt\n"
            "  sightline path gen q3dm17.bsp --kind flyover --altitude 40 --look-down 45 -o fly.txt\n");
}

static void usage_random(FILE *out)
{
    fprintf(out,
            "usage: sightline path random SCENE --kind street|flyover --count N -o PATH.txt [options]\n\n"
            "Write N independent random viewpoints (pose i at time i seconds) for benchmarks.\n"
            "  street   a random point of a random street (chosen by length), anywhere across the street\n"
            "           within 0.4 of its width from the centre line, eye 1.7 m above the ground, random\n"
            "           yaw, level view. Without streets, the scene's Quake III spawn points (metadata\n"
            "           q3.spawns) are used; otherwise it fails.\n"
            "  flyover  a random point over the scene's bounds at the flyover altitude, random yaw,\n"
            "           looking 30 +- 15 degrees down\n\n"
            "options:\n"
            "  --kind K          street or flyover (default street)\n"
            "  --count N         viewpoints (default 100)\n"
            "  --seed N          random seed (default 1)\n"
            "  -o, --output F    path file to write (required)\n"
            "  --eye-height H, --lane-offset F, --altitude A, --look-down DEG, --fov DEG, --width W,\n"
            "  --height H, --near N, --far F, --ortho H, --map NAME, --allow-external PATH,\n"
            "  --import-timeout S, --json,\n"
            "  --quiet: as for `path gen`\n"
            "  --help            this text\n\n"
            "examples:\n"
            "  sightline path random city.slscene --kind street --count 1000 --seed 1 -o views.txt\n"
            "  sightline path random city.slscene --kind flyover --count 200 --seed 2 -o aerial.txt\n");
}

static void usage_info(FILE *out, const char *action)
{
    bool check = !strcmp(action, "check");
    fprintf(out,
            "usage: sightline path %s PATH.txt [--json]\n\n"
            "%s\n\n"
            "options:\n"
            "  --json    machine-readable output on stdout\n"
            "  --help    this text\n\n"
            "%s\n"
            "example:\n"
            "  sightline path %s walk.txt%s\n",
            action,
            check ? "Validate a path file: exit status 0 when it is well formed, 1 with \"file:line: reason\"\n"
                    "otherwise."
                  : "Print a path file's frame count, duration, length travelled, bounds, speeds and camera.",
            format_help, action, check ? "" : " --json");
}

/* Options shared by gen and random. */
typedef struct gen_args {
    const char *scene, *map, *output, *kind;
    sl_path_options opt;
    uint32_t count;
    uint64_t seed;
    bool json, quiet;
    /* which options were given (defaults depend on the kind, known only at the end) */
    bool has_speed, has_eye, has_lane;
    float speed, eye, lane, look_down_deg, fov_deg, ortho;
    bool has_look, has_fov, has_ortho;
    uint32_t width, height;
    float near_plane, far_plane;
    bool has_width, has_height, has_near, has_far;
} gen_args;

/* Parse one option common to gen and random; false when the option is not one of them. */
static bool parse_common(cli_args *a, const char *name, const char *val, gen_args *g)
{
    if (!strcmp(name, "o")) /* --o FILE, as -o */
        g->output = cli_value(a, name, val);
    else if (!strcmp(name, "kind"))
        g->kind = cli_value(a, name, val);
    else if (!strcmp(name, "seed"))
        cli_parse_u64(a, name, cli_value(a, name, val), &g->seed);
    else if (!strcmp(name, "eye-height"))
        g->has_eye = cli_parse_float(a, name, cli_value(a, name, val), &g->eye);
    else if (!strcmp(name, "lane-offset"))
        g->has_lane = cli_parse_float(a, name, cli_value(a, name, val), &g->lane);
    else if (!strcmp(name, "altitude"))
        cli_parse_float(a, name, cli_value(a, name, val), &g->opt.altitude);
    else if (!strcmp(name, "look-down"))
        g->has_look = cli_parse_float(a, name, cli_value(a, name, val), &g->look_down_deg);
    else if (!strcmp(name, "fov"))
        g->has_fov = cli_parse_float(a, name, cli_value(a, name, val), &g->fov_deg);
    else if (!strcmp(name, "width"))
        g->has_width = cli_parse_u32(a, name, cli_value(a, name, val), &g->width);
    else if (!strcmp(name, "height"))
        g->has_height = cli_parse_u32(a, name, cli_value(a, name, val), &g->height);
    else if (!strcmp(name, "near"))
        g->has_near = cli_parse_float(a, name, cli_value(a, name, val), &g->near_plane);
    else if (!strcmp(name, "far"))
        g->has_far = cli_parse_float(a, name, cli_value(a, name, val), &g->far_plane);
    else if (!strcmp(name, "ortho"))
        g->has_ortho = cli_parse_float(a, name, cli_value(a, name, val), &g->ortho);
    else
        return false;
    return true;
}

/* Apply the given options over the kind's defaults. */
static void apply_common(gen_args *g, sl_path_kind kind)
{
    float altitude = g->opt.altitude;
    g->opt = sl_path_options_default(kind);
    g->opt.altitude = altitude;
    g->opt.seed = g->seed;
    if (g->has_speed)
        g->opt.speed = g->speed;
    if (g->has_eye)
        g->opt.eye_height = g->eye;
    if (g->has_lane)
        g->opt.lane_offset = g->lane;
    if (g->has_look)
        g->opt.look_down = (float)(g->look_down_deg * DEG);
    sl_camera *c = &g->opt.intrinsics;
    if (g->has_fov)
        c->fov_y = (float)(g->fov_deg * DEG);
    if (g->has_width)
        c->width = g->width;
    if (g->has_height)
        c->height = g->height;
    if (g->has_near)
        c->near_plane = g->near_plane;
    if (g->has_far)
        c->far_plane = g->far_plane;
    if (g->has_ortho) {
        c->projection = SL_ORTHOGRAPHIC;
        c->ortho_height = g->ortho;
    }
}

/* A float as the double of its shortest round-trip text, so that 0.2f prints as 0.2. */
static double tidy(float v)
{
    char buf[32];
    for (int prec = 6; prec <= 9; prec++) {
        snprintf(buf, sizeof buf, "%.*g", prec, (double)v);
        if (strtof(buf, NULL) == v)
            return strtod(buf, NULL);
    }
    return v;
}

/* An angle held in float radians, in degrees with the fewest digits that convert back. */
static double tidy_deg(float rad)
{
    char buf[32];
    for (int prec = 6; prec <= 9; prec++) {
        snprintf(buf, sizeof buf, "%.*g", prec, rad / DEG);
        if ((float)(strtod(buf, NULL) * DEG) == rad)
            return strtod(buf, NULL);
    }
    return rad / DEG;
}

static void print_stats(const char *file, sl_path p, bool json, const char *what)
{
    sl_path_stats s;
    sl_path_get_stats(p, &s);
    sl_camera c = sl_path_intrinsics(p);
    bool ortho = c.projection == SL_ORTHOGRAPHIC;
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "file", file);
        if (what)
            cli_json_string(&j, "kind", what);
        cli_json_uint(&j, "frames", s.frames);
        cli_json_double(&j, "duration_s", s.duration);
        cli_json_double(&j, "length_m", s.length);
        if (s.frames) {
            cli_json_array_begin(&j, "bounds_min");
            cli_json_double(&j, NULL, tidy(s.bounds.min.x)), cli_json_double(&j, NULL, tidy(s.bounds.min.y)),
                cli_json_double(&j, NULL, tidy(s.bounds.min.z));
            cli_json_array_end(&j);
            cli_json_array_begin(&j, "bounds_max");
            cli_json_double(&j, NULL, tidy(s.bounds.max.x)), cli_json_double(&j, NULL, tidy(s.bounds.max.y)),
                cli_json_double(&j, NULL, tidy(s.bounds.max.z));
            cli_json_array_end(&j);
        }
        cli_json_double(&j, "speed_min_mps", s.speed_min);
        cli_json_double(&j, "speed_mean_mps", s.speed_mean);
        cli_json_double(&j, "speed_max_mps", s.speed_max);
        cli_json_uint(&j, "jumps", s.jumps);
        cli_json_object_begin(&j, "camera");
        cli_json_string(&j, "projection", ortho ? "orthographic" : "perspective");
        cli_json_double(&j, "fov_deg", tidy_deg(c.fov_y));
        cli_json_double(&j, "ortho_height", tidy(c.ortho_height));
        cli_json_double(&j, "near", tidy(c.near_plane));
        cli_json_double(&j, "far", tidy(c.far_plane));
        cli_json_uint(&j, "width", c.width);
        cli_json_uint(&j, "height", c.height);
        cli_json_object_end(&j);
        cli_json_end(&j);
        return;
    }
    printf("%s%s%s\n", file, what ? ": " : "", what ? what : "");
    printf("  frames     %u\n", s.frames);
    printf("  duration   %.3f s\n", s.duration);
    printf("  length     %.2f m\n", s.length);
    if (s.frames)
        printf("  bounds     (%.2f, %.2f, %.2f) .. (%.2f, %.2f, %.2f) m\n", s.bounds.min.x, s.bounds.min.y, s.bounds.min.z,
               s.bounds.max.x, s.bounds.max.y, s.bounds.max.z);
    printf("  speed      min %.3f, mean %.3f, max %.3f m/s\n", s.speed_min, s.speed_mean, s.speed_max);
    if (s.jumps)
        printf("  jumps      %u (moves between poses of the same time: in the length, not the speeds)\n", s.jumps);
    if (ortho)
        printf("  camera     orthographic, %g m high, %ux%u, near %g m, far %g m\n", tidy(c.ortho_height), c.width,
               c.height, tidy(c.near_plane), tidy(c.far_plane));
    else
        printf("  camera     perspective, fov %g deg, %ux%u, near %g m, far %g m\n", tidy_deg(c.fov_y), c.width, c.height,
               tidy(c.near_plane), tidy(c.far_plane));
}

static int run_gen(int argc, char **argv, bool random_views)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = random_views ? "path random" : "path gen";
    gen_args g;
    memset(&g, 0, sizeof g);
    g.seed = 1;
    g.count = 100;
    uint32_t frames = 0;
    float fps = 0;
    bool has_frames = false, has_fps = false, head_bob = false;
    const char *name, *val;
    cli_import imp = {0};
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_import_option(&a, name, val, &imp) ||
            cli_common_option(&a, name, val, CLI_INPUT | CLI_OUTPUT | CLI_MAP | CLI_JSON | CLI_QUIET, &com)) {
            continue;
        } else if (parse_common(&a, name, val, &g)) {
        } else if (random_views && !strcmp(name, "count")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &g.count);
        } else if (!random_views && !strcmp(name, "frames")) {
            has_frames = cli_parse_u32(&a, name, cli_value(&a, name, val), &frames);
        } else if (!random_views && !strcmp(name, "fps")) {
            has_fps = cli_parse_float(&a, name, cli_value(&a, name, val), &fps);
        } else if (!random_views && !strcmp(name, "speed")) {
            g.has_speed = cli_parse_float(&a, name, cli_value(&a, name, val), &g.speed);
        } else if (!random_views && !strcmp(name, "head-bob")) {
            head_bob = true;
        } else {
            cli_unknown(&a, name);
        }
    }
    if (com.help) {
        random_views ? usage_random(stdout) : usage_gen(stdout);
        return 0;
    }
    if (a.error) {
        if (a.unknown[0])
            cli_suggest_option(a.cmd, a.unknown, random_views ? usage_random : usage_gen);
        return 2;
    }
    g.scene = com.input;
    g.map = com.map;
    g.json = com.json;
    g.quiet = com.quiet;
    if (com.output)
        g.output = com.output;
    if (!g.scene || !g.output) {
        cli_error(a.cmd, "missing %s (see sightline %s --help)", !g.scene ? "SCENE" : "-o PATH.txt", a.cmd);
        return 2;
    }
    const char *inputs[] = {g.scene};
    if (!cli_output_not_input(a.cmd, g.output, inputs, 1))
        return 2;
    const char *kind = g.kind ? g.kind : random_views ? "street" : "walk";
    sl_path_kind pk;
    sl_view_kind vk = SL_VIEWS_STREET;
    if (random_views) {
        if (!strcmp(kind, "street"))
            vk = SL_VIEWS_STREET, pk = SL_PATH_WALK;
        else if (!strcmp(kind, "flyover"))
            vk = SL_VIEWS_FLYOVER, pk = SL_PATH_FLYOVER;
        else {
            cli_error(a.cmd, "--kind: '%s' is not street or flyover", kind);
            return 2;
        }
    } else {
        if (!strcmp(kind, "walk"))
            pk = SL_PATH_WALK;
        else if (!strcmp(kind, "drive"))
            pk = SL_PATH_DRIVE;
        else if (!strcmp(kind, "flyover"))
            pk = SL_PATH_FLYOVER;
        else {
            cli_error(a.cmd, "--kind: '%s' is not walk, drive or flyover", kind);
            return 2;
        }
    }
    apply_common(&g, pk);
    if (has_frames)
        g.opt.frames = frames;
    if (has_fps)
        g.opt.fps = fps;
    g.opt.head_bob = head_bob;

    sl_error err;
    sl_scene scene;
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&imp, &io);
    if (cli_open_scene(g.scene, g.map, &io, NULL, &scene, NULL, 0, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_path path;
    sl_status st = random_views ? sl_path_random_views(scene, vk, g.count, g.seed, &g.opt, NULL, &path, &err)
                                : sl_path_generate(scene, &g.opt, NULL, &path, &err);
    sl_scene_destroy(scene);
    if (st != SL_OK)
        return cli_fail(a.cmd, &err);
    st = sl_path_save(path, g.output, &err);
    if (st == SL_OK) {
        char what[96];
        snprintf(what, sizeof what, "%s%s, seed %llu", random_views ? "random " : "", kind, (unsigned long long)g.seed);
        print_stats(g.output, path, g.json, what);
    }
    sl_path_destroy(path);
    return st == SL_OK ? 0 : cli_fail(a.cmd, &err);
}

static int run_info(int argc, char **argv, bool check)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = check ? "path check" : "path info";
    const char *name, *val;
    cli_common com = {0};
    while (cli_next(&a, &name, &val))
        if (!cli_common_option(&a, name, val, CLI_INPUT | CLI_JSON, &com))
            cli_unknown(&a, name);
    if (com.help) {
        usage_info(stdout, check ? "check" : "info");
        return 0;
    }
    if (a.error) {
        if (a.unknown[0])
            cli_suggest_option(a.cmd, a.unknown, usage_main);
        return 2;
    }
    const char *file = com.input;
    bool json = com.json;
    if (!file) {
        cli_error(a.cmd, "missing PATH.txt (see sightline %s --help)", a.cmd);
        return 2;
    }
    sl_error err;
    sl_path p;
    if (sl_path_load(file, NULL, &p, &err) != SL_OK) {
        if (check && json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            cli_json_string(&j, "file", file);
            cli_json_bool(&j, "valid", false);
            cli_json_string(&j, "error", err.message);
            cli_json_end(&j);
        }
        return cli_fail(a.cmd, &err);
    }
    if (check) {
        sl_path_stats s;
        sl_path_get_stats(p, &s);
        if (json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            cli_json_string(&j, "file", file);
            cli_json_bool(&j, "valid", true);
            cli_json_uint(&j, "frames", s.frames);
            cli_json_double(&j, "duration_s", s.duration);
            cli_json_end(&j);
        } else {
            printf("%s: ok, %u poses over %.3f s\n", file, s.frames, s.duration);
        }
    } else {
        print_stats(file, p, json, NULL);
    }
    sl_path_destroy(p);
    return 0;
}

int sl_cmd_path(int argc, char **argv)
{
    static const char *const actions[] = {"gen", "random", "info", "check"};
    int status, k = cli_action(argc, argv, "path", usage_main, actions, (int)(sizeof actions / sizeof *actions), &status);
    if (k < 0)
        return status;
    return k < 2 ? run_gen(argc - 1, argv + 1, k == 1) : run_info(argc - 1, argv + 1, k == 3);
}

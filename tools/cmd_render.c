/* `sightline render`: images of what a camera sees, from the exact point oracle: the object-id
 * buffer (each object in its own colour), the depth image and the depth-complexity (overdraw)
 * image, as PNG, for one camera or for the frames of a path.
 *
 * Each kind of image is a "mode": a name, a line of help, and a function that writes one frame's
 * image. Adding an image (say a method's cull map) is one function and one line in `modes[]`; the
 * option `--NAME` then selects it (as does `--images NAME,...`), and the mode may keep state for
 * the whole run through its optional setup/cleanup hooks. */
#include "cli.h"

#include "tool.h"
#include "sightline/bench.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/truth.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "sightline/urban.h"

#define DEG (M_PI / 180.0)

/* What a mode sees of the current frame. The oracle has rendered the frame (view 0) before any
 * mode runs. */
typedef struct render_ctx {
    const char *cmd;
    sl_scene scene;
    sl_oracle oracle;
    sl_view view;              /* this frame's view (of its camera, or of --view-matrix/--proj-matrix with
                                  a finite far plane: the one the oracle drew) */
    uint32_t frame;            /* frame number (path index, 0 for --camera) */
    const sl_oracle_frame *truth;
    void *state;               /* the mode's own, from its setup hook */
} render_ctx;

typedef struct render_mode {
    const char *name;          /* file suffix and option name (--NAME) */
    bool default_on;           /* written when neither --images nor a mode option is given */
    bool needs_overdraw;       /* the oracle must count fragments per pixel */
    const char *help;
    /* optional: once before the first frame / after the last (state lives in ctx->state) */
    sl_status (*setup)(render_ctx *ctx, sl_error *err);
    void (*cleanup)(render_ctx *ctx);
    /* write this frame's image to file */
    sl_status (*write)(render_ctx *ctx, const char *file, sl_error *err);
} render_mode;

static sl_status write_ids(render_ctx *ctx, const char *file, sl_error *err)
{
    sl_oracle_view v;
    sl_status st = sl_oracle_get_view(ctx->oracle, 0, &v, err);
    return st == SL_OK ? sl_image_write_ids(&v, file, NULL, err) : st;
}

static sl_status write_depth(render_ctx *ctx, const char *file, sl_error *err)
{
    sl_oracle_view v;
    sl_status st = sl_oracle_get_view(ctx->oracle, 0, &v, err);
    return st == SL_OK ? sl_image_write_depth_view(&v, &ctx->view, file, NULL, err) : st;
}

static sl_status write_overdraw(render_ctx *ctx, const char *file, sl_error *err)
{
    sl_oracle_view v;
    sl_status st = sl_oracle_get_view(ctx->oracle, 0, &v, err);
    return st == SL_OK ? sl_image_write_overdraw(&v, file, NULL, NULL, err) : st;
}

static sl_status write_cullmap(render_ctx *ctx, const char *file, sl_error *err)
{
    return sl_cullmap_render_png_view(ctx->scene, &ctx->view, NULL, file, err);
}

/* The image kinds, in the order they are written. */
static const render_mode modes[] = {
    {"id", true, false, "object-id buffer, each object in its own colour (sl_id_color), black = nothing", NULL, NULL,
     write_ids},
    {"depth", true, false, "distance from the camera, nearest bright, log scale, normalised per image", NULL, NULL,
     write_depth},
    {"overdraw", true, true, "depth complexity: fragments per pixel on a colour ramp, 0 black, the image's max yellow",
     NULL, NULL, write_overdraw},
    {"cullmap", false, false,
     "the viewpoint's cull map from above: occluder-shadow heights over the city, visible footprints, the frustum "
     "(cullmap method; 2.5D scenes with footprints)",
     NULL, NULL, write_cullmap},
};
#define MODE_COUNT (sizeof modes / sizeof modes[0])

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline render SCENE (--camera \"x,y,z,yaw,pitch,roll[,fov]\" | --path FILE [--frames A:B]\n"
            "                        | --view-matrix M --proj-matrix M [--clip-depth D])\n"
            "                        [--width W --height H] [--out DIR] [options]\n\n"
            "Render the exact id buffer of the point oracle for one camera or for the frames of a path, and\n"
            "write images as PNG into DIR, named frame-NNNNN-KIND.png. Kinds:\n");
    for (size_t m = 0; m < MODE_COUNT; m++)
        fprintf(out, "  %-10s %s%s\n", modes[m].name, modes[m].help, modes[m].default_on ? "" : " (not by default)");
    fprintf(out,
            "\nSCENE is city:tiny|small|vienna[:SEED] (generated on the fly) or a file: .slscene, a Quake III\n"
            ".bsp or .pk3 (with --map), or any format assimp reads.\n\n"
            "options:\n"
            "  --camera C        x,y,z,yaw,pitch,roll[,fov]: metres, degrees (yaw 0 looks along +X, 90 along\n"
            "                    +Y; pitch > 0 up; fov vertical, default 60)\n"
            "  --path FILE       a path file (docs/paths.md): its cameras\n"
            "  --view-matrix M   an engine's world-to-eye matrix: 16 comma-separated numbers, column-major\n"
            "                    (OpenGL order: m[12..14] is the translation); rigid, either handedness\n"
            "  --proj-matrix M   its eye-to-clip matrix, 16 numbers, column-major: perspective or\n"
            "                    orthographic, off-axis, x/y-flipped (Vulkan), finite or infinite far\n"
            "  --clip-depth D    the projection's depth range: gl ([-1,1], default), zero-one (D3D, Vulkan,\n"
            "                    Metal [0,1]) or reversed (reversed-z: near 1, far 0); the view is\n"
            "                    normalised to an unmirrored OpenGL view (docs/culler-contract.md, \"Views\");\n"
            "                    an infinite far plane is bounded by the scene\n"
            "  --frames A:B      with --path: frames A to B-1 (A:, :B and A also work; default all)\n"
            "  --width W         image width (default 1024, or the path's)\n"
            "  --height H        image height (default 768, or the path's)\n"
            "  --out DIR         output folder (default render-out); the images are moved in only when\n"
            "                    all are written, other files in DIR are left alone\n"
            "  --images LIST     comma-separated kinds to write (default:");
    for (size_t m = 0, k = 0; m < MODE_COUNT; m++)
        if (modes[m].default_on)
            fprintf(out, "%s%s", k++ ? "," : " ", modes[m].name);
    fprintf(out, ")\n"
                 "  --KIND            add one kind (e.g. --depth); with any of these only the named kinds are\n"
                 "                    written\n"
                 "  --threads T       oracle threads (default 2)\n"
                 "  --map NAME        map inside a .pk3\n"
                 CLI_ALLOW_EXTERNAL_HELP
                 "  --json            list the files written as JSON on stdout\n"
                 "  --quiet           no progress bar\n"
                 "  --help            this text\n\n"
                 "examples:\n"
                 "  sightline render city:tiny --camera \"0,0,1.7,45,0,0\" --out shots\n"
                 "  sightline render city.slscene --path walk.txt --frames 0:10 --images id,depth\n"
                 "  sightline render city:small --camera \"0,0,300,30,-45,0,70\" --width 1920 --height 1080\n"
                 "  sightline render city:tiny --clip-depth reversed --view-matrix 0,0,-1,0,-1,0,0,0,0,1,0,0,0,-1.7,0,1 \\\n"
                 "      --proj-matrix 1.299038,0,0,0,0,1.732051,0,0,0,0,0,-1,0,0,0.1,0   (reversed-z, infinite far:\n"
                 "      the view of --camera 0,0,1.7,0,0,0 at 1024x768)\n");
}

/* "x,y,z,yaw,pitch,roll[,fov]" (degrees) into a camera. */
static bool parse_camera(const char *text, sl_camera *cam)
{
    return sl_parse_camera_spec(text, cam); /* src/core/text_parse.c */
}

static int find_mode(const char *name)
{
    for (size_t m = 0; m < MODE_COUNT; m++)
        if (!strcmp(modes[m].name, name))
            return (int)m;
    return -1;
}

int sl_cmd_render(int argc, char **argv)
{
    const char *cmd = argv[0];
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_import imp = {0};
    const char *name, *val, *camera_text = NULL, *path_file = NULL, *frames = NULL;
    const char *view_text = NULL, *proj_text = NULL, *depth_text = NULL;
    const char *out_dir = "render-out", *images = NULL;
    uint32_t width = 0, height = 0, threads = 2;
    bool selected[MODE_COUNT] = {false}, any_selected = false;
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_MAP | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!strcmp(name, "camera")) {
            camera_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "path")) {
            path_file = cli_value(&a, name, val);
        } else if (!strcmp(name, "view-matrix")) {
            view_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "proj-matrix")) {
            proj_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "clip-depth")) {
            depth_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "frames")) {
            frames = cli_value(&a, name, val);
        } else if (!strcmp(name, "width")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &width);
        } else if (!strcmp(name, "height")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &height);
        } else if (!strcmp(name, "out")) {
            out_dir = cli_value(&a, name, val);
        } else if (!strcmp(name, "images")) {
            images = cli_value(&a, name, val);
        } else if (!strcmp(name, "threads")) {
            cli_parse_threads(&a, name, cli_value(&a, name, val), false, &threads);
        } else if (cli_import_option(&a, name, val, &imp)) {
        } else if (find_mode(name) >= 0 && !val) {
            selected[find_mode(name)] = any_selected = true;
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    const char *scene_spec = com.input, *map = com.map;
    bool json = com.json, quiet = com.quiet;
    if (!scene_spec) {
        cli_error(cmd, "missing SCENE (see --help)");
        return 2;
    }
    bool matrices = view_text || proj_text;
    if ((camera_text != NULL) + (path_file != NULL) + matrices != 1) {
        cli_error(cmd, ((camera_text != NULL) + (path_file != NULL) + matrices)
                           ? "give one of --camera, --path and --view-matrix/--proj-matrix"
                           : "missing --camera or --path (or --view-matrix and --proj-matrix)");
        return 2;
    }
    float vm[16], pm[16];
    sl_clip_depth depth = SL_CLIP_DEPTH_GL;
    if (matrices && (!view_text || !proj_text)) {
        cli_error(cmd, "--view-matrix and --proj-matrix go together");
        return 2;
    }
    if (depth_text && (!matrices || !sl_clip_depth_parse(depth_text, &depth))) {
        cli_error(cmd, matrices ? "--clip-depth '%s': expected gl, zero-one or reversed"
                                : "--clip-depth applies to --view-matrix and --proj-matrix only", depth_text);
        return 2;
    }
    if (matrices && (!sl_parse_floats(view_text, vm, 16) || !sl_parse_floats(proj_text, pm, 16))) {
        cli_error(cmd, "--%s '%s': expected 16 comma-separated finite numbers (column-major)",
                  !sl_parse_floats(view_text, vm, 16) ? "view-matrix" : "proj-matrix",
                  !sl_parse_floats(view_text, vm, 16) ? view_text : proj_text);
        return 2;
    }
    sl_view mview;
    memset(&mview, 0, sizeof mview);
    if (matrices) {
        sl_error verr;
        if (sl_view_from_matrices(vm, pm, depth, width ? width : 1024, height ? height : 768, &mview, &verr) != SL_OK) {
            cli_error(cmd, "%s", verr.message);
            return 2;
        }
    }
    sl_camera cam = sl_camera_default();
    if (camera_text && !parse_camera(camera_text, &cam)) {
        cli_error(cmd, "--camera '%s': expected x,y,z,yaw,pitch,roll[,fov] (metres, degrees)", camera_text);
        return 2;
    }
    uint32_t first = 0, end = UINT32_MAX;
    if (frames && !path_file) {
        cli_error(cmd, "--frames applies to --path only");
        return 2;
    }
    if (frames && !sl_parse_range(frames, &first, &end)) { /* src/core/text_parse.c */
        cli_error(cmd, "--frames '%s': expected A:B with A < B (or A:, :B, A)", frames);
        return 2;
    }
    if ((width == 0) != (height == 0) || width > 16384 || height > 16384) {
        cli_error(cmd, "--width and --height go together, each 1..16384");
        return 2;
    }
    if (images) {
        char buf[512];
        snprintf(buf, sizeof buf, "%s", images);
        for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
            int m = find_mode(tok);
            if (m < 0) {
                cli_error(cmd, "--images: unknown kind '%s' (see --help)", tok);
                return 2;
            }
            selected[m] = any_selected = true;
        }
        if (!any_selected) {
            cli_error(cmd, "--images: empty list");
            return 2;
        }
    }
    bool overdraw = false;
    for (size_t m = 0; m < MODE_COUNT; m++) {
        if (!any_selected)
            selected[m] = modes[m].default_on;
        overdraw |= selected[m] && modes[m].needs_overdraw;
    }
    if (camera_text) {
        cam.width = width ? width : 1024;
        cam.height = height ? height : 768;
        sl_error cerr;
        if (sl_camera_validate(&cam, &cerr) != SL_OK) {
            cli_error(cmd, "--camera: %s", cerr.message);
            return 2;
        }
    }

    sl_error err;
    sl_path path = NULL;
    if (path_file) {
        if (sl_path_load(path_file, NULL, &path, &err) != SL_OK)
            return cli_fail(cmd, &err);
        uint32_t n = sl_path_count(path);
        if (first >= n) {
            cli_error(cmd, "%s: --frames %s starts beyond its %u frames", path_file, frames ? frames : "", n);
            sl_path_destroy(path);
            return 1;
        }
        end = TOOL_MIN(end, n);
    } else {
        end = 1;
    }
    /* the images go to a new folder first, moved into OUT only when every one is written */
    cli_outdir od;
    if (!cli_outdir_begin(cmd, out_dir, &od)) {
        sl_path_destroy(path);
        return 1;
    }
    const char *inputs[2] = {scene_spec, path_file};
    od.inputs = inputs;
    od.input_count = 2;
    cli_progress_state ps;
    sl_progress prog = cli_progress(&ps, quiet || json);
    sl_scene scene = NULL;
    char label[128];
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&imp, &io);
    if (cli_open_scene(scene_spec, map, &io, &prog, &scene, label, sizeof label, &err) != SL_OK) {
        cli_progress_done(&ps);
        cli_outdir_abort(&od);
        sl_path_destroy(path);
        return cli_fail(cmd, &err);
    }
    cli_progress_done(&ps);
    sl_oracle_options oo = sl_oracle_default_options();
    oo.threads = threads;
    oo.count_overdraw = overdraw;
    sl_oracle oracle = NULL;
    int status = 0;
    if (matrices && isinf(mview.far_plane)) {
        /* the depth image needs a finite far plane: the one the oracle bounds it to */
        sl_aabb world = sl_scene_bounds(scene);
        if (sl_view_bound_far(&mview, &world, &mview, &err) != SL_OK)
            status = cli_fail(cmd, &err);
    }
    render_ctx ctx[MODE_COUNT];
    bool set_up[MODE_COUNT] = {false};
    memset(ctx, 0, sizeof ctx);
    if (sl_oracle_create(scene, &oo, NULL, &oracle, &err) != SL_OK)
        status = cli_fail(cmd, &err);
    for (size_t m = 0; m < MODE_COUNT && !status; m++) {
        ctx[m].cmd = cmd;
        ctx[m].scene = scene;
        ctx[m].oracle = oracle;
        if (selected[m] && modes[m].setup) {
            if (modes[m].setup(&ctx[m], &err) != SL_OK)
                status = cli_fail(cmd, &err);
            else
                set_up[m] = true;
        }
    }
    cli_json j;
    if (json && !status) {
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "scene", label);
        cli_json_string(&j, "out", out_dir);
        cli_json_array_begin(&j, "frames");
    }
    uint32_t written = 0;
    char file[4400], shown[4400];
    for (uint32_t f = first; f < end && !status; f++) {
        tool_progress(&prog, "rendering", f - first, end - first);
        sl_camera c = cam;
        if (path) {
            c = sl_path_camera(path, f);
            if (width) {
                c.width = width;
                c.height = height;
            }
        }
        sl_view fv = mview;
        sl_oracle_frame truth;
        if ((!matrices && sl_view_from_camera(&c, &fv, &err) != SL_OK) || sl_oracle_render_view(oracle, &fv, &truth, &err) != SL_OK) {
            tool_error_prefix(&err, "frame %u", f);
            status = cli_fail(cmd, &err);
            break;
        }
        if (json) {
            cli_json_object_begin(&j, NULL);
            cli_json_uint(&j, "frame", f);
            cli_json_uint(&j, "visible", truth.visible_count);
            cli_json_double(&j, "oracle_ms", truth.ms);
            cli_json_array_begin(&j, "files");
        }
        for (size_t m = 0; m < MODE_COUNT && !status; m++) {
            if (!selected[m])
                continue;
            ctx[m].view = fv;
            ctx[m].frame = f;
            ctx[m].truth = &truth;
            snprintf(file, sizeof file, "%s/frame-%05u-%s.png", od.stage, f, modes[m].name);
            snprintf(shown, sizeof shown, "%s/frame-%05u-%s.png", out_dir, f, modes[m].name);
            if (modes[m].write(&ctx[m], file, &err) != SL_OK) {
                status = cli_fail(cmd, &err);
                break;
            }
            written++;
            if (json)
                cli_json_string(&j, NULL, shown);
        }
        if (json) {
            cli_json_array_end(&j);
            cli_json_object_end(&j);
        }
    }
    tool_progress(&prog, "rendering", end - first, end - first);
    cli_progress_done(&ps);
    if (status)
        cli_outdir_abort(&od);
    else if (!cli_outdir_commit(cmd, &od))
        status = 1;
    if (json && !status) {
        cli_json_array_end(&j);
        cli_json_uint(&j, "images", written);
        cli_json_end(&j);
    } else if (json) {
        fputc('\n', stdout);
    } else if (!status) {
        printf("%u image%s of %u frame%s written to %s/\n", written, written == 1 ? "" : "s", end - first,
               end - first == 1 ? "" : "s", out_dir);
    }
    for (size_t m = 0; m < MODE_COUNT; m++)
        if (set_up[m] && modes[m].cleanup)
            modes[m].cleanup(&ctx[m]);
    sl_oracle_destroy(oracle);
    sl_scene_destroy(scene);
    sl_path_destroy(path);
    return status;
}

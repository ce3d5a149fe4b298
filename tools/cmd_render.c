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
#include <unistd.h>
#ifdef SL_HAVE_GL
#include "sightline/render.h"
#include <sys/wait.h>
#define SL_ORACLE_DEFAULT false /* with the renderer, `shaded` is the default kind */
#else
#define SL_ORACLE_DEFAULT true
#endif

#define DEG (M_PI / 180.0)

/* The run's settings a mode may need (the shaded kind: the renderer, the culler, the outputs). */
typedef struct render_settings {
    const char *stage, *out_dir;   /* where files are written now / where they end up */
    const char *method, *method_options; /* the culler (NULL: none, every object drawn) */
    const char *video;             /* --video FILE.mp4, or NULL */
    float fps;                     /* the video's frame rate */
    int context;                   /* sl_gl_context_kind */
    bool depth_prepass;
    bool quiet;
} render_settings;

/* What a mode sees of the current frame. The oracle has rendered the frame (view 0) before any
 * mode that needs it runs (truth is NULL when no selected mode needs the oracle). */
typedef struct render_ctx {
    const render_settings *settings;
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
    bool needs_oracle;         /* the oracle renders each frame before the mode writes */
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

/* Is `name` an executable in PATH? */
static bool in_path(const char *name)
{
    const char *path = getenv("PATH");
    char buf[4200];
    for (const char *p = path ? path : "/usr/bin:/bin"; *p;) {
        const char *e = strchr(p, ':');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        snprintf(buf, sizeof buf, "%.*s/%s", (int)n, p, name);
        if (n && access(buf, X_OK) == 0)
            return true;
        p += n + (e ? 1 : 0);
    }
    return false;
}

#ifdef SL_HAVE_GL
/* ---- shaded: the OpenGL renderer, headless (docs/render.md) ---- */

typedef struct shaded_state {
    sl_renderer r;
    sl_culler culler;
    uint32_t *ids;
    uint32_t width, height;
    sl_output csv, json;
    uint32_t rows;
    FILE *video;                /* ffmpeg's stdin */
    pid_t video_pid;
    char video_tmp[4200];
    uint8_t *rgba;
    bool failed;
} shaded_state;

static sl_status shaded_setup(render_ctx *ctx, sl_error *err)
{
    shaded_state *st = calloc(1, sizeof *st);
    if (!st)
        return tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "shaded: out of memory");
    ctx->state = st;
    st->video_pid = -1;
    char file[4400];
    snprintf(file, sizeof file, "%s/frames.csv", ctx->settings->stage);
    sl_status s = sl_output_open(file, NULL, &st->csv, err);
    if (s != SL_OK)
        return s;
    fprintf(sl_output_stream(st->csv), "frame,method,width,height,frame_ms,cull_ms,draw_ms,finish_ms,gpu_draw_ms,"
                                       "objects_drawn,triangles_drawn,draw_calls,queries,wait_ms\n");
    snprintf(file, sizeof file, "%s/frames.json", ctx->settings->stage);
    if ((s = sl_output_open(file, NULL, &st->json, err)) != SL_OK)
        return s;
    return SL_OK;
}

/* Start ffmpeg reading raw RGBA frames of w x h on its stdin, writing the video to a temporary
 * name beside the target (renamed when it exits cleanly). */
static sl_status video_start(render_ctx *ctx, shaded_state *st, uint32_t w, uint32_t h, sl_error *err)
{
    const render_settings *rs = ctx->settings;
    snprintf(st->video_tmp, sizeof st->video_tmp, "%s.tmp-%ld.mp4", rs->video, (long)getpid());
    char size[32], rate[32];
    snprintf(size, sizeof size, "%ux%u", w, h);
    snprintf(rate, sizeof rate, "%g", rs->fps);
    int fds[2];
    if (pipe(fds) != 0)
        return tool_fail(err, SL_ERROR_IO, "--video: pipe: %s", strerror(errno));
    pid_t pid = fork();
    if (pid < 0) {
        close(fds[0]);
        close(fds[1]);
        return tool_fail(err, SL_ERROR_IO, "--video: fork: %s", strerror(errno));
    }
    if (pid == 0) {
        dup2(fds[0], 0);
        close(fds[0]);
        close(fds[1]);
        /* even sizes for yuv420p; mpeg4 is in every libavcodec */
        execlp("ffmpeg", "ffmpeg", "-nostdin", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgba",
               "-video_size", size, "-framerate", rate, "-i", "pipe:0", "-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2",
               "-c:v", "mpeg4", "-q:v", "3", "-pix_fmt", "yuv420p", "-f", "mp4", st->video_tmp, (char *)NULL);
        _exit(127);
    }
    close(fds[0]);
    st->video = fdopen(fds[1], "wb");
    st->video_pid = pid;
    if (!st->video)
        return tool_fail(err, SL_ERROR_IO, "--video: fdopen: %s", strerror(errno));
    return SL_OK;
}

/* Close ffmpeg's input and wait; on success rename the video into place. */
static sl_status video_finish(shaded_state *st, const char *target, bool keep, sl_error *err)
{
    if (st->video_pid < 0)
        return SL_OK;
    bool write_ok = st->video && fflush(st->video) == 0;
    if (st->video)
        fclose(st->video);
    st->video = NULL;
    int status = 0;
    while (waitpid(st->video_pid, &status, 0) < 0 && errno == EINTR) {
    }
    st->video_pid = -1;
    bool ok = write_ok && WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (!keep || !ok) {
        unlink(st->video_tmp);
        if (keep)
            return tool_fail(err, SL_ERROR_IO, "--video %s: ffmpeg failed (exit status %d)", target,
                                  WIFEXITED(status) ? WEXITSTATUS(status) : -1);
        return SL_OK;
    }
    if (rename(st->video_tmp, target) != 0) {
        int e = errno;
        unlink(st->video_tmp);
        return tool_fail(err, SL_ERROR_IO, "--video %s: rename: %s", target, strerror(e));
    }
    return SL_OK;
}

static sl_status shaded_write(render_ctx *ctx, const char *file, sl_error *err)
{
    shaded_state *st = ctx->state;
    const render_settings *rs = ctx->settings;
    uint32_t w = ctx->view.width, h = ctx->view.height;
    sl_status s = SL_OK;
    if (!st->r) {
        sl_renderer_options o;
        sl_renderer_options_default(&o);
        o.width = w;
        o.height = h;
        o.context = (sl_gl_context_kind)rs->context;
        o.depth_prepass = rs->depth_prepass;
        if ((s = sl_renderer_create(ctx->scene, &o, NULL, &st->r, err)) != SL_OK)
            return s;
        st->width = w;
        st->height = h;
        st->ids = malloc(((size_t)sl_scene_object_count(ctx->scene) + 1) * 4);
        if (!st->ids)
            return tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "shaded: out of memory");
        if (rs->method) {
            /* the renderer's culler: a method that draws (gl-stopwait, chc, chc++) gets the GL
             * backend and draws the frame while it culls; gpu-hiz is the render layer's own */
            if ((s = sl_renderer_create_culler(st->r, rs->method, rs->method_options, &st->culler, err)) != SL_OK)
                return s;
        }
        sl_renderer_info info;
        sl_renderer_get_info(st->r, &info);
        if (info.texture_warning[0])
            fprintf(stderr, "%s: warning: %s\n", ctx->cmd, info.texture_warning);
        static const char *kinds[] = {"auto", "surfaceless", "device", "current"};
        FILE *j = sl_output_stream(st->json);
        fprintf(j, "{\"renderer\":{\"vendor\":\"%s\",\"renderer\":\"%s\",\"version\":\"%s\",\"context\":\"%s\","
                   "\"reversed_z\":%s,\"timer_queries\":%s},\n \"method\":\"%s\",\"options\":\"%s\",\n \"frames\":[",
                info.vendor, info.renderer, info.version, kinds[info.context & 3], info.reversed_z ? "true" : "false",
                info.timer_queries ? "true" : "false", rs->method ? rs->method : "none",
                st->culler ? sl_culler_options(st->culler) : "");
        if (rs->video) {
            if (!(st->rgba = malloc((size_t)w * h * 4)))
                return tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "shaded: out of memory");
            if ((s = video_start(ctx, st, w, h, err)) != SL_OK)
                return s;
        }
    }
    if (w != st->width || h != st->height) {
        if (st->video)
            return tool_fail(err, SL_ERROR_INVALID_ARGUMENT,
                                  "--video: frame %u is %ux%u, the video's frames are %ux%u", ctx->frame, w, h,
                                  st->width, st->height);
        if ((s = sl_renderer_resize(st->r, w, h, err)) != SL_OK)
            return s;
        st->width = w;
        st->height = h;
    }
    sl_render_frame_stats fs;
    uint32_t count = 0;
    if ((s = sl_renderer_frame(st->r, st->culler, &ctx->view, SL_RENDER_SHADED, st->ids, &count, &fs, err)) != SL_OK ||
        (s = sl_renderer_write_png(st->r, file, err)) != SL_OK)
        return s;
    if (st->video) {
        if ((s = sl_renderer_read_rgba(st->r, st->rgba, err)) != SL_OK)
            return s;
        if (fwrite(st->rgba, 4, (size_t)w * h, st->video) != (size_t)w * h)
            return tool_fail(err, SL_ERROR_IO, "--video: writing to ffmpeg: %s", strerror(errno));
    }
    const char *m = rs->method ? rs->method : "none";
    fprintf(sl_output_stream(st->csv), "%u,%s,%u,%u,%.4f,%.4f,%.4f,%.4f,%.4f,%u,%llu,%u,%llu,%.4f\n", ctx->frame, m, w, h,
            fs.frame_ms, fs.cull_ms, fs.draw_ms, fs.finish_ms, fs.gpu_draw_ms, fs.objects_drawn,
            (unsigned long long)fs.triangles_drawn, fs.draw_calls, (unsigned long long)fs.queries, fs.wait_ms);
    fprintf(sl_output_stream(st->json),
            "%s\n  {\"frame\":%u,\"frame_ms\":%.4f,\"cull_ms\":%.4f,\"draw_ms\":%.4f,\"finish_ms\":%.4f,"
            "\"gpu_draw_ms\":%.4f,\"objects_drawn\":%u,\"triangles_drawn\":%llu,\"draw_calls\":%u,\"queries\":%llu,"
            "\"query_stalls\":%llu,\"wait_ms\":%.4f}",
            st->rows ? "," : "", ctx->frame, fs.frame_ms, fs.cull_ms, fs.draw_ms, fs.finish_ms, fs.gpu_draw_ms,
            fs.objects_drawn, (unsigned long long)fs.triangles_drawn, fs.draw_calls, (unsigned long long)fs.queries,
            (unsigned long long)fs.query_stalls, fs.wait_ms);
    st->rows++;
    return SL_OK;
}

/* Commit the CSV, the JSON and the video (ok: the run succeeded), or drop them. */
static sl_status shaded_finish(render_ctx *ctx, bool ok, sl_error *err)
{
    shaded_state *st = ctx->state;
    if (!st)
        return SL_OK;
    sl_status s = SL_OK;
    if (st->json)
        fprintf(sl_output_stream(st->json), "%s]}\n", st->rows ? "\n " : "");
    if (ok && st->csv)
        s = sl_output_commit(st->csv, err);
    else if (st->csv)
        sl_output_abort(st->csv);
    st->csv = NULL;
    if (ok && s == SL_OK && st->json)
        s = sl_output_commit(st->json, err);
    else if (st->json)
        sl_output_abort(st->json);
    st->json = NULL;
    sl_status v = video_finish(st, ctx->settings->video, ok && s == SL_OK, err);
    return s != SL_OK ? s : v;
}

static void shaded_cleanup(render_ctx *ctx)
{
    shaded_state *st = ctx->state;
    if (!st)
        return;
    sl_error ignored;
    shaded_finish(ctx, false, &ignored);
    sl_culler_destroy(st->culler);
    sl_renderer_destroy(st->r);
    free(st->ids);
    free(st->rgba);
    free(st);
    ctx->state = NULL;
}
#endif

/* The image kinds, in the order they are written. */
static const render_mode modes[] = {
#ifdef SL_HAVE_GL
    {"shaded", true, false, false,
     "the OpenGL renderer's frame, headless (sl_renderer_frame: per-object colour, sun and sky; --methods picks the "
     "culler); also frames.csv and frames.json (frame time, cull time, objects/triangles drawn, queries)",
     shaded_setup, shaded_cleanup, shaded_write},
#endif
    {"id", SL_ORACLE_DEFAULT, false, true, "object-id buffer, each object in its own colour (sl_id_color), black = nothing",
     NULL, NULL, write_ids},
    {"depth", SL_ORACLE_DEFAULT, false, true, "distance from the camera, nearest bright, log scale, normalised per image",
     NULL, NULL, write_depth},
    {"overdraw", SL_ORACLE_DEFAULT, true, true,
     "depth complexity: fragments per pixel on a colour ramp, 0 black, the image's max yellow", NULL, NULL,
     write_overdraw},
    {"cullmap", false, false, false,
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
            "Render frames for one camera, the frames of a path or a walk, and write images as PNG into DIR,\n"
            "named frame-NNNNN-KIND.png: the OpenGL renderer's shaded frames (headless, when built with\n"
            "OpenGL: docs/render.md) and the exact point oracle's id, depth and overdraw images. Kinds:\n");
    for (size_t m = 0; m < MODE_COUNT; m++)
        fprintf(out, "  %-10s %s%s\n", modes[m].name, modes[m].help, modes[m].default_on ? "" : " (not by default)");
    fprintf(out,
            "\nSCENE is city:tiny|small|vienna[:SEED] (generated on the fly) or a file: .slscene, a Quake III\n"
            ".bsp or .pk3 (with --map), or any format assimp reads.\n\n"
            "options:\n"
            "  --camera C        x,y,z,yaw,pitch,roll[,fov]: metres, degrees (yaw 0 looks along +X, 90 along\n"
            "                    +Y; pitch > 0 up; fov vertical, default 60)\n"
            "  --path FILE       a path file (docs/paths.md): its cameras\n"
            "  --walk N          the bench's street-level walk of N frames (sl_path_generate walk; --fps, --seed)\n"
            "  --fps F           walk frames per second and the video's frame rate (default 30)\n"
            "  --seed S          seed of the walk (default 1)\n"
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
                 "shaded frames (built with OpenGL; `sightline render --help` lists shaded among the kinds):\n"
                 "  --methods NAME[:OPTS]  the culler that decides what is drawn (the bench's method grammar:\n"
                 "                    a registry name, `sightline methods`; OPTS key=value,...; default: none,\n"
                 "                    every object drawn)\n"
                 "  --method-options NAME:OPTS  the method's options, as in `sightline bench`\n"
                 "  --video FILE.mp4  also pipe the frames to the ffmpeg command (Debian package ffmpeg; exit 1\n"
                 "                    when it is not installed), written to FILE.mp4 when the run succeeds\n"
                 "  --context KIND    the headless GL context: auto (an EGL device with a hardware driver,\n"
                 "                    else surfaceless; default), device, surfaceless (Mesa llvmpipe)\n"
                 "  --depth-prepass   draw depth first, then colour with an equal depth test\n"
                 "                    Per frame, DIR/frames.csv and DIR/frames.json: frame_ms (start of culling to\n"
                 "                    glFinish), cull_ms, draw_ms, finish_ms, gpu_draw_ms (GL timer query),\n"
                 "                    objects and triangles drawn, draw calls, queries, wait_ms\n"
                 "  --map NAME        map inside a .pk3\n"
                 CLI_ALLOW_EXTERNAL_HELP
                 "  --json            list the files written as JSON on stdout\n"
                 "  --quiet           no progress bar\n"
                 "  --help            this text\n\n"
                 "examples:\n"
                 "  sightline render city:tiny --walk 120 --methods vfc --video walk.mp4 --out walk\n"
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
    uint32_t width = 0, height = 0, threads = 2, walk = 0;
    uint64_t seed = 1;
    float fps = 30.0f;
    bool has_walk = false, depth_prepass = false;
    const char *methods = NULL, *method_options = NULL, *video = NULL, *context_text = NULL;
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
        } else if (!strcmp(name, "walk")) {
            has_walk = cli_parse_u32(&a, name, cli_value(&a, name, val), &walk);
        } else if (!strcmp(name, "fps")) {
            cli_parse_float(&a, name, cli_value(&a, name, val), &fps);
        } else if (!strcmp(name, "seed")) {
            cli_parse_u64(&a, name, cli_value(&a, name, val), &seed);
        } else if (!strcmp(name, "methods")) {
            methods = cli_value(&a, name, val);
        } else if (!strcmp(name, "method-options")) {
            method_options = cli_value(&a, name, val);
        } else if (!strcmp(name, "video")) {
            video = cli_value(&a, name, val);
        } else if (!strcmp(name, "context")) {
            context_text = cli_value(&a, name, val);
        } else if (!strcmp(name, "depth-prepass") && !val) {
            depth_prepass = true;
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
    if ((camera_text != NULL) + (path_file != NULL) + has_walk + matrices != 1) {
        cli_error(cmd, ((camera_text != NULL) + (path_file != NULL) + has_walk + matrices)
                           ? "give one of --camera, --path, --walk and --view-matrix/--proj-matrix"
                           : "missing --camera or --path (or --walk, or --view-matrix and --proj-matrix)");
        return 2;
    }
    if (has_walk && walk == 0) {
        cli_error(cmd, "--walk: at least 1 frame");
        return 2;
    }
    if (!(fps >= 0.001f && fps <= 1000.0f)) {
        cli_error(cmd, "--fps: expected 0.001..1000");
        return 2;
    }
    /* the culler: NAME[:OPTS], or NAME with --method-options NAME:OPTS */
    char method_name[128] = "", method_opts[1024] = "";
    if (methods) {
        const char *colon = strchr(methods, ':');
        size_t n = colon ? (size_t)(colon - methods) : strlen(methods);
        if (n == 0 || n >= sizeof method_name || (strchr(methods, ',') && (!colon || strchr(methods, ',') < colon))) {
            cli_error(cmd, "--methods '%s': expected one method NAME[:key=value,...] (render draws with one culler)",
                      methods);
            return 2;
        }
        snprintf(method_name, sizeof method_name, "%.*s", (int)n, methods);
        if (colon)
            snprintf(method_opts, sizeof method_opts, "%s", colon + 1);
        if (method_options) {
            size_t k = strlen(method_name);
            if (strncmp(method_options, method_name, k) || method_options[k] != ':') {
                cli_error(cmd, "--method-options '%s': expected %s:key=value,...", method_options, method_name);
                return 2;
            }
            if (colon) {
                cli_error(cmd, "--method-options and options in --methods: give one of them");
                return 2;
            }
            snprintf(method_opts, sizeof method_opts, "%s", method_options + k + 1);
        }
        bool render_method = false;
#ifdef SL_HAVE_GL
        for (uint32_t i = 0; i < sl_render_method_count(); i++)
            render_method |= !strcmp(sl_render_method(i)->name, method_name);
#endif
        if (strcmp(method_name, "none") && !render_method) { /* a render-layer method's options: checked at creation */
            sl_error merr;
            uint32_t index;
            if (sl_cull_method_find(method_name, &index, &merr) != SL_OK ||
                sl_cull_method_check_options(method_name, method_opts, &merr) != SL_OK) {
                cli_error(cmd, "--methods: %s", merr.message);
                return 2;
            }
        }
    } else if (method_options) {
        cli_error(cmd, "--method-options needs --methods");
        return 2;
    }
    int context_kind = 0;
    if (context_text) {
        if (!strcmp(context_text, "auto"))
            context_kind = 0;
        else if (!strcmp(context_text, "surfaceless"))
            context_kind = 1;
        else if (!strcmp(context_text, "device"))
            context_kind = 2;
        else {
            cli_error(cmd, "--context '%s': expected auto, device or surfaceless", context_text);
            return 2;
        }
    }
    if (video && (strlen(video) < 5 || strcmp(video + strlen(video) - 4, ".mp4"))) {
        cli_error(cmd, "--video '%s': expected a FILE.mp4", video);
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
    if (frames && !path_file && !has_walk) {
        cli_error(cmd, "--frames applies to --path and --walk only");
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
    bool overdraw = false, need_oracle = false;
    for (size_t m = 0; m < MODE_COUNT; m++) {
        if (!any_selected)
            selected[m] = modes[m].default_on;
        overdraw |= selected[m] && modes[m].needs_overdraw;
        need_oracle |= selected[m] && modes[m].needs_oracle;
    }
    int shaded = find_mode("shaded");
    bool shaded_on = shaded >= 0 && selected[shaded];
    if ((methods || video || context_text || depth_prepass) && !shaded_on) {
        const char *opt = methods ? "--methods" : video ? "--video" : context_text ? "--context" : "--depth-prepass";
        if (shaded < 0)
            cli_error(cmd, "%s: this sightline was built without OpenGL (SL_GL=OFF, or no libopengl-dev/libegl-dev): "
                           "no shaded frames", opt);
        else
            cli_error(cmd, "%s applies to the shaded kind, which --images leaves out", opt);
        return 2;
    }
    if (video && !in_path("ffmpeg")) {
        cli_error(cmd, "--video: the ffmpeg command is not installed (Debian package ffmpeg)");
        return 1;
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
    if (has_walk) {
        end = TOOL_MIN(end, walk); /* generated once the scene is open */
    } else if (path_file) {
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
    if (has_walk) {
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.frames = walk;
        po.fps = fps;
        po.seed = seed;
        po.intrinsics.width = width ? width : 1024;
        po.intrinsics.height = height ? height : 768;
        if (first >= walk || sl_path_generate(scene, &po, NULL, &path, &err) != SL_OK) {
            if (first >= walk)
                cli_error(cmd, "--frames %s starts beyond the walk's %u frames", frames ? frames : "", walk);
            cli_outdir_abort(&od);
            sl_scene_destroy(scene);
            return first >= walk ? 1 : cli_fail(cmd, &err);
        }
    }
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
    render_settings settings = {od.stage, out_dir, method_name[0] && strcmp(method_name, "none") ? method_name : NULL,
                                method_opts[0] ? method_opts : NULL, video, fps, context_kind, depth_prepass, quiet};
    if (!status && need_oracle && sl_oracle_create(scene, &oo, NULL, &oracle, &err) != SL_OK)
        status = cli_fail(cmd, &err);
    for (size_t m = 0; m < MODE_COUNT && !status; m++) {
        ctx[m].settings = &settings;
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
        memset(&truth, 0, sizeof truth);
        if ((!matrices && sl_view_from_camera(&c, &fv, &err) != SL_OK) ||
            (oracle && sl_oracle_render_view(oracle, &fv, &truth, &err) != SL_OK)) {
            tool_error_prefix(&err, "frame %u", f);
            status = cli_fail(cmd, &err);
            break;
        }
        if (json) {
            cli_json_object_begin(&j, NULL);
            cli_json_uint(&j, "frame", f);
            if (oracle) {
                cli_json_uint(&j, "visible", truth.visible_count);
                cli_json_double(&j, "oracle_ms", truth.ms);
            }
            cli_json_array_begin(&j, "files");
        }
        for (size_t m = 0; m < MODE_COUNT && !status; m++) {
            if (!selected[m])
                continue;
            ctx[m].view = fv;
            ctx[m].frame = f;
            ctx[m].truth = oracle ? &truth : NULL;
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
#ifdef SL_HAVE_GL
    /* the shaded kind's CSV and JSON into the stage, its video into place */
    if (shaded_on && set_up[shaded] && !status && shaded_finish(&ctx[shaded], true, &err) != SL_OK)
        status = cli_fail(cmd, &err);
#endif
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

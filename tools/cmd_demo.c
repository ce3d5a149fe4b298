/* `sightline demo`: the README's first command ends here. Generates the default city, walks
 * through its streets and looks down from a few flyover viewpoints with every registered culling
 * method judged by the exact oracle, and writes a small report (report.html and report.md with
 * images, plots and the summary tables) into a folder. Methods appear in it as they land in the
 * registry. Exits 1 when a conservative method dropped a visible object. */
#include "cli.h"
#include "pvs_cli.h"

#include "tool.h"
#include "sightline/bench.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/region.h"
#include "sightline/truth.h"
#ifdef SL_HAVE_GL
#include "sightline/render.h"
#endif

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define DEMO_WALK_FRAMES 600
#define DEMO_WALK_FPS 5.0f
#define DEMO_FLY_VIEWS 24
#define QUICK_WALK_FRAMES 40
#define QUICK_FLY_VIEWS 4
/* the map thumbnails' longer side in pixels: twice the report grid's 170 px column, for dense screens */
#define DEMO_THUMB_SIZE 340

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline demo [--preset small | --scene FILE] [--seed N] [--out DIR] [--frames N] [--quick]\n"
            "                     [--methods LIST] [--json]\n\n"
            "Generate the default city, run a street-level walkthrough (%u frames at %g fps: a 1.4 m/s walk\n"
            "sampled every %.2f m) and %u random flyover views with every registered culling method (one\n"
            "that cannot run with its default options is named as not run; the pvs culler gets a PVS baked\n"
            "for the street cells along the walk, walk.slpvs, with the %s method), judge every frame\n"
            "with the exact point oracle, and write a report into DIR: report.html and report.md with the\n"
            "verdict and the recommendation first, a table of contents, the results tables (the best value\n"
            "of each column highlighted), plots, a rendered frame (ids, depth, overdraw; shaded with the\n"
            "OpenGL renderer), a grid of top-down visibility maps with a colour key and a scale bar, what\n"
            "each method is and the scene's statistics (docs/bench.md, \"The report\"), plus the raw per-frame\n"
            "frames.csv / frames.json and the walk's path file (walk.txt) to replay with `sightline bench`.\n"
            "Takes well under a few minutes on 2 cores with the small city.\n\n"
            "options:\n"
            "  --preset P    city preset: tiny, small (default), vienna (about 8M triangles: slow), oldtown-small, oldtown\n"
            "  --scene FILE  a scene of your own instead (a .slscene, a GIS file, any file `sightline\n"
            "                import` reads) with a street network for the walk (docs/gis-import.md)\n"
            "  --methods LIST  only these methods, NAME[:key=value...] comma-separated (the grammar of\n"
            "                bench, render and view); pvs without file= runs on the walk's PVS\n"
            "  --seed N      city and walk seed (default 1)\n"
            "  --out DIR     report folder (default demo-out); files moved in only when all are written\n"
            "  --frames N    walkthrough frames (default %u; --quick: %u)\n"
            "  --quick       a short run (%u walk frames, %u flyover views) for a smoke test\n"
            "  --width W --height H   frame size (default 1024x768)\n"
            "  --json        print a machine-readable summary instead of the tables\n"
            "  --quiet       no progress bar\n"
            "  --help        this text\n\n"
            "Exit status: 0 ok, 1 failure or a conservative method missed a visible object, 2 usage error.\n\n"
            "examples:\n"
            "  sightline demo\n"
            "  sightline demo --preset tiny --quick --out /tmp/demo\n"
            "  sightline demo --preset tiny --quick --methods vfc,hzb:res=culling,pvs --out /tmp/demo\n"
            "  sightline demo --preset vienna --frames 300 --out vienna-demo\n",
            DEMO_WALK_FRAMES, (double)DEMO_WALK_FPS, 1.4 / DEMO_WALK_FPS, DEMO_FLY_VIEWS, CLI_PVS_ALONG_METHOD, DEMO_WALK_FRAMES,
            QUICK_WALK_FRAMES, QUICK_WALK_FRAMES, QUICK_FLY_VIEWS);
}

#ifdef SL_HAVE_GL
/* The walk frame shaded, and the same view from above with the oracle's visible set highlighted
 * (frame-shaded.png, frame-above.png in work). Without a GL context the report says why instead. */
static void demo_shaded(sl_scene scene, const sl_camera *cam, const uint32_t *visible, uint32_t nvisible,
                        const char *work, const char *images[2], char *note, size_t note_size)
{
    static const char *files[2] = {"frame-shaded.png", "frame-above.png"};
    sl_error err;
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = cam->width;
    o.height = cam->height;
    sl_renderer r = NULL;
    uint32_t n = sl_scene_object_count(scene);
    uint32_t *colors = calloc(n ? n : 1, 4);
    char path[4400];
    sl_view v;
    sl_status st = colors ? sl_renderer_create(scene, &o, NULL, &r, &err)
                          : tool_fail(&err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
    if (st == SL_OK && (st = sl_view_from_camera(cam, &v, &err)) == SL_OK &&
        (st = sl_renderer_frame(r, NULL, &v, SL_RENDER_SHADED, NULL, NULL, NULL, &err)) == SL_OK) {
        snprintf(path, sizeof path, "%s/%s", work, files[0]);
        st = sl_renderer_write_png(r, path, &err);
    }
    if (st == SL_OK) {
        /* from 150 m above the walker, looking down, the walker's heading up in the image */
        sl_camera above = *cam;
        above.position.z += 150.0f;
        above.pitch = (float)(-89.0 * M_PI / 180.0);
        above.roll = 0.0f;
        above.fov_y = (float)(60.0 * M_PI / 180.0);
        above.near_plane = 1.0f;
        above.far_plane = 2000.0f;
        for (uint32_t i = 0; i < n; i++)
            colors[i] = sl_scene_object(scene, i).kind == SL_KIND_GROUND ? 0xB4B4B4FFu : 0x8C8C8CFFu;
        for (uint32_t k = 0; k < nvisible; k++)
            if (visible[k] < n)
                colors[visible[k]] = sl_scene_object(scene, visible[k]).kind == SL_KIND_GROUND ? 0xF2D3A0FFu : 0xFF8C1AFFu;
        if ((st = sl_view_from_camera(&above, &v, &err)) == SL_OK && (st = sl_renderer_set_colors(r, colors, &err)) == SL_OK &&
            (st = sl_renderer_frame(r, NULL, &v, SL_RENDER_SHADED, NULL, NULL, NULL, &err)) == SL_OK) {
            snprintf(path, sizeof path, "%s/%s", work, files[1]);
            st = sl_renderer_write_png(r, path, &err);
        }
    }
    if (st == SL_OK) {
        images[0] = files[0];
        images[1] = files[1];
    } else {
        snprintf(note, note_size, "No shaded frames: %s", err.message);
    }
    sl_renderer_destroy(r);
    free(colors);
}
#endif

/* ---- report writing ---- */

typedef struct report {
    sl_output md, html;
} report;

/* A write error is sticky in the stream and reported by sl_output_commit; nothing more is written
 * after one. */
static void put(sl_output *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(sl_output *f, const char *fmt, ...)
{
    FILE *fp = sl_output_stream(*f);
    if (ferror(fp))
        return;
    va_list ap;
    va_start(ap, fmt);
    vfprintf(fp, fmt, ap);
    va_end(ap);
}

/* HTML text with &, <, > and " escaped. */
static void put_html(sl_output *f, const char *s)
{
    for (; s && *s; s++) {
        if (*s == '&')
            put(f, "&amp;");
        else if (*s == '<')
            put(f, "&lt;");
        else if (*s == '>')
            put(f, "&gt;");
        else if (*s == '"')
            put(f, "&quot;");
        else
            put(f, "%c", *s);
    }
}

/* Markdown table cell text: pipes escaped, line breaks as spaces. */
static void put_md(sl_output *f, const char *s)
{
    for (; s && *s; s++) {
        if (*s == '|')
            put(f, "\\|");
        else if (*s == '\n')
            put(f, "; ");
        else
            put(f, "%c", *s);
    }
}

static const char *grouped(char *buf, size_t n, double v)
{
    char raw[64];
    snprintf(raw, sizeof raw, "%.0f", v);
    size_t len = strlen(raw), o = 0;
    for (size_t i = 0; i < len && o + 2 < n; i++) {
        buf[o++] = raw[i];
        size_t left = len - 1 - i;
        if (left && left % 3 == 0 && raw[i] != '-')
            buf[o++] = ',';
    }
    buf[o] = 0;
    return buf;
}

/* An image in both reports (path relative to the report), with its caption. */
static void put_image(report *r, const char *file, const char *caption)
{
    put(&r->md, "![%s](%s)\n\n*%s*\n\n", caption, file, caption);
    put(&r->html, "<figure><a href=\"%s\"><img src=\"%s\" alt=\"", file, file);
    put_html(&r->html, caption);
    put(&r->html, "\"></a><figcaption>");
    put_html(&r->html, caption);
    put(&r->html, "</figcaption></figure>\n");
}

/* A section heading with an anchor (id) for the table of contents; Markdown viewers derive the
 * same anchors from the text. */
static void put_section(report *r, const char *id, const char *text)
{
    put(&r->md, "## %s\n\n", text);
    put(&r->html, "<h2 id=\"%s\">", id);
    put_html(&r->html, text);
    put(&r->html, "</h2>\n");
}

static void put_para(report *r, const char *text)
{
    put(&r->md, "%s\n\n", text);
    put(&r->html, "<p>");
    put_html(&r->html, text);
    put(&r->html, "</p>\n");
}

/* The sections, in order: anchor and title (the table of contents lists them). */
static const char *const sections[][2] = {
    {"recommendation", "Recommendation"},
    {"results", "Results"},
    {"plots", "Plots"},
    {"frame", "A frame of the walk"},
    {"shaded", "The frame, shaded"},
    {"maps", "Top-down visibility maps"},
    {"methods", "The methods"},
    {"scene", "The scene"},
    {"further", "Going further"},
};
#define SECTION_COUNT (sizeof sections / sizeof sections[0])

/* The report's style: a readable width on a laptop, wide tables scroll inside their box, the best
 * cell of each column green, violations red, maps in a grid of thumbnails. No external resources. */
static const char report_css[] =
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222;line-height:1.4}"
    "h2{border-bottom:1px solid #ddd;padding-bottom:.2em;margin-top:1.8em}"
    ".scroll{overflow-x:auto;max-width:100%}"
    "table{border-collapse:collapse;margin:.6em 0;font-size:.92em}"
    "td,th{border:1px solid #ccc;padding:3px 7px;text-align:right;vertical-align:top}"
    "td:first-child,th:first-child,td.l,th.l{text-align:left}"
    "th{background:#f4f4f4}"
    ".best{background:#c8efc8;font-weight:bold}"
    ".bad{background:#f66;color:#000;font-weight:bold}"
    ".pick{font-size:.8em;color:#1a5c1a;margin-left:.4em;white-space:nowrap}"
    ".ok{color:#186a18}.fail{color:#c00;font-weight:bold}"
    ".legend{font-size:.9em;color:#444}"
    ".sw{display:inline-block;width:1em;height:1em;border:1px solid #555;vertical-align:-.15em;margin:0 .3em 0 .8em}"
    "nav.toc{background:#f7f7f7;border:1px solid #ddd;padding:.4em 1em;margin:1em 0}"
    "nav.toc ol{margin:.3em 0;padding-left:1.4em;columns:2}"
    "img{max-width:100%;height:auto;border:1px solid #ddd}"
    "figure{margin:1em 0}figcaption{font-size:.9em;color:#444}"
    ".grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(170px,1fr));gap:.6em}"
    ".grid figure{margin:0}.grid img{width:100%}"
    ".pair{display:grid;grid-template-columns:repeat(auto-fit,minmax(320px,1fr));gap:1em}"
    "details{margin:0}summary{cursor:pointer;color:#245}"
    "code{background:#f3f3f3;padding:1px 3px}"
    "details code{display:block;white-space:pre-wrap;overflow-wrap:anywhere;max-width:34em;font-size:.85em}";

/* Which way a column improves: 0 not ranked, -1 lower is better. */
enum { COL_FRAMES, COL_OBJECTS, COL_TRIANGLES, COL_VISIBLE, COL_OVER, COL_MISSED, COL_MISSED_PX, COL_MED, COL_P95,
       COL_MAX, COL_COUNT };
static const char *const col_names[COL_COUNT] = {"frames", "objects drawn", "triangles drawn", "exact visible",
                                                 "over-estimation", "missed objects", "missed pixels",
                                                 "cull ms median", "p95", "max"};
/* the library's ranked column of each (-1: not ranked): sl_bench_best_columns says which is best */
static const int col_rank[COL_COUNT] = {-1, SL_BENCH_COL_OBJECTS, SL_BENCH_COL_TRIANGLES, -1, SL_BENCH_COL_OVERESTIMATION,
                                        SL_BENCH_COL_MISSED_OBJECTS, SL_BENCH_COL_MISSED_PIXELS, SL_BENCH_COL_MS_MEDIAN,
                                        SL_BENCH_COL_MS_P95, SL_BENCH_COL_MS_MAX};

static double col_value(const sl_bench_summary *s, int c)
{
    switch (c) {
    case COL_FRAMES: return s->frames;
    case COL_OBJECTS: return s->objects_drawn_mean;
    case COL_TRIANGLES: return s->triangles_drawn_mean;
    case COL_VISIBLE: return s->visible_mean;
    case COL_OVER: return s->overestimation;
    case COL_MISSED: return (double)s->missed_objects_total;
    case COL_MISSED_PX: return (double)s->missed_pixels_total;
    case COL_MED: return s->cull_ms.median;
    case COL_P95: return s->cull_ms.p95;
    default: return s->cull_ms.max;
    }
}

/* The value shown in a cell, as printed (the best is found among the printed values, so that
 * two cells that read the same are both highlighted or neither). */
static void col_text(char *buf, size_t n, const sl_bench_summary *s, int c)
{
    double v = col_value(s, c);
    switch (c) {
    case COL_FRAMES: case COL_MISSED: case COL_MISSED_PX: snprintf(buf, n, "%.0f", v); break;
    case COL_OBJECTS: case COL_TRIANGLES: case COL_VISIBLE: grouped(buf, n, v); break;
    case COL_OVER: snprintf(buf, n, "%.2f", v); break;
    default: snprintf(buf, n, "%.3f", v); break;
    }
}

/* The results table of one bench in HTML (Markdown comes from sl_bench_print_summary, which
 * prints the same best cells in bold): the best cell of every ranked column (sl_bench_best_columns:
 * all of them on a tie, none when every method ties) has class "best", a conservative method's
 * misses class "bad", the recommended methods a note. */
static void html_summary(report *r, sl_bench b)
{
    uint32_t nm = sl_bench_method_count(b);
    sl_bench_summary *sum = calloc(nm ? nm : 1, sizeof *sum);
    sl_bench_method_info *info = calloc(nm ? nm : 1, sizeof *info);
    bool *ok = calloc(nm ? nm : 1, sizeof *ok);
    if (!sum || !info || !ok) {
        put(&r->html, "<p class=\"fail\">out of memory for the results table</p>\n");
        free(sum), free(info), free(ok);
        return;
    }
    for (uint32_t mi = 0; mi < nm; mi++)
        ok[mi] = sl_bench_method(b, mi, &info[mi], NULL) == SL_OK && sl_bench_summarize(b, mi, &sum[mi], NULL) == SL_OK &&
                 sum[mi].frames > 0;
    char cell[64];
    sl_bench_recommendation rec;
    if (sl_bench_recommend(b, &rec, NULL) != SL_OK)
        rec.fastest = rec.tightest = -1;
    put(&r->html, "<div class=\"scroll\"><table><tr><th>method</th><th class=\"l\">guarantee</th>");
    for (int c = 0; c < COL_COUNT; c++)
        put(&r->html, "<th>%s</th>", col_names[c]);
    put(&r->html, "</tr>\n");
    for (uint32_t mi = 0; mi < nm; mi++) {
        if (!ok[mi])
            continue;
        const sl_bench_summary *s = &sum[mi];
        bool bad = sl_cull_guarantee_keeps_visible(info[mi].guarantee, true) && s->missed_objects_total;
        put(&r->html, "<tr><td>");
        put_html(&r->html, info[mi].name);
        if ((int32_t)mi == rec.fastest)
            put(&r->html, "<span class=\"pick\">&#9733; fastest pick</span>");
        if ((int32_t)mi == rec.tightest)
            put(&r->html, "<span class=\"pick\">&#9733; tightest pick</span>");
        put(&r->html, "</td><td class=\"l\">%s</td>", sl_cull_guarantee_name(info[mi].guarantee));
        uint32_t best = sl_bench_best_columns(b, mi);
        for (int c = 0; c < COL_COUNT; c++) {
            col_text(cell, sizeof cell, s, c);
            bool is_best = col_rank[c] >= 0 && ((best >> col_rank[c]) & 1u);
            const char *cls = (c == COL_MISSED || c == COL_MISSED_PX) && bad ? " class=\"bad\""
                              : is_best                                     ? " class=\"best\""
                                                                            : "";
            put(&r->html, "<td%s>%s</td>", cls, cell);
        }
        put(&r->html, "</tr>\n");
    }
    put(&r->html, "</table></div>\n");
    free(sum), free(info), free(ok);
}

/* The colours of the top-down maps (src/truth/bench_map.c draws them), for the key. */
static const struct {
    const char *color, *text;
} map_key[] = {
    {"#2ca02c", "visible and kept"},
    {"#ff9f1c", "kept although hidden or outside the view (over-estimation)"},
    {"#8c8c8c", "culled, and indeed not visible"},
    {"#e00000", "visible but dropped (ringed in red): a conservative method never shows it"},
    {"#1f5fbf", "the eye (black dot) and its view frustum"},
};

static void write_report_body(report *r, sl_scene scene, const char *label, sl_bench *benches, uint32_t nb,
                              const sl_bench_skip *skipped, uint32_t nskipped, const char *pvs_note,
                              const char *frame_images[3], uint32_t frame_index, const char *shaded_images[2],
                              const char *shaded_note, uint64_t violations, const char *preset, uint64_t seed,
                              const char *scene_file, double seconds)
{
    char text[2048], g1[48], g2[48], g3[48];
    sl_scene_stats ss;
    sl_scene_get_stats(scene, &ss);
    uint32_t nmethods = nb ? sl_bench_method_count(benches[0]) : 0;
    put(&r->md, "# Sightline demo: %s\n\n", label);
    put(&r->html, "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                  "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
                  "<title>Sightline demo: %s</title>\n<style>%s</style></head><body>\n"
                  "<h1>Sightline demo: %s</h1>\n",
        label, report_css, label);

    /* summary: what ran, the verdict */
    put(&r->html, "<div id=\"summary\">\n");
    char scene_what[1200];
    if (scene_file)
        snprintf(scene_what, sizeof scene_what, "the scene %.1000s (seed %llu", label, (unsigned long long)seed);
    else
        snprintf(scene_what, sizeof scene_what, "a procedurally generated city (preset %s, seed %llu", preset, (unsigned long long)seed);
    snprintf(text, sizeof text,
             "%u culling methods ran on the same frames of %s: "
             "a street-level walk and a few flyover views) and were judged against the exact point oracle, which "
             "rasterizes every triangle into an object-id buffer and reports which objects own a pixel. A "
             "conservative method must never drop a visible object. The run took %.1f s.",
             nmethods, scene_what, seconds);
    put_para(r, text);
    if (violations) {
        snprintf(text, sizeof text,
                 "CONSERVATIVENESS VIOLATION: conservative methods dropped %llu visible object(s) in total; see the "
                 "missed objects column (red) and frames.csv.",
                 (unsigned long long)violations);
        put(&r->md, "**%s**\n\n", text);
        put(&r->html, "<p class=\"fail\">%s</p>\n", text);
    } else {
        put(&r->md, "**Every conservative method kept every visible object in every frame (0 missed).**\n\n");
        put(&r->html, "<p class=\"ok\"><b>Every conservative method kept every visible object in every frame "
                      "(0 missed).</b></p>\n");
    }
    put(&r->html, "</div>\n");

    /* the recommendation first: what a reader came for */
    put_section(r, sections[0][0], sections[0][1]);
    for (uint32_t bi = 0; bi < nb; bi++) {
        sl_bench_recommendation rec;
        if (sl_bench_recommend(benches[bi], &rec, NULL) != SL_OK)
            continue;
        snprintf(text, sizeof text, "%s: %s", sl_bench_label(benches[bi]), rec.text);
        put_para(r, text);
    }

    /* the table of contents */
    put(&r->md, "Contents:");
    put(&r->html, "<nav class=\"toc\" id=\"contents\"><b>Contents</b><ol>\n");
    for (size_t i = 0; i < SECTION_COUNT; i++) {
        /* the anchor Markdown viewers make of a heading: lower case, spaces as dashes, no punctuation */
        char slug[64];
        size_t o = 0;
        for (const char *c = sections[i][1]; *c && o + 1 < sizeof slug; c++)
            if ((*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') || *c == '-')
                slug[o++] = *c;
            else if (*c >= 'A' && *c <= 'Z')
                slug[o++] = (char)(*c - 'A' + 'a');
            else if (*c == ' ')
                slug[o++] = '-';
        slug[o] = 0;
        put(&r->md, "%s [%s](#%s)", i ? " ·" : "", sections[i][1], slug);
        put(&r->html, "<li><a href=\"#%s\">%s</a></li>\n", sections[i][0], sections[i][1]);
    }
    put(&r->md, "\n\n");
    put(&r->html, "</ol></nav>\n");

    put_section(r, sections[1][0], sections[1][1]);
    put_para(r, "Objects drawn, triangles drawn and exact visible are means per frame; missed objects and pixels are "
                "totals over the frames (a conservative method must show 0); over-estimation is the sum over the "
                "frames of the objects drawn divided by the sum of the objects the oracle finds visible (a ratio of "
                "sums: 1.00 is exact, 2.00 draws twice what is seen); cull time is the wall time of one cull call in "
                "milliseconds (median, 95th percentile and maximum over the frames; the machine may be shared). "
                "frames.csv and frames.json hold every frame; docs/bench.md describes the columns.");
    put(&r->html, "<p class=\"legend\"><span class=\"sw best\"></span>best in its column: the fewest objects and "
                  "triangles drawn and the least over-estimation among the methods that missed nothing, the fewest "
                  "missed objects and pixels, the shortest cull times (every tie is highlighted; a column where all "
                  "methods tie is not)<span class=\"sw bad\"></span>a conservative method that dropped a visible "
                  "object &#9733; the recommended methods</p>\n");
    for (uint32_t bi = 0; bi < nb; bi++) {
        put(&r->html, "<h3>");
        put_html(&r->html, sl_bench_label(benches[bi]));
        put(&r->html, "</h3>\n");
        html_summary(r, benches[bi]);
    }
    put(&r->md, "The best value of each ranked column is in bold: the fewest objects and triangles drawn and the "
                "least over-estimation among the methods that missed nothing, the fewest missed objects and pixels, "
                "the shortest cull times (every tie; a column where all methods tie has none).\n\n");
    if (!ferror(sl_output_stream(r->md)))
        sl_bench_print_summary(benches, nb, sl_output_stream(r->md));

    put_section(r, sections[2][0], sections[2][1]);
    put_para(r, "Per frame and method: cull time, triangles drawn (the black dashed line is the exact visible set's "
                "triangles) and missed pixels (only the methods that missed any; none when no method did). Every "
                "method has its own colour, dash pattern and marker, named in the legend on the right; a logarithmic "
                "axis is marked as such.");
    static const char *plots[3][2] = {{"cull-time", "cull time per frame and method"},
                                      {"triangles", "triangles drawn per frame (dashed: the exact visible set)"},
                                      {"missed-pixels", "missed pixels per frame, methods with misses only"}};
    for (uint32_t bi = 0; bi < nb; bi++)
        for (int k = 0; k < 3; k++) {
            char file[256];
            snprintf(file, sizeof file, "%s-%s.svg", sl_bench_label(benches[bi]), plots[k][0]);
            snprintf(text, sizeof text, "%s: %s", sl_bench_label(benches[bi]), plots[k][1]);
            put_image(r, file, text);
        }

    put_section(r, sections[3][0], sections[3][1]);
    snprintf(text, sizeof text,
             "Frame %u of the walk as the oracle sees it: every object in its own colour; the distance (near is "
             "bright); and the depth complexity, i.e. how many fragments a renderer drawing everything in the "
             "frustum would write per pixel (dark blue few, yellow the most).",
             frame_index);
    put_para(r, text);
    static const char *what[3] = {"object ids", "depth", "depth complexity (overdraw)"};
    put(&r->html, "<div class=\"pair\">\n");
    for (int k = 0; k < 3; k++)
        if (frame_images[k]) {
            snprintf(text, sizeof text, "Walk frame %u: %s", frame_index, what[k]);
            put_image(r, frame_images[k], text);
        }
    put(&r->html, "</div>\n");

    put_section(r, sections[4][0], sections[4][1]);
    if (shaded_images[0]) {
        snprintf(text, sizeof text,
                 "Walk frame %u drawn by the OpenGL renderer (headless; docs/render.md), and the same view from "
                 "150 m above the walker (the walker's heading up): the objects the oracle finds visible from the "
                 "walker's camera in orange (ground in pale orange), the rest grey.",
                 frame_index);
        put_para(r, text);
        put(&r->html, "<div class=\"pair\">\n");
        snprintf(text, sizeof text, "Walk frame %u, shaded", frame_index);
        put_image(r, shaded_images[0], text);
        snprintf(text, sizeof text, "Walk frame %u from above: the visible set highlighted (orange)", frame_index);
        put_image(r, shaded_images[1], text);
        put(&r->html, "</div>\n");
    } else {
        put_para(r, shaded_note);
    }

    put_section(r, sections[5][0], sections[5][1]);
    put_para(r, "The city from above, each object coloured by what the oracle and one method say from the first "
                "frame's camera; ground and water are paler, lighter is higher. The bar in the lower left corner "
                "gives the scale in metres. Click a map for the full size.");
    put(&r->md, "Key: green = visible and kept; orange = kept although hidden or outside the view (over-estimation); "
                "grey = culled and indeed not visible; red (ringed) = visible but dropped; black dot = the eye, blue "
                "wedge = its view frustum.\n\n");
    put(&r->html, "<p class=\"legend\" id=\"map-key\"><b>Key:</b>");
    for (size_t i = 0; i < sizeof map_key / sizeof map_key[0]; i++)
        put(&r->html, "<span class=\"sw\" style=\"background:%s\"></span>%s", map_key[i].color, map_key[i].text);
    put(&r->html, "</p>\n");
    for (uint32_t bi = 0; bi < nb; bi++) {
        put(&r->html, "<h3>");
        put_html(&r->html, sl_bench_label(benches[bi]));
        put(&r->html, ", first frame</h3>\n<div class=\"grid maps\">\n");
        put(&r->md, "### %s, first frame\n\n", sl_bench_label(benches[bi]));
        for (uint32_t mi = 0; mi < sl_bench_method_count(benches[bi]); mi++) {
            sl_bench_method_info info;
            if (sl_bench_method(benches[bi], mi, &info, NULL) != SL_OK || info.external)
                continue;
            char file[256], thumb[256];
            snprintf(file, sizeof file, "%s-map-%s.png", sl_bench_label(benches[bi]), info.name);
            snprintf(thumb, sizeof thumb, "%s-map-%s-thumb.png", sl_bench_label(benches[bi]), info.name);
            /* thumbnails: HTML inside Markdown, which the common viewers render */
            put(&r->md, "<a href=\"%s\"><img src=\"%s\" width=\"170\" alt=\"%s\" title=\"%s\"></a>\n", file, thumb,
                info.name, info.name);
            put(&r->html, "<figure><a href=\"%s\"><img loading=\"lazy\" src=\"%s\" alt=\"", file, thumb);
            put_html(&r->html, info.name);
            put(&r->html, " map\"></a><figcaption>");
            put_html(&r->html, info.name);
            put(&r->html, "</figcaption></figure>\n");
        }
        put(&r->md, "\n\n");
        put(&r->html, "</div>\n");
    }

    put_section(r, sections[6][0], sections[6][1]);
    put(&r->md, "| method | guarantee | what it does | options (effective) |\n|---|---|---|---|\n");
    put(&r->html, "<div class=\"scroll\"><table><tr><th>method</th><th class=\"l\">guarantee</th>"
                  "<th class=\"l\">what it does</th><th class=\"l\">options (effective)</th></tr>\n");
    for (uint32_t mi = 0; mi < nmethods; mi++) {
        sl_bench_method_info info;
        uint32_t idx;
        sl_cull_method_desc d;
        if (sl_bench_method(benches[0], mi, &info, NULL) != SL_OK ||
            sl_cull_method_find(info.name, &idx, NULL) != SL_OK || sl_cull_method_info(idx, &d, NULL) != SL_OK)
            continue;
        put(&r->md, "| %s | %s | ", info.name, sl_cull_guarantee_name(info.guarantee));
        put_md(&r->md, d.summary);
        put(&r->md, " | `%s` |\n", info.options);
        put(&r->html, "<tr><td>");
        put_html(&r->html, info.name);
        put(&r->html, "</td><td class=\"l\">%s</td><td class=\"l\">", sl_cull_guarantee_name(info.guarantee));
        put_html(&r->html, d.summary);
        put(&r->html, "</td><td class=\"l\">");
        if (info.options[0]) {
            put(&r->html, "<details><summary>options</summary><code>");
            put_html(&r->html, info.options);
            put(&r->html, "</code></details>");
        } else {
            put(&r->html, "(none)");
        }
        put(&r->html, "</td></tr>\n");
    }
    put(&r->md, "\n");
    put(&r->html, "</table></div>\n");
    if (pvs_note[0])
        put_para(r, pvs_note);
    for (uint32_t i = 0; i < nskipped; i++) {
        snprintf(text, sizeof text, "Not run: %s, which needs an option the demo cannot choose for it: %s",
                 skipped[i].name, skipped[i].reason);
        put_para(r, text);
    }
    put(&r->md, "`sightline methods` lists every method with its options.\n\n");
    put(&r->html, "<p><code>sightline methods</code> lists every method with its options.</p>\n");

    put_section(r, sections[7][0], sections[7][1]);
    snprintf(text, sizeof text,
             "%s objects (%u buildings, %u ground and water patches, %u trees, %u cars, %u lamps), %s triangles "
             "drawn (%s stored, instancing shares the props), %u 2.5D footprints, %u street edges; bounds "
             "%.0f x %.0f m, %.0f m high; %.1f MiB in memory.",
             grouped(g1, sizeof g1, ss.object_count), ss.objects_per_kind[SL_KIND_BUILDING],
             ss.objects_per_kind[SL_KIND_GROUND] + ss.objects_per_kind[SL_KIND_WATER],
             ss.objects_per_kind[SL_KIND_TREE], ss.objects_per_kind[SL_KIND_CAR], ss.objects_per_kind[SL_KIND_LAMP],
             grouped(g2, sizeof g2, (double)ss.instanced_triangle_count), grouped(g3, sizeof g3, (double)ss.triangle_count),
             ss.footprint_count, ss.street_edge_count, (double)(ss.bounds.max.x - ss.bounds.min.x),
             (double)(ss.bounds.max.y - ss.bounds.min.y), (double)(ss.bounds.max.z - ss.bounds.min.z),
             (double)ss.memory_bytes / (1024.0 * 1024.0));
    put_para(r, text);

    put_section(r, sections[8][0], sections[8][1]);
    char arg[400];
    if (scene_file)
        snprintf(arg, sizeof arg, "%.300s", scene_file);
    else
        snprintf(arg, sizeof arg, "city:%s:%llu", preset, (unsigned long long)seed);
    snprintf(text, sizeof text,
             "Replay the walk with more repeats per frame: sightline bench %s --path walk.txt --repeat 5. "
             "Other views: --random street --count 200, or --random flyover. Render any frame: sightline render "
             "%s --path walk.txt --frames 10:11. See docs/bench.md.",
             arg, arg);
    put_para(r, text);
    put(&r->html, "<p><a href=\"#contents\">Back to the contents</a></p>\n</body></html>\n");
}

/* ---- the command ---- */

int sl_cmd_demo(int argc, char **argv)
{
    const char *cmd = argv[0];
    cli_args a;
    cli_args_init(&a, argc, argv);
    const char *name, *val, *preset_name = "small", *out_dir = "demo-out", *scene_file = NULL, *methods_text = NULL;
    bool has_preset = false;
    uint64_t seed = 1;
    uint32_t frames = 0, width = 1024, height = 768;
    bool quick = false, has_frames = false;
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_JSON | CLI_QUIET, &com)) {
        } else if (!name) {
            cli_unknown(&a, NULL);
        } else if (!strcmp(name, "preset")) {
            preset_name = cli_value(&a, name, val);
            has_preset = true;
        } else if (!strcmp(name, "scene")) {
            scene_file = cli_value(&a, name, val);
        } else if (!strcmp(name, "seed")) {
            cli_parse_u64(&a, name, cli_value(&a, name, val), &seed);
        } else if (!strcmp(name, "out")) {
            out_dir = cli_value(&a, name, val);
        } else if (!strcmp(name, "frames")) {
            has_frames = cli_parse_u32(&a, name, cli_value(&a, name, val), &frames);
        } else if (!strcmp(name, "width")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &width);
        } else if (!strcmp(name, "height")) {
            cli_parse_u32(&a, name, cli_value(&a, name, val), &height);
        } else if (!strcmp(name, "quick")) {
            quick = true;
        } else if (!strcmp(name, "methods")) {
            methods_text = cli_value(&a, name, val);
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    bool json = com.json, quiet = com.quiet;
    sl_city_preset preset;
    if (sl_city_preset_from_name(preset_name, &preset, NULL) != SL_OK) {
        cli_error(cmd, "--preset '%s' is not tiny, small, vienna, oldtown or oldtown-small", preset_name);
        return 2;
    }
    if (scene_file && has_preset) {
        cli_error(cmd, "--preset and --scene exclude each other");
        return 2;
    }
    if (has_frames && frames == 0) {
        cli_error(cmd, "--frames must be at least 1");
        return 2;
    }
    if (!width || !height || width > 16384 || height > 16384) {
        cli_error(cmd, "--width/--height must be 1..16384");
        return 2;
    }
    uint32_t walk_frames = has_frames ? frames : quick ? QUICK_WALK_FRAMES : DEMO_WALK_FRAMES;
    uint32_t fly_views = quick ? QUICK_FLY_VIEWS : DEMO_FLY_VIEWS;
    /* everything goes to a new folder first, moved into OUT only when the demo has written it all */
    cli_outdir od;
    if (!cli_outdir_begin(cmd, out_dir, &od))
        return 1;
    const char *work = od.stage;
    double t0 = tool_now();
    cli_progress_state ps;
    sl_progress prog = cli_progress(&ps, quiet || json);
    sl_error err;
    char spec[4200], label[128], path[4400];
    if (scene_file)
        snprintf(spec, sizeof spec, "%s", scene_file);
    else
        snprintf(spec, sizeof spec, "city:%s:%llu", sl_city_preset_name(preset), (unsigned long long)seed);
    if (!json && !quiet && scene_file)
        fprintf(stderr, "sightline demo: opening %s...\n", scene_file);
    else if (!json && !quiet)
        fprintf(stderr, "sightline demo: generating the %s city (seed %llu)...\n", sl_city_preset_name(preset),
                (unsigned long long)seed);
    sl_scene scene = NULL;
    if (cli_open_scene(spec, NULL, NULL, &prog, &scene, label, sizeof label, &err) != SL_OK) {
        cli_progress_done(&ps);
        cli_outdir_abort(&od);
        return cli_fail(cmd, &err);
    }
    cli_progress_done(&ps);

    /* every registered method that runs with its default options (the others are named), or the
     * methods of --methods; pvs without a file gets the walk's PVS, baked below */
    sl_bench_method_spec specs[SL_BENCH_MAX_METHODS];
    sl_bench_skip skipped[SL_BENCH_MAX_METHODS];
    uint32_t nskipped = 0, nm = 0;
    int pvs_listed = -1; /* --methods: the index of a pvs to bake for, -1: none */
    char method_buf[4096], pvs_options[4600];
    if (!methods_text) {
        nm = sl_bench_registered_methods(specs, SL_BENCH_MAX_METHODS, skipped, SL_BENCH_MAX_METHODS, &nskipped);
        nskipped = TOOL_MIN(nskipped, SL_BENCH_MAX_METHODS);
    } else {
        int n = cli_method_list(cmd, methods_text, method_buf, sizeof method_buf, specs, SL_BENCH_MAX_METHODS);
        for (int k = 0; k < n; k++) {
            const char *o = specs[k].options;
            bool has_file = o && (!strncmp(o, "file=", 5) || strstr(o, ",file="));
            if (!strcmp(specs[k].name, "pvs") && !has_file) {
                pvs_listed = k;
                continue; /* its other options are checked once the file is baked */
            }
            if (sl_cull_method_check_options(specs[k].name, o, &err) != SL_OK) {
                cli_error(cmd, "--methods: %s", err.message);
                n = -1;
                break;
            }
        }
        if (n < 0) {
            sl_scene_destroy(scene);
            cli_outdir_abort(&od);
            return 2;
        }
        nm = (uint32_t)n;
    }

    sl_path walk = NULL, fly = NULL;
    sl_bench benches[2] = {NULL, NULL};
    uint32_t nb = 0;
    int status = 0;
    sl_path_options wo = sl_path_options_default(SL_PATH_WALK);
    wo.frames = walk_frames;
    wo.fps = DEMO_WALK_FPS;
    wo.seed = seed;
    wo.intrinsics.width = width;
    wo.intrinsics.height = height;
    sl_path_options fo = sl_path_options_default(SL_PATH_FLYOVER);
    fo.intrinsics = wo.intrinsics;
    if (sl_path_generate(scene, &wo, NULL, &walk, &err) != SL_OK ||
        sl_path_random_views(scene, SL_VIEWS_FLYOVER, fly_views, seed, &fo, NULL, &fly, &err) != SL_OK)
        status = cli_fail(cmd, &err);
    snprintf(path, sizeof path, "%s/walk.txt", work);
    if (!status && sl_path_save(walk, path, &err) != SL_OK)
        status = cli_fail(cmd, &err);
    /* the pvs culler: bake the cells along the walk, then run it with the others */
    cli_pvs_along dp;
    char pvs_note[1024] = "";
    memset(&dp, 0, sizeof dp);
    if (!status && (!methods_text || pvs_listed >= 0)) {
        if (!json && !quiet)
            fprintf(stderr, "sightline demo: baking the PVS of the street cells along the walk (%s)...\n",
                    CLI_PVS_ALONG_METHOD);
        snprintf(path, sizeof path, "%s/walk.slpvs", work);
        if (cli_pvs_bake_along(scene, walk, 0, UINT32_MAX, path, &prog, &dp, &err) != SL_OK)
            status = cli_fail(cmd, &err);
        cli_progress_done(&ps);
    }
    if (!status && pvs_listed >= 0) {
        /* --methods named pvs: the baked file plus the options given */
        const char *given = specs[pvs_listed].options;
        snprintf(pvs_options, sizeof pvs_options, "%s%s%s", dp.options, given ? "," : "", given ? given : "");
        if (!dp.options[0]) {
            cli_error(cmd, "--methods: pvs cannot run: %s", dp.why[0] ? dp.why : "no PVS was baked");
            status = 1;
        } else if (sl_cull_method_check_options("pvs", pvs_options, &err) != SL_OK) {
            cli_error(cmd, "--methods: %s", err.message);
            status = 2;
        } else {
            specs[pvs_listed].options = pvs_options;
        }
    }
    if (!status && dp.options[0] && !methods_text && nm < SL_BENCH_MAX_METHODS) {
        specs[nm++] = (sl_bench_method_spec){"pvs", dp.options};
        /* it runs after all: take it off the list of methods not run */
        uint32_t k = 0;
        for (uint32_t i = 0; i < nskipped; i++)
            if (strcmp(skipped[i].name, "pvs") != 0)
                skipped[k++] = skipped[i];
        nskipped = k;
        snprintf(pvs_note, sizeof pvs_note,
                 "pvs runs on walk.slpvs, baked for this demo: the %u street cells within %g m of the walk's "
                 "cameras, method %s, %.1f s, %.1f%% of the objects culled per cell on average. Where the eye is "
                 "in none of them (the flyover) the pvs culler falls back to frustum culling.",
                 dp.cells, (double)CLI_PVS_ALONG_RADIUS, CLI_PVS_ALONG_METHOD, dp.seconds, 100.0 * dp.culled);
        if (!json && !quiet)
            fprintf(stderr, "sightline demo: walk.slpvs: %u cells in %.1f s\n", dp.cells, dp.seconds);
    } else if (!status && dp.why[0]) {
        for (uint32_t i = 0; i < nskipped; i++)
            if (!strcmp(skipped[i].name, "pvs"))
                snprintf(skipped[i].reason, sizeof skipped[i].reason, "%s", dp.why);
    }
    /* a generated city has what every method needs; a method that cannot work on it is named, not run */
    uint32_t first_na = nskipped;
    cli_drop_not_applicable(cmd, scene, label, specs, &nm, skipped, &nskipped, SL_BENCH_MAX_METHODS, true);
    for (uint32_t i = 0; i < nskipped && !json && !status; i++)
        fprintf(stderr, "sightline demo: not running %s: %s\n", skipped[i].name, skipped[i].reason);
    if (!status && !nm) {
        cli_error(cmd, "no method to run: %s", nskipped > first_na ? skipped[first_na].reason : "none listed");
        status = 2;
    }
    static const char *set_names[2] = {"walk", "flyover"};
    for (uint32_t k = 0; k < 2 && !status; k++) {
        char set_label[160];
        snprintf(set_label, sizeof set_label, "%s-%s", label, set_names[k]);
        sl_bench_options bo = sl_bench_default_options();
        bo.width = width;
        bo.height = height;
        bo.label = set_label;
        bo.progress = prog;
        if (sl_bench_create(scene, specs, nm, &bo, NULL, &benches[k], &err) != SL_OK) {
            status = cli_fail(cmd, &err);
            break;
        }
        nb++;
        if (cli_outdir_show_bench(benches[k], work, out_dir, &err) != SL_OK) {
            status = cli_fail(cmd, &err);
            break;
        }
        sl_path views = k == 0 ? walk : fly;
        sl_status st = sl_bench_run_path(benches[k], views, 0, sl_path_count(views), &err);
        cli_progress_done(&ps);
        snprintf(path, sizeof path, "%s/%s-", work, set_label);
        if (st == SL_OK)
            st = sl_bench_write_plots(benches[k], path, &err);
        sl_bench_map_options mo;
        memset(&mo, 0, sizeof mo);
        mo.camera = sl_path_camera(views, 0);
        mo.thumb_size = DEMO_THUMB_SIZE;
        snprintf(path, sizeof path, "%s/%s-map-", work, set_label);
        if (st == SL_OK)
            st = sl_bench_write_maps(benches[k], &mo, path, NULL, &err);
        if (st != SL_OK)
            status = cli_fail(cmd, &err);
    }

    /* one frame of the walk as images: the middle one */
    uint32_t frame_index = walk ? sl_path_count(walk) / 2 : 0;
    const char *frame_images[3] = {NULL, NULL, NULL};
    const char *shaded_images[2] = {NULL, NULL};
    char shaded_note[700] = "This sightline was built without the OpenGL renderer (docs/render.md): no shaded frames.";
    if (!status) {
        sl_oracle_options oo = sl_oracle_default_options();
        oo.count_overdraw = true;
        sl_oracle oracle = NULL;
        sl_oracle_frame fr;
        sl_oracle_view v;
        sl_camera c = sl_path_camera(walk, frame_index);
        sl_status st = sl_oracle_create(scene, &oo, NULL, &oracle, &err);
        if (st == SL_OK)
            st = sl_oracle_render(oracle, &c, &fr, &err);
        if (st == SL_OK)
            st = sl_oracle_get_view(oracle, 0, &v, &err);
        static const char *files[3] = {"frame-id.png", "frame-depth.png", "frame-overdraw.png"};
        for (int k = 0; k < 3 && st == SL_OK; k++) {
            snprintf(path, sizeof path, "%s/%s", work, files[k]);
            st = k == 0   ? sl_image_write_ids(&v, path, NULL, &err)
                 : k == 1 ? sl_image_write_depth(&v, &c, path, NULL, &err)
                          : sl_image_write_overdraw(&v, path, NULL, NULL, &err);
            if (st == SL_OK)
                frame_images[k] = files[k];
        }
#ifdef SL_HAVE_GL
        if (st == SL_OK)
            demo_shaded(scene, &c, fr.visible, fr.visible_count, work, shaded_images, shaded_note,
                        sizeof shaded_note);
#endif
        sl_oracle_destroy(oracle);
        if (st != SL_OK)
            status = cli_fail(cmd, &err);
    }

    uint64_t violations = 0;
    if (!status) {
        static const char *files[3] = {"frames.csv", "frames.json", "summary.md"};
        for (int k = 0; k < 3 && !status; k++) {
            snprintf(path, sizeof path, "%s/%s", work, files[k]);
            sl_status st = k == 0   ? sl_bench_write_csv(benches, nb, path, &err)
                           : k == 1 ? sl_bench_write_json(benches, nb, path, &err)
                                    : sl_bench_write_summary(benches, nb, path, &err);
            if (st != SL_OK)
                status = cli_fail(cmd, &err);
        }
        violations = sl_bench_print_violations(benches, nb, 20, stderr);
    }
    if (!status) {
        report r;
        memset(&r, 0, sizeof r);
        char md_path[4400], html_path[4400];
        snprintf(md_path, sizeof md_path, "%s/report.md", work);
        snprintf(html_path, sizeof html_path, "%s/report.html", work);
        if (sl_output_open(md_path, NULL, &r.md, &err) != SL_OK) {
            status = cli_fail(cmd, &err);
        } else if (sl_output_open(html_path, NULL, &r.html, &err) != SL_OK) {
            sl_output_abort(r.md);
            status = cli_fail(cmd, &err);
        } else {
            write_report_body(&r, scene, label, benches, nb, skipped, nskipped, pvs_note, frame_images, frame_index,
                              shaded_images, shaded_note, violations, sl_city_preset_name(preset), seed,
                              scene_file, tool_now() - t0);
            /* a write error makes the commit fail */
            sl_status s1 = sl_output_commit(r.md, &err);
            if (s1 != SL_OK) {
                sl_output_abort(r.html);
                status = cli_fail(cmd, &err);
            } else if (sl_output_commit(r.html, &err) != SL_OK) {
                status = cli_fail(cmd, &err);
            }
        }
    }
    /* the demo's files take their places in OUT only when all are written */
    if (status)
        cli_outdir_abort(&od);
    else if (!cli_outdir_commit(cmd, &od))
        status = 1;
    if (!status) {
        double seconds = tool_now() - t0;
        if (json) {
            cli_json j;
            cli_json_begin(&j, stdout);
            cli_json_string(&j, "scene", label);
            cli_json_string(&j, "out", out_dir);
            snprintf(path, sizeof path, "%s/report.html", out_dir);
            cli_json_string(&j, "report", path);
            cli_json_double(&j, "seconds", seconds);
            cli_json_uint(&j, "violations", violations);
            if (dp.options[0]) {
                cli_json_uint(&j, "pvs_cells", dp.cells);
                cli_json_double(&j, "pvs_bake_seconds", dp.seconds);
            }
            cli_json_array_begin(&j, "skipped");
            for (uint32_t i = 0; i < nskipped; i++) {
                cli_json_object_begin(&j, NULL);
                cli_json_string(&j, "name", skipped[i].name);
                cli_json_string(&j, "reason", skipped[i].reason);
                cli_json_object_end(&j);
            }
            cli_json_array_end(&j);
            cli_json_array_begin(&j, "runs");
            for (uint32_t bi = 0; bi < nb; bi++) {
                cli_json_object_begin(&j, NULL);
                cli_json_string(&j, "label", sl_bench_label(benches[bi]));
                cli_json_uint(&j, "frames", sl_bench_frame_count(benches[bi]));
                cli_json_array_begin(&j, "methods");
                for (uint32_t mi = 0; mi < sl_bench_method_count(benches[bi]); mi++) {
                    sl_bench_method_info info;
                    sl_bench_summary s;
                    if (sl_bench_method(benches[bi], mi, &info, NULL) != SL_OK ||
                        sl_bench_summarize(benches[bi], mi, &s, NULL) != SL_OK)
                        continue;
                    cli_json_object_begin(&j, NULL);
                    cli_json_string(&j, "name", info.name);
                    cli_json_string(&j, "guarantee", sl_cull_guarantee_name(info.guarantee));
                    cli_json_double(&j, "objects_drawn_mean", s.objects_drawn_mean);
                    cli_json_double(&j, "triangles_drawn_mean", s.triangles_drawn_mean);
                    cli_json_double(&j, "visible_mean", s.visible_mean);
                    cli_json_double(&j, "overestimation", s.overestimation);
                    cli_json_uint(&j, "missed_objects", s.missed_objects_total);
                    cli_json_uint(&j, "missed_pixels", s.missed_pixels_total);
                    cli_json_double(&j, "cull_ms_median", s.cull_ms.median);
                    cli_json_object_end(&j);
                }
                cli_json_array_end(&j);
                cli_json_object_end(&j);
            }
            cli_json_array_end(&j);
            cli_json_end(&j);
        } else {
            sl_bench_print_summary(benches, nb, stdout);
            printf("demo finished in %.1f s. Report: %s/report.html (and report.md); open it in a browser.\n",
                   seconds, out_dir);
        }
        if (violations) {
            fprintf(stderr, "sightline demo: CONSERVATIVENESS VIOLATION: conservative methods missed %llu visible "
                            "object(s) (see above and the report)\n",
                    (unsigned long long)violations);
            status = 1;
        }
    }
    for (uint32_t i = 0; i < 2; i++)
        sl_bench_destroy(benches[i]);
    sl_path_destroy(walk);
    sl_path_destroy(fly);
    sl_scene_destroy(scene);
    return status;
}

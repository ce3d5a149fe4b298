/* Report graphics: SVG line plots for per-frame series (cull time, triangles, missed pixels),
 * PNG images of oracle views (ids, depth, overdraw) and a few drawing primitives for maps.
 *
 * The plots are plain SVG 1.1 (no scripts, no external fonts) so any browser or image viewer opens
 * them. Long series are thinned per pixel column to the first, lowest, highest and last value, so
 * a plot of a hundred thousand frames stays small while every spike stays visible. */
#include "plot.h"

#include "sightline/image.h"

#include <math.h>
#include <stdarg.h>

/* ---- SVG ------------------------------------------------------------------------------------ */

uint32_t sl_plot_color(uint32_t i)
{
    /* qualitative, told apart on white and mostly by the colour-blind too; black is the reference's */
    static const uint32_t palette[SL_PLOT_COLORS] = {0x1f77b4, 0xd62728, 0x2ca02c, 0xff7f0e, 0x9467bd,
                                                     0x8c564b, 0xe377c2, 0x17becf, 0xa6a600, 0x393b79,
                                                     0x7f7f7f, 0xaa3377, 0x00786a, 0xf4a582};
    return palette[i % SL_PLOT_COLORS];
}

/* Dash patterns of the lines (solid first) and of a reference line. */
static const char *const dash_patterns[SL_PLOT_DASHES] = {"", "9,3", "2,2.5", "9,3,2,3", "4.5,4.5"};
#define REFERENCE_DASH "12,6"

static void out(sl_atomic_file *f, const char *fmt, ...) SL_PRINTF(2, 3);
static void out(sl_atomic_file *f, const char *fmt, ...)
{
    if (f->failed)
        return;
    va_list ap;
    va_start(ap, fmt);
    if (vfprintf(f->fp, fmt, ap) < 0)
        f->failed = true;
    va_end(ap);
}

/* Text with the five XML specials escaped. */
static void out_text(sl_atomic_file *f, const char *s)
{
    for (; s && *s; s++) {
        switch (*s) {
        case '&': out(f, "&amp;"); break;
        case '<': out(f, "&lt;"); break;
        case '>': out(f, "&gt;"); break;
        case '"': out(f, "&quot;"); break;
        case '\'': out(f, "&apos;"); break;
        default:
            if ((unsigned char)*s >= 0x20)
                out(f, "%c", *s);
        }
    }
}

/* A tick step of 1, 2 or 5 times a power of ten giving about `target` intervals over range. */
static double nice_step(double range, int target)
{
    double raw = range / target, p = pow(10, floor(log10(raw))), m = raw / p;
    return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
}

/* A tick label: integers without decimals, others with a few significant digits. */
static void tick_label(char *buf, size_t n, double v)
{
    if (fabs(v) < 1e-12)
        v = 0;
    double a = fabs(v);
    if (a >= 1e6 && a < 1e15 && v == floor(v))
        snprintf(buf, n, "%.3gM", v / 1e6);
    else if (a >= 1e4 && a < 1e6 && v == floor(v))
        snprintf(buf, n, "%.4gk", v / 1e3);
    else
        snprintf(buf, n, "%.4g", v);
}

typedef struct axis {
    double lo, hi;
    bool log;
} axis;

static double axis_pos(const axis *a, double v, double p0, double p1)
{
    double t;
    if (a->log)
        t = (log10(v) - log10(a->lo)) / (log10(a->hi) - log10(a->lo));
    else
        t = (v - a->lo) / (a->hi - a->lo);
    return p0 + t * (p1 - p0);
}

/* Marker m (0..SL_PLOT_MARKERS-1: circle, square, triangle, diamond, inverted triangle, cross,
 * plus) of colour c centred on x, y. */
static void out_marker(sl_atomic_file *f, uint32_t m, double x, double y, uint32_t c)
{
    const double r = 4.2;
    c &= 0xffffff;
    switch (m % SL_PLOT_MARKERS) {
    case 0: out(f, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"%.1f\" fill=\"#%06x\" stroke=\"white\"/>\n", x, y, r, c); break;
    case 1:
        out(f, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"#%06x\" stroke=\"white\"/>\n",
            x - 0.85 * r, y - 0.85 * r, 1.7 * r, 1.7 * r, c);
        break;
    case 2:
        out(f, "<path d=\"M%.1f %.1fL%.1f %.1fL%.1f %.1fZ\" fill=\"#%06x\" stroke=\"white\"/>\n", x, y - 1.15 * r,
            x + r, y + 0.75 * r, x - r, y + 0.75 * r, c);
        break;
    case 3:
        out(f, "<path d=\"M%.1f %.1fL%.1f %.1fL%.1f %.1fL%.1f %.1fZ\" fill=\"#%06x\" stroke=\"white\"/>\n", x,
            y - 1.2 * r, x + r, y, x, y + 1.2 * r, x - r, y, c);
        break;
    case 4:
        out(f, "<path d=\"M%.1f %.1fL%.1f %.1fL%.1f %.1fZ\" fill=\"#%06x\" stroke=\"white\"/>\n", x, y + 1.15 * r,
            x + r, y - 0.75 * r, x - r, y - 0.75 * r, c);
        break;
    case 5:
        out(f, "<path d=\"M%.1f %.1fL%.1f %.1fM%.1f %.1fL%.1f %.1f\" stroke=\"#%06x\" stroke-width=\"2.2\"/>\n",
            x - r, y - r, x + r, y + r, x - r, y + r, x + r, y - r, c);
        break;
    default:
        out(f, "<path d=\"M%.1f %.1fL%.1f %.1fM%.1f %.1fL%.1f %.1f\" stroke=\"#%06x\" stroke-width=\"2.2\"/>\n",
            x - 1.2 * r, y, x + 1.2 * r, y, x, y - 1.2 * r, x, y + 1.2 * r, c);
        break;
    }
}

sl_status sl_plot_write_svg(const sl_plot *p, const char *path, const sl_allocator *alloc, sl_error *err)
{
    if (!p || !path || (p->series_count && !p->series))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_plot_write_svg: plot and path must not be NULL");
    double W = p->width ? p->width : 960, H = p->height ? p->height : 480;
    const double left = 84, right = 190, top = 44, bottom = 56;
    H = SL_MAX(H, top + 20.0 + 20.0 * p->series_count + bottom); /* room for the legend */
    double px0 = left, px1 = W - right, py0 = H - bottom, py1 = top; /* py0: bottom of the plot area */
    if (px1 - px0 < 50 || py0 - py1 < 50)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: plot size %gx%g is too small", path, W, H);

    /* ranges */
    size_t n = 0;
    double ymin = INFINITY, ymax = -INFINITY, ypos_min = INFINITY;
    for (uint32_t s = 0; s < p->series_count; s++) {
        const sl_plot_series *se = &p->series[s];
        n = SL_MAX(n, se->count);
        for (size_t i = 0; i < se->count; i++) {
            double v = se->y[i];
            if (!isfinite(v))
                continue;
            ymin = SL_MIN(ymin, v);
            ymax = SL_MAX(ymax, v);
            if (v > 0)
                ypos_min = SL_MIN(ypos_min, v);
        }
    }
    axis ax = {0, 1, false}, ay = {0, 1, false};
    if (n && p->x) {
        ax.lo = INFINITY, ax.hi = -INFINITY;
        for (size_t i = 0; i < n; i++)
            if (isfinite(p->x[i])) {
                ax.lo = SL_MIN(ax.lo, p->x[i]);
                ax.hi = SL_MAX(ax.hi, p->x[i]);
            }
        if (!isfinite(ax.lo))
            ax.lo = 0, ax.hi = 1;
    } else if (n) {
        ax.hi = (double)(n - 1);
    }
    if (!(ax.hi > ax.lo))
        ax.hi = ax.lo + 1;
    bool have = isfinite(ymin);
    bool log_y = p->y_scale == SL_PLOT_LOG ||
                 (p->y_scale == SL_PLOT_AUTO && have && isfinite(ypos_min) && ymax / ypos_min > 100.0);
    if (log_y && have && isfinite(ypos_min)) {
        ay.log = true;
        ay.lo = pow(10, floor(log10(ypos_min)));
        ay.hi = pow(10, ceil(log10(ymax)));
        if (!(ay.hi > ay.lo))
            ay.hi = ay.lo * 10;
    } else {
        ay.lo = have ? SL_MIN(0, ymin) : 0;
        ay.hi = have ? ymax : 1;
        if (!(ay.hi > ay.lo))
            ay.hi = ay.lo + 1;
        double step = nice_step(ay.hi - ay.lo, 5);
        ay.hi = ceil(ay.hi / step - 1e-9) * step;
        ay.lo = floor(ay.lo / step + 1e-9) * step;
    }

    sl_atomic_file f;
    sl_status st = sl_atomic_open(alloc, path, &f, err);
    if (st != SL_OK)
        return st;
    out(&f, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\" viewBox=\"0 0 %g %g\" "
            "font-family=\"sans-serif\" font-size=\"12\">\n"
            "<rect x=\"0\" y=\"0\" width=\"%g\" height=\"%g\" fill=\"white\"/>\n",
        W, H, W, H, W, H);
    out(&f, "<text x=\"%g\" y=\"24\" font-size=\"15\" font-weight=\"bold\">", left);
    out_text(&f, p->title);
    out(&f, "</text>\n");

    /* grid and ticks */
    char label[48];
    double xstep = nice_step(ax.hi - ax.lo, 8);
    for (double v = ceil(ax.lo / xstep - 1e-9) * xstep; v <= ax.hi + 1e-9 * xstep; v += xstep) {
        double x = axis_pos(&ax, v, px0, px1);
        tick_label(label, sizeof label, v);
        out(&f, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e4e4e4\"/>\n", x, py0, x, py1);
        out(&f, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">%s</text>\n", x, py0 + 16, label);
    }
    if (ay.log) {
        for (double d = ay.lo; d <= ay.hi * 1.0001; d *= 10) {
            for (int k = 1; k < 10; k++) {
                double v = d * k;
                if (v > ay.hi * 1.0001)
                    break;
                double y = axis_pos(&ay, v, py0, py1);
                out(&f, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\"/>\n", px0, y, px1, y,
                    k == 1 ? "#d0d0d0" : "#f0f0f0");
                if (k == 1) {
                    tick_label(label, sizeof label, v);
                    out(&f, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%s</text>\n", px0 - 6, y + 4, label);
                }
            }
        }
    } else {
        double ystep = nice_step(ay.hi - ay.lo, 5);
        for (double v = ay.lo; v <= ay.hi + 1e-9 * ystep; v += ystep) {
            double y = axis_pos(&ay, v, py0, py1);
            tick_label(label, sizeof label, v);
            out(&f, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e4e4e4\"/>\n", px0, y, px1, y);
            out(&f, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%s</text>\n", px0 - 6, y + 4, label);
        }
    }
    out(&f, "<rect x=\"%g\" y=\"%g\" width=\"%g\" height=\"%g\" fill=\"none\" stroke=\"#333\"/>\n", px0, py1,
        px1 - px0, py0 - py1);
    out(&f, "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\">", 0.5 * (px0 + px1), H - 14);
    out_text(&f, p->x_label);
    out(&f, "</text>\n<text transform=\"translate(18,%g) rotate(-90)\" text-anchor=\"middle\">", 0.5 * (py0 + py1));
    out_text(&f, p->y_label);
    out(&f, "%s</text>\n", ay.log ? " (log scale)" : "");
    if (!have)
    {
        out(&f, "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\" font-size=\"15\" fill=\"#555\">", 0.5 * (px0 + px1),
            0.5 * (py0 + py1));
        out_text(&f, p->empty_note && !p->series_count ? p->empty_note : "no data");
        out(&f, "</text>\n");
    }

    /* series: polylines clipped to the plot area; thinned per pixel column when long */
    out(&f, "<clipPath id=\"area\"><rect x=\"%g\" y=\"%g\" width=\"%g\" height=\"%g\"/></clipPath>\n", px0 - 2,
        py1 - 2, px1 - px0 + 4, py0 - py1 + 4);
    size_t columns = (size_t)(px1 - px0);
    for (uint32_t s = 0; s < p->series_count; s++) {
        const sl_plot_series *se = &p->series[s];
        uint32_t c = se->color, style = se->style ? se->style - 1 : s;
        const char *dash = se->dashed ? REFERENCE_DASH : dash_patterns[style % SL_PLOT_DASHES];
        out(&f, "<g clip-path=\"url(#area)\" fill=\"none\" stroke=\"#%06x\" stroke-width=\"1.6\"", c & 0xffffff);
        if (dash[0])
            out(&f, " stroke-dasharray=\"%s\"", dash);
        out(&f, ">\n");
        bool open = false;
        size_t points = 0;
        size_t bucket = se->count > 4 * columns ? (se->count + columns - 1) / columns : 1;
        for (size_t b0 = 0; b0 < se->count; b0 += bucket) {
            size_t b1 = SL_MIN(se->count, b0 + bucket);
            /* the bucket's first, lowest, highest and last finite values, in x order */
            size_t pick[4], np = 0, lo = SIZE_MAX, hi = SIZE_MAX;
            for (size_t i = b0; i < b1; i++) {
                if (!isfinite(se->y[i]))
                    continue;
                if (lo == SIZE_MAX || se->y[i] < se->y[lo])
                    lo = i;
                if (hi == SIZE_MAX || se->y[i] > se->y[hi])
                    hi = i;
            }
            if (bucket == 1) {
                pick[np++] = b0;
            } else if (lo != SIZE_MAX) {
                size_t first = SIZE_MAX, last = SIZE_MAX;
                for (size_t i = b0; i < b1; i++)
                    if (isfinite(se->y[i])) {
                        if (first == SIZE_MAX)
                            first = i;
                        last = i;
                    }
                size_t cand[4] = {first, SL_MIN(lo, hi), SL_MAX(lo, hi), last};
                for (int k = 0; k < 4; k++)
                    if (!np || cand[k] > pick[np - 1])
                        pick[np++] = cand[k];
            }
            for (size_t k = 0; k < np; k++) {
                size_t i = pick[k];
                double v = se->y[i];
                if (!isfinite(v)) {
                    if (open)
                        out(&f, "\"/>\n");
                    open = false;
                    continue;
                }
                if (ay.log)
                    v = SL_MAX(v, ay.lo); /* zero and below sit on the axis */
                double x = axis_pos(&ax, p->x ? p->x[i] : (double)i, px0, px1), y = axis_pos(&ay, v, py0, py1);
                if (!open)
                    out(&f, "<polyline points=\"");
                out(&f, "%s%.1f,%.1f", open ? " " : "", x, y);
                open = true;
                points++;
            }
        }
        if (open)
            out(&f, "\"/>\n");
        /* markers: on every point of a short series, else at 8 places staggered per style */
        if (!se->dashed && se->count) {
            size_t marks = se->count <= 16 ? se->count : 8;
            double shift = se->count <= 16 ? 0 : ((double)((style * 3) % 7) + 0.5) / 7.0;
            for (size_t k = 0; k < marks; k++) {
                size_t i = se->count <= 16 ? k : (size_t)(((double)k + shift) * (double)se->count / (double)marks);
                if (i >= se->count || !isfinite(se->y[i]))
                    continue;
                double v = ay.log ? SL_MAX(se->y[i], ay.lo) : se->y[i];
                out_marker(&f, style, axis_pos(&ax, p->x ? p->x[i] : (double)i, px0, px1), axis_pos(&ay, v, py0, py1), c);
            }
        }
        if (points == 1) /* a single frame: a dot, since a one-point line draws nothing */
            for (size_t i = 0; i < se->count; i++)
                if (isfinite(se->y[i])) {
                    double v = ay.log ? SL_MAX(se->y[i], ay.lo) : se->y[i];
                    out(&f, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"#%06x\"/>\n",
                        axis_pos(&ax, p->x ? p->x[i] : (double)i, px0, px1), axis_pos(&ay, v, py0, py1), c & 0xffffff);
                    break;
                }
        out(&f, "</g>\n");
    }
    /* legend */
    for (uint32_t s = 0; s < p->series_count; s++) {
        const sl_plot_series *se = &p->series[s];
        double y = py1 + 10 + 20.0 * s, x = px1 + 10;
        uint32_t style = se->style ? se->style - 1 : s;
        const char *dash = se->dashed ? REFERENCE_DASH : dash_patterns[style % SL_PLOT_DASHES];
        out(&f, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"#%06x\" stroke-width=\"2.2\"", x, y, x + 34, y,
            se->color & 0xffffff);
        if (dash[0])
            out(&f, " stroke-dasharray=\"%s\"", dash);
        out(&f, "/>\n");
        if (!se->dashed)
            out_marker(&f, style, x + 17, y, se->color);
        out(&f, "<text x=\"%g\" y=\"%g\">", x + 40, y + 4);
        out_text(&f, se->name);
        out(&f, "</text>\n");
    }
    out(&f, "</svg>\n");
    return sl_atomic_commit(&f, err);
}

/* ---- images of oracle views ------------------------------------------------------------------ */

static sl_status check_view(const sl_oracle_view *v, const char *path, sl_error *err)
{
    if (!v || !path || !v->ids || !v->depth || !v->width || !v->height)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "image: view and path must not be NULL");
    return SL_OK;
}

static uint8_t *alloc_pixels(const sl_allocator *alloc, const sl_oracle_view *v, uint32_t channels, size_t *bytes)
{
    *bytes = (size_t)v->width * v->height * channels;
    return sl_alloc(alloc, *bytes);
}

static void put_rgb(uint8_t *p, uint32_t c)
{
    p[0] = (uint8_t)(c >> 16), p[1] = (uint8_t)(c >> 8), p[2] = (uint8_t)c;
}

sl_status sl_image_write_ids(const sl_oracle_view *v, const char *path, const sl_allocator *alloc, sl_error *err)
{
    sl_status st = check_view(v, path, err);
    if (st != SL_OK)
        return st;
    size_t bytes;
    uint8_t *px = alloc_pixels(alloc, v, 3, &bytes);
    if (!px)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    size_t n = (size_t)v->width * v->height;
    for (size_t i = 0; i < n; i++)
        put_rgb(px + 3 * i, v->ids[i] == SL_NONE ? 0 : sl_id_color(v->ids[i]));
    st = sl_png_write(path, v->width, v->height, 3, px, 0, err);
    sl_free(alloc, px, bytes);
    return st;
}

/* Distance along the view axis of a stored reversed depth (1 near .. 0 far) of a projection with
 * near plane n and far plane f (OpenGL depth, as the oracle draws). */
static double eye_distance(double n, double f, bool ortho, float rd)
{
    double z = 1.0 - 2.0 * (double)rd; /* NDC z */
    if (ortho)
        return 0.5 * (z * (f - n) + f + n);
    return 2.0 * f * n / ((f + n) - z * (f - n));
}

static sl_status write_depth(const sl_oracle_view *v, double n, double f, bool ortho, const char *path,
                             const sl_allocator *alloc, sl_error *err)
{
    size_t bytes;
    uint8_t *px = alloc_pixels(alloc, v, 1, &bytes);
    if (!px)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    size_t count = (size_t)v->width * v->height;
    bool persp = !ortho;
    /* the range of distances shown, in the scale the image uses (log for perspective) */
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < count; i++) {
        if (v->ids[i] == SL_NONE)
            continue;
        double d = eye_distance(n, f, ortho, v->depth[i]);
        double s = persp ? log(SL_MAX(d, 1e-6)) : d;
        lo = SL_MIN(lo, s);
        hi = SL_MAX(hi, s);
    }
    double span = hi > lo ? hi - lo : 1;
    for (size_t i = 0; i < count; i++) {
        if (v->ids[i] == SL_NONE) {
            px[i] = 0;
            continue;
        }
        double d = eye_distance(n, f, ortho, v->depth[i]);
        double s = persp ? log(SL_MAX(d, 1e-6)) : d;
        double t = 1.0 - (s - lo) / span; /* 1 nearest */
        px[i] = (uint8_t)lround(32.0 + 223.0 * SL_CLAMP(t, 0.0, 1.0)); /* drawn pixels never black */
    }
    sl_status st = sl_png_write(path, v->width, v->height, 1, px, 0, err);
    sl_free(alloc, px, bytes);
    return st;
}

sl_status sl_image_write_depth(const sl_oracle_view *v, const sl_camera *cam, const char *path,
                               const sl_allocator *alloc, sl_error *err)
{
    sl_status st = check_view(v, path, err);
    if (st != SL_OK)
        return st;
    if (!cam)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: no camera for the depth image", path);
    return write_depth(v, cam->near_plane, cam->far_plane, cam->projection == SL_ORTHOGRAPHIC, path, alloc, err);
}

sl_status sl_image_write_depth_view(const sl_oracle_view *v, const sl_view *view, const char *path,
                                    const sl_allocator *alloc, sl_error *err)
{
    sl_status st = check_view(v, path, err);
    if (st != SL_OK)
        return st;
    if (!view)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: no view for the depth image", path);
    if ((st = sl_view_validate(view, err)) != SL_OK)
        return st;
    if (!isfinite(view->far_plane))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: the depth image needs the view the oracle drew: an infinite far plane bounded by the "
                       "scene first (sl_view_bound_far)", path);
    return write_depth(v, view->near_plane, view->far_plane, view->projection == SL_ORTHOGRAPHIC, path, alloc, err);
}

sl_status sl_image_write_overdraw(const sl_oracle_view *v, const char *path, const sl_allocator *alloc,
                                  uint32_t *max_out, sl_error *err)
{
    sl_status st = check_view(v, path, err);
    if (st != SL_OK)
        return st;
    if (!v->overdraw)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: the view has no overdraw counts (create the oracle with count_overdraw)", path);
    size_t bytes;
    uint8_t *px = alloc_pixels(alloc, v, 3, &bytes);
    if (!px)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    size_t n = (size_t)v->width * v->height;
    uint32_t mx = 0;
    for (size_t i = 0; i < n; i++)
        mx = SL_MAX(mx, v->overdraw[i]);
    for (size_t i = 0; i < n; i++)
        put_rgb(px + 3 * i, v->overdraw[i] ? sl_ramp_color((float)v->overdraw[i] / (float)mx) : 0);
    if (max_out)
        *max_out = mx;
    st = sl_png_write(path, v->width, v->height, 3, px, 0, err);
    sl_free(alloc, px, bytes);
    return st;
}

/* ---- drawing ---------------------------------------------------------------------------------- */

static void plot_dot(sl_canvas *c, long x, long y, uint32_t color)
{
    if (x < 0 || y < 0 || x >= (long)c->width || y >= (long)c->height)
        return;
    put_rgb(c->rgb + 3 * ((size_t)y * c->width + (size_t)x), color);
}

void sl_canvas_disc(sl_canvas *c, double cx, double cy, double r, uint32_t color)
{
    if (!(isfinite(cx) && isfinite(cy) && isfinite(r)) || r < 0)
        return;
    long x0 = (long)floor(cx - r), x1 = (long)ceil(cx + r), y0 = (long)floor(cy - r), y1 = (long)ceil(cy + r);
    x0 = SL_MAX(x0, 0), y0 = SL_MAX(y0, 0);
    x1 = SL_MIN(x1, (long)c->width - 1), y1 = SL_MIN(y1, (long)c->height - 1);
    for (long y = y0; y <= y1; y++)
        for (long x = x0; x <= x1; x++) {
            double dx = x + 0.5 - cx, dy = y + 0.5 - cy;
            if (dx * dx + dy * dy <= r * r)
                plot_dot(c, x, y, color);
        }
}

void sl_canvas_line(sl_canvas *c, double x0, double y0, double x1, double y1, uint32_t color, int thickness)
{
    if (!(isfinite(x0) && isfinite(y0) && isfinite(x1) && isfinite(y1)))
        return;
    /* clip the segment to the canvas grown by the thickness (Liang-Barsky), so far-away end
     * points cost nothing */
    double m = thickness + 1.0, xmin = -m, ymin = -m, xmax = c->width + m, ymax = c->height + m;
    double dx = x1 - x0, dy = y1 - y0, t0 = 0, t1 = 1;
    double pp[4] = {-dx, dx, -dy, dy}, qq[4] = {x0 - xmin, xmax - x0, y0 - ymin, ymax - y0};
    for (int k = 0; k < 4; k++) {
        if (pp[k] == 0) {
            if (qq[k] < 0)
                return;
            continue;
        }
        double r = qq[k] / pp[k];
        if (pp[k] < 0)
            t0 = SL_MAX(t0, r);
        else
            t1 = SL_MIN(t1, r);
        if (t0 > t1)
            return;
    }
    double ax = x0 + t0 * dx, ay = y0 + t0 * dy, bx = x0 + t1 * dx, by = y0 + t1 * dy;
    double len = hypot(bx - ax, by - ay);
    long steps = (long)ceil(len * 2) + 1;
    double r = 0.5 * SL_MAX(thickness, 1);
    for (long i = 0; i <= steps; i++) {
        double t = (double)i / (double)steps;
        sl_canvas_disc(c, ax + t * (bx - ax), ay + t * (by - ay), r, color);
    }
}

void sl_canvas_ring(sl_canvas *c, double cx, double cy, double r, uint32_t color, int thickness)
{
    int segments = SL_MAX(16, (int)(r * 0.8));
    for (int i = 0; i < segments; i++) {
        double a0 = 2 * M_PI * i / segments, a1 = 2 * M_PI * (i + 1) / segments;
        sl_canvas_line(c, cx + r * cos(a0), cy + r * sin(a0), cx + r * cos(a1), cy + r * sin(a1), color, thickness);
    }
}

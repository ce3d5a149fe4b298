/* Top-down visibility maps: the whole scene seen from above, every object coloured by what the
 * oracle and one method say about it from a chosen viewpoint.
 *
 * The map is itself an oracle render: an orthographic camera looking straight down over the
 * scene's bounds draws the object-id buffer, so roofs, streets and props appear exactly as their
 * triangles lie, with no separate 2D rasterizer. Each pixel is then coloured by the class of the
 * object it shows (visible and kept, missed, kept but hidden, culled) and shaded by height. */
#include "bench_internal.h"
#include "plot.h"

#include "sightline/image.h"

#include <math.h>

enum { CLS_CULLED = 0, CLS_EXTRA = 1, CLS_VISIBLE = 2, CLS_MISSED = 3 };
static const uint32_t class_color[4] = {0x8c8c8c, 0xff9f1c, 0x2ca02c, 0xe00000};
/* the eye's frustum (the demo report's map key names these colours) */
#define FRUSTUM_COLOR 0x1f5fbfu

/* Blend colour c toward white by t in [0,1], then scale by brightness k. */
static uint32_t shade(uint32_t c, double pale, double k)
{
    uint32_t r = 0;
    for (int s = 16; s >= 0; s -= 8) {
        double v = (double)((c >> s) & 255);
        v = (v + (255 - v) * pale) * k;
        r |= (uint32_t)lround(SL_CLAMP(v, 0.0, 255.0)) << s;
    }
    return r;
}

/* World point to map pixel through the top-down camera's matrix. */
static void to_pixel(const sl_mat4 *vp, uint32_t w, uint32_t h, sl_vec3 p, double *px, double *py)
{
    const float *m = vp->m;
    double cx = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
    double cy = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    double cw = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    if (cw == 0)
        cw = 1;
    *px = (cx / cw + 1.0) * 0.5 * w;
    *py = (1.0 - cy / cw) * 0.5 * h;
}

/* Blend colour c over pixel x, y with opacity a. */
static void blend_px(sl_canvas *cv, long x, long y, uint32_t c, double a)
{
    if (x < 0 || y < 0 || x >= (long)cv->width || y >= (long)cv->height)
        return;
    uint8_t *p = cv->rgb + 3 * ((size_t)y * cv->width + (size_t)x);
    for (int k = 0; k < 3; k++) {
        double v = (double)((c >> (16 - 8 * k)) & 255);
        p[k] = (uint8_t)lround((1 - a) * p[k] + a * v);
    }
}

/* A filled triangle blended over the canvas (pixel centres inside), clipped to the canvas, only
 * where ids shows no object: the objects keep the colours of the key. */
static void fill_triangle(sl_canvas *cv, const uint32_t *ids, const double x[3], const double y[3], uint32_t c,
                          double a)
{
    for (int k = 0; k < 3; k++)
        if (!isfinite(x[k]) || !isfinite(y[k]))
            return;
    double area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
    if (area == 0)
        return;
    long x0 = (long)floor(SL_MIN(SL_MIN(x[0], x[1]), x[2])), x1 = (long)ceil(SL_MAX(SL_MAX(x[0], x[1]), x[2]));
    long y0 = (long)floor(SL_MIN(SL_MIN(y[0], y[1]), y[2])), y1 = (long)ceil(SL_MAX(SL_MAX(y[0], y[1]), y[2]));
    x0 = SL_MAX(x0, 0), y0 = SL_MAX(y0, 0);
    x1 = SL_MIN(x1, (long)cv->width - 1), y1 = SL_MIN(y1, (long)cv->height - 1);
    for (long py = y0; py <= y1; py++)
        for (long px = x0; px <= x1; px++) {
            double cx = px + 0.5, cy = py + 0.5, w[3];
            for (int k = 0; k < 3; k++) {
                int a1 = (k + 1) % 3, a2 = (k + 2) % 3;
                w[k] = ((x[a2] - x[a1]) * (cy - y[a1]) - (cx - x[a1]) * (y[a2] - y[a1])) / area;
            }
            if (w[0] >= 0 && w[1] >= 0 && w[2] >= 0 && ids[(size_t)py * cv->width + (size_t)px] == SL_NONE)
                blend_px(cv, px, py, c, a);
        }
}

/* Glyphs of the scale bar's label, 5 rows of 5 bits (the high bit the left column): the digits,
 * then 'm' and a space. */
static const uint8_t glyphs[12][5] = {
    {0x1c, 0x14, 0x14, 0x14, 0x1c}, {0x08, 0x18, 0x08, 0x08, 0x1c}, {0x1c, 0x04, 0x1c, 0x10, 0x1c},
    {0x1c, 0x04, 0x1c, 0x04, 0x1c}, {0x14, 0x14, 0x1c, 0x04, 0x04}, {0x1c, 0x10, 0x1c, 0x04, 0x1c},
    {0x1c, 0x10, 0x1c, 0x14, 0x1c}, {0x1c, 0x04, 0x04, 0x04, 0x04}, {0x1c, 0x14, 0x1c, 0x14, 0x1c},
    {0x1c, 0x14, 0x1c, 0x04, 0x1c}, {0x00, 0x1e, 0x15, 0x15, 0x15}, {0x00, 0x00, 0x00, 0x00, 0x00},
};

/* Text of digits, 'm' and spaces at x, y (top left), each glyph cell s x s pixels; returns the
 * width drawn. */
static double draw_text(sl_canvas *cv, double x, double y, const char *text, int s, uint32_t c)
{
    double x_start = x;
    for (; *text; text++) {
        int g = *text >= '0' && *text <= '9' ? *text - '0' : *text == 'm' ? 10 : 11;
        int cols = g == 10 ? 5 : 3; /* digits in the three high bits */
        for (int row = 0; row < 5; row++)
            for (int col = 0; col < cols; col++)
                if (glyphs[g][row] & (0x10 >> col))
                    for (int dy = 0; dy < s; dy++)
                        for (int dx = 0; dx < s; dx++)
                            blend_px(cv, (long)(x + col * s + dx), (long)(y + row * s + dy), c, 1.0);
        x += (cols + 1) * s;
    }
    return x - x_start;
}

/* A scale bar in the lower left corner: a round length (1, 2 or 5 times a power of ten metres)
 * of about a fifth of the map's width, black on a white box, labelled "N m". */
static void draw_scale_bar(sl_canvas *cv, double ppm, double *metres_out)
{
    double want = 0.2 * cv->width / ppm, p = pow(10, floor(log10(want))), m = want / p;
    double metres = (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p, len = metres * ppm;
    int s = (int)SL_MAX(1, lround(cv->width / 400.0)); /* glyph cell: 2 px on a 1024 map */
    char label[32];
    snprintf(label, sizeof label, "%.0f m", metres);
    double pad = 3.0 * s, bar = 2.0 * s, text_h = 5.0 * s, text_w = (double)strlen(label) * 6 * s;
    double x0 = 0.025 * cv->width, y1 = cv->height - 0.025 * cv->height; /* the box's lower left */
    double bw = SL_MAX(len, text_w) + 2 * pad, bh = text_h + bar + 3 * pad + 2 * s;
    for (long y = (long)(y1 - bh); y < (long)y1; y++)
        for (long x = (long)x0; x < (long)(x0 + bw); x++)
            blend_px(cv, x, y, 0xffffff, 0.85);
    double by = y1 - pad - bar;
    for (long y = (long)by; y < (long)(by + bar); y++)
        for (long x = (long)(x0 + pad); x < (long)(x0 + pad + len); x++)
            blend_px(cv, x, y, 0x000000, 1.0);
    for (long y = (long)(by - 2 * s); y < (long)(by + bar); y++) /* end ticks */
        for (int k = 0; k < 2; k++)
            for (long x = 0; x < s; x++)
                blend_px(cv, (long)(x0 + pad + (k ? len - s : 0)) + x, y, 0x000000, 1.0);
    draw_text(cv, x0 + pad, by - 2 * s - pad - text_h, label, s, 0x000000);
    if (metres_out)
        *metres_out = metres;
}

/* Mark every object a method keeps from the viewpoint: one cull for a camera, the union of the
 * six face cameras for an eye. */
static sl_status method_kept(struct sl_bench_t *b, bench_method *m, const sl_bench_map_options *o,
                             const sl_camera *cam, float near_plane, float far_plane, uint8_t *kept, sl_error *err)
{
    memset(kept, 0, b->object_count);
    uint32_t views = o->use_eye ? 6 : 1;
    for (uint32_t v = 0; v < views; v++) {
        sl_camera c = o->use_eye ? sl_cube_face_camera(o->eye, (sl_cube_face)v, o->cube_size, near_plane, far_plane)
                                 : *cam;
        sl_status st = sl_culler_cull(m->culler, &c, m->result, SL_MAX(b->object_count, 1), &m->result_count, err);
        if (st != SL_OK) {
            sl_error_prefix(err, "%s: map: %s", b->label, m->name);
            return st;
        }
        for (uint32_t i = 0; i < m->result_count; i++)
            kept[m->result[i]] = 1;
    }
    return SL_OK;
}

/* A w x h RGB image scaled down to `size` pixels along its longer side, each pixel the mean of
 * the source pixels its footprint covers (area weights, so thin lines fade instead of vanishing),
 * written as PNG. */
static sl_status write_thumbnail(const sl_allocator *a, const char *path, const uint8_t *rgb, uint32_t w, uint32_t h,
                                 uint32_t size, sl_error *err)
{
    double scale = (double)size / SL_MAX(w, h);
    uint32_t tw = SL_MAX(1u, (uint32_t)lround(w * scale)), th = SL_MAX(1u, (uint32_t)lround(h * scale));
    size_t bytes = (size_t)tw * th * 3;
    uint8_t *out = sl_alloc(a, bytes);
    if (!out)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the thumbnail", path);
    double sx = (double)w / tw, sy = (double)h / th;
    for (uint32_t ty = 0; ty < th; ty++) {
        double y0 = ty * sy, y1 = y0 + sy;
        for (uint32_t tx = 0; tx < tw; tx++) {
            double x0 = tx * sx, x1 = x0 + sx, sum[3] = {0, 0, 0}, wsum = 0;
            for (uint32_t y = (uint32_t)y0; y < h && y < y1; y++) {
                double wy = fmin(y + 1.0, y1) - fmax((double)y, y0);
                for (uint32_t x = (uint32_t)x0; x < w && x < x1; x++) {
                    double wt = wy * (fmin(x + 1.0, x1) - fmax((double)x, x0));
                    const uint8_t *p = rgb + ((size_t)y * w + x) * 3;
                    for (int c = 0; c < 3; c++)
                        sum[c] += wt * p[c];
                    wsum += wt;
                }
            }
            uint8_t *q = out + ((size_t)ty * tw + tx) * 3;
            for (int c = 0; c < 3; c++)
                q[c] = (uint8_t)lround(wsum > 0 ? sum[c] / wsum : 255);
        }
    }
    sl_status st = sl_png_write(path, tw, th, 3, out, 0, err);
    sl_free(a, out, bytes);
    return st;
}

sl_status sl_bench_write_maps(sl_bench b, const sl_bench_map_options *opt_in, const char *prefix,
                              sl_bench_map_counts *counts, sl_error *err)
{
    if (!b || !opt_in || !prefix)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_write_maps: bench, options and prefix must not be NULL");
    sl_bench_map_options o = *opt_in;
    if (!o.size)
        o.size = 1024;
    if (!o.cube_size)
        o.cube_size = 512;
    if (o.size < 16 || o.size > 8192)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_write_maps: size %u is outside 16..8192", o.size);
    if (o.cube_size < 16 || o.cube_size > 4096)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_write_maps: cube size %u is outside 16..4096",
                       o.cube_size);
    if (o.thumb_size && (o.thumb_size < 16 || o.thumb_size > o.size))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_write_maps: thumbnail size %u is outside 16..%u",
                       o.thumb_size, o.size);
    if (o.use_eye && !sl_finite3(&o.eye.x))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_write_maps: the eye is not finite");
    sl_camera cam = o.camera;
    if (!o.use_eye && b->opt.width) {
        cam.width = b->opt.width;
        cam.height = b->opt.height;
    }
    if (!o.use_eye) {
        sl_status st = sl_camera_validate(&cam, err);
        if (st != SL_OK) {
            sl_error_prefix(err, "sl_bench_write_maps: camera");
            return st;
        }
    }
    const sl_allocator *a = &b->alloc;
    uint32_t n = b->object_count;
    sl_vec3 eye = o.use_eye ? o.eye : cam.position;

    /* bounds of the map: the scene and the viewpoint, with a margin */
    sl_aabb box = sl_scene_bounds(b->scene);
    if (sl_aabb_is_empty(&box))
        box.min = box.max = eye;
    sl_aabb_grow(&box, eye);
    double ex = box.max.x - box.min.x, ey = box.max.y - box.min.y, diag = sqrt(ex * ex + ey * ey);
    double margin = 0.03 * SL_MAX(SL_MAX(ex, ey), 1.0) + 2.0;
    ex += 2 * margin, ey += 2 * margin;
    float near_plane = 0.1f, far_plane = (float)SL_MAX(5000.0, 2.0 * (diag + (box.max.z - box.min.z)));

    uint8_t *vis = sl_alloc(a, SL_MAX(n, 1)), *kept = sl_alloc(a, SL_MAX(n, 1)), *ground = sl_alloc(a, SL_MAX(n, 1));
    uint8_t *rgb = NULL;
    size_t rgb_bytes = 0;
    size_t plen = strlen(prefix) + 256;
    char *path = sl_alloc(a, plen);
    sl_oracle top = NULL;
    sl_status st = SL_OK;
    if (!vis || !kept || !ground || !path) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the map", b->label);
        goto done;
    }

    /* 1. the truth from the viewpoint (the bench's oracle: its last frame is gone afterwards) */
    b->have_truth = false;
    sl_oracle_frame fr;
    st = o.use_eye ? sl_oracle_render_cube(b->oracle, o.eye, o.cube_size, near_plane, far_plane, &fr, err)
                   : sl_oracle_render(b->oracle, &cam, &fr, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s: map", b->label);
        goto done;
    }
    memset(vis, 0, n);
    for (uint32_t i = 0; i < fr.visible_count; i++)
        vis[fr.visible[i]] = 1;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t k = sl_scene_object(b->scene, i).kind;
        ground[i] = k == SL_KIND_GROUND || k == SL_KIND_WATER;
    }

    /* 2. the scene from above: an orthographic camera straight down, north up */
    uint32_t w, h;
    if (ex >= ey) {
        w = o.size;
        h = (uint32_t)SL_MAX(16.0, lround(o.size * ey / ex));
    } else {
        h = o.size;
        w = (uint32_t)SL_MAX(16.0, lround(o.size * ex / ey));
    }
    sl_camera tc = sl_camera_default();
    tc.projection = SL_ORTHOGRAPHIC;
    tc.position = (sl_vec3){(float)(0.5 * (box.min.x + box.max.x)), (float)(0.5 * (box.min.y + box.max.y)),
                            box.max.z + 10.0f};
    tc.yaw = (float)(M_PI / 2);
    tc.pitch = -(float)(M_PI / 2);
    tc.roll = 0;
    tc.width = w;
    tc.height = h;
    /* the viewport's aspect may differ from ex/ey by rounding: cover both extents */
    tc.ortho_height = (float)SL_MAX(ey, ex * h / w);
    tc.near_plane = 1.0f;
    tc.far_plane = (float)(box.max.z - box.min.z) + 20.0f;
    sl_oracle_options oo = sl_oracle_default_options();
    oo.threads = b->opt.threads;
    st = sl_oracle_create(b->scene, &oo, a, &top, err);
    sl_oracle_frame tf;
    if (st == SL_OK)
        st = sl_oracle_render(top, &tc, &tf, err);
    sl_oracle_view tv;
    if (st == SL_OK)
        st = sl_oracle_get_view(top, 0, &tv, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s: map: top-down render", b->label);
        goto done;
    }
    sl_mat4 vp = sl_camera_view_proj(&tc);
    float dlo = INFINITY, dhi = -INFINITY;
    for (size_t i = 0; i < (size_t)w * h; i++)
        if (tv.ids[i] != SL_NONE) {
            dlo = SL_MIN(dlo, tv.depth[i]);
            dhi = SL_MAX(dhi, tv.depth[i]);
        }
    double dspan = dhi > dlo ? (double)dhi - dlo : 1.0;
    rgb_bytes = (size_t)w * h * 3;
    rgb = sl_alloc(a, rgb_bytes);
    if (!rgb) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for a %ux%u map", b->label, w, h);
        goto done;
    }
    sl_canvas canvas = {rgb, w, h};
    double ppm = h / (double)tc.ortho_height; /* pixels per metre (square pixels) */

    /* 3. one image per method */
    for (uint32_t mi = 0; mi < b->method_count; mi++) {
        bench_method *m = &b->methods[mi];
        sl_bench_map_counts cnt = {0, 0, 0, 0};
        if (!m->culler) { /* external: nothing to run from this viewpoint */
            if (counts)
                counts[mi] = cnt;
            continue;
        }
        st = method_kept(b, m, &o, &cam, near_plane, far_plane, kept, err);
        if (st != SL_OK)
            goto done;
        for (uint32_t i = 0; i < n; i++) {
            int c = vis[i] ? (kept[i] ? CLS_VISIBLE : CLS_MISSED) : (kept[i] ? CLS_EXTRA : CLS_CULLED);
            cnt.visible_kept += c == CLS_VISIBLE;
            cnt.missed += c == CLS_MISSED;
            cnt.extra += c == CLS_EXTRA;
            cnt.culled += c == CLS_CULLED;
        }
        for (size_t i = 0; i < (size_t)w * h; i++) {
            uint32_t id = tv.ids[i], col = 0xffffff;
            if (id != SL_NONE) {
                int c = vis[id] ? (kept[id] ? CLS_VISIBLE : CLS_MISSED) : (kept[id] ? CLS_EXTRA : CLS_CULLED);
                double t = ((double)tv.depth[i] - dlo) / dspan; /* 1 highest */
                col = shade(class_color[c], ground[id] && c != CLS_MISSED ? 0.5 : 0.0, 0.62 + 0.38 * t);
            }
            rgb[3 * i] = (uint8_t)(col >> 16), rgb[3 * i + 1] = (uint8_t)(col >> 8), rgb[3 * i + 2] = (uint8_t)col;
        }
        /* ring every missed object so that a single one cannot hide in the picture */
        for (uint32_t i = 0; i < n; i++) {
            if (!vis[i] || kept[i])
                continue;
            sl_aabb ob = sl_scene_object_bounds(b->scene, i);
            sl_vec3 c = {0.5f * (ob.min.x + ob.max.x), 0.5f * (ob.min.y + ob.max.y), ob.max.z};
            double px, py, r = 0.5 * ppm * hypot(ob.max.x - ob.min.x, ob.max.y - ob.min.y) + 5;
            to_pixel(&vp, w, h, c, &px, &py);
            sl_canvas_ring(&canvas, px, py, SL_MIN(r, 0.25 * SL_MAX(w, h)), class_color[CLS_MISSED], 2);
        }
        /* the viewpoint: a dot, and the frustum's horizontal wedge (filled, outlined) or a ring for
         * all directions; sized to the map so that a thumbnail still shows them */
        double ex0, ey0, unit = SL_MAX(1.0, SL_MAX(w, h) / 512.0);
        to_pixel(&vp, w, h, eye, &ex0, &ey0);
        if (o.use_eye) {
            sl_canvas_ring(&canvas, ex0, ey0, 10 * unit, FRUSTUM_COLOR, (int)lround(2 * unit));
        } else {
            sl_frustum fu = sl_camera_frustum(&cam);
            /* far corners: bl, br, tr, tl at indices 4..7; the wedge follows the mid-height of the
             * left and right far edges, clipped by the canvas */
            sl_vec3 l = {0.5f * (fu.corners[4].x + fu.corners[7].x), 0.5f * (fu.corners[4].y + fu.corners[7].y), 0};
            sl_vec3 r = {0.5f * (fu.corners[5].x + fu.corners[6].x), 0.5f * (fu.corners[5].y + fu.corners[6].y), 0};
            double lx, ly, rx, ry;
            to_pixel(&vp, w, h, l, &lx, &ly);
            to_pixel(&vp, w, h, r, &rx, &ry);
            double tx[3] = {ex0, lx, rx}, ty[3] = {ey0, ly, ry};
            fill_triangle(&canvas, tv.ids, tx, ty, FRUSTUM_COLOR, 0.22);
            sl_canvas_line(&canvas, ex0, ey0, lx, ly, FRUSTUM_COLOR, (int)lround(2 * unit));
            sl_canvas_line(&canvas, ex0, ey0, rx, ry, FRUSTUM_COLOR, (int)lround(2 * unit));
        }
        sl_canvas_disc(&canvas, ex0, ey0, 5.5 * unit, 0xffffff);
        sl_canvas_disc(&canvas, ex0, ey0, 4 * unit, 0x000000);
        draw_scale_bar(&canvas, ppm, NULL);
        snprintf(path, plen, "%s%s.png", prefix, m->name);
        st = sl_png_write(path, w, h, 3, rgb, 0, err);
        if (st == SL_OK && o.thumb_size) {
            snprintf(path, plen, "%s%s-thumb.png", prefix, m->name);
            st = write_thumbnail(a, path, rgb, w, h, o.thumb_size, err);
        }
        if (st != SL_OK)
            goto done;
        if (counts)
            counts[mi] = cnt;
    }
done:
    sl_oracle_destroy(top);
    sl_free(a, vis, SL_MAX(n, 1));
    sl_free(a, kept, SL_MAX(n, 1));
    sl_free(a, ground, SL_MAX(n, 1));
    sl_free(a, path, plen);
    sl_free(a, rgb, rgb_bytes);
    for (uint32_t mi = 0; mi < b->method_count; mi++)
        b->methods[mi].result_count = 0; /* the last results are the map's, not a frame's */
    return st;
}

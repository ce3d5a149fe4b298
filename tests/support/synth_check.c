#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sightline/cull.h"
#include "sightline/truth.h"
#include "support/synth_check.h"

typedef struct tri3 { double v[3][3]; } tri3;

static void world(const sl_object_view *ov, const float *p, double out[3])
{
    const float *m = ov->transform.m;
    out[0] = (double)m[0] * p[0] + (double)m[1] * p[1] + (double)m[2] * p[2] + m[3];
    out[1] = (double)m[4] * p[0] + (double)m[5] * p[1] + (double)m[6] * p[2] + m[7];
    out[2] = (double)m[8] * p[0] + (double)m[9] * p[1] + (double)m[10] * p[2] + m[11];
}

/* 1 inside, 0 outside, -1 the ray passed too near an edge or grazed a triangle */
static int parity(const tri3 *t, uint32_t nt, const double o[3], const double d[3])
{
    uint32_t hits = 0;
    for (uint32_t i = 0; i < nt; i++) {
        const double *a = t[i].v[0], *b = t[i].v[1], *c = t[i].v[2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
        double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        double scale = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]) *
                       sqrt(e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2]);
        double tv[3] = {o[0] - a[0], o[1] - a[1], o[2] - a[2]};
        if (fabs(det) <= 1e-9 * scale) {
            /* parallel to the plane: a hit only when the ray lies in it (then it is unclear) */
            double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            double dist = n[0] * tv[0] + n[1] * tv[1] + n[2] * tv[2];
            if (fabs(dist) <= 1e-9 * scale)
                return -1;
            continue;
        }
        double u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
        double q[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2], tv[0] * e1[1] - tv[1] * e1[0]};
        double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
        double s = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
        const double g = 1e-7;
        if (u < -g || v < -g || u + v > 1 + g || s < -g)
            continue;
        if (u < g || v < g || u + v > 1 - g || s < g)
            return -1; /* on an edge, or the point on the surface */
        hits++;
    }
    return (int)(hits & 1);
}

/* The triangles of the closed connected components (vertices equal after rounding to 0.1 mm;
 * every edge used twice, or once in the plane of the lowest z), moved to the front of t; their
 * count. The parity test holds for those only. */
typedef struct vkey { int64_t k[3]; uint32_t id; } vkey;
typedef struct ekey { uint32_t a, b, t; } ekey;
static int vkey_cmp(const void *x, const void *y)
{
    const vkey *p = x, *q = y;
    for (int i = 0; i < 3; i++)
        if (p->k[i] != q->k[i])
            return p->k[i] < q->k[i] ? -1 : 1;
    return 0;
}
static int ekey_cmp(const void *x, const void *y)
{
    const ekey *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}
static uint32_t root_of(uint32_t *par, uint32_t x)
{
    while (par[x] != x)
        x = par[x] = par[par[x]];
    return x;
}
/* T-junctions, the checker's own way (brute force, independent of synth.c's): a triangle with
 * mesh vertices strictly inside its edges (within tol of them) becomes a fan around its centroid
 * over its boundary A, points on AB, B, points on BC, C, points on CA: the same plane, and every
 * boundary piece an edge of its own. Returns the new triangle array (*nt updated); frees t. */
static tri3 *split_t(tri3 *t, uint32_t *nt, double tol)
{
    uint32_t n = *nt, cap = n ? 2 * n : 1, out_n = 0;
    tri3 *out = malloc(cap * sizeof *out);
    assert_non_null(out);
    for (uint32_t i = 0; i < n; i++) {
        double ring[3 * 66][3];
        uint32_t rn = 0;
        for (int k = 0; k < 3; k++) {
            const double *a = t[i].v[k], *b = t[i].v[(k + 1) % 3];
            double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            double pt[64], pp[64][3];
            uint32_t np = 0;
            memcpy(ring[rn++], a, sizeof ring[0]);
            for (uint32_t j = 0; j < n && len2 > 16 * tol * tol; j++)
                for (int q = 0; q < 3; q++) {
                    const double *v = t[j].v[q];
                    double r[3] = {v[0] - a[0], v[1] - a[1], v[2] - a[2]};
                    double u = (r[0] * d[0] + r[1] * d[1] + r[2] * d[2]) / len2, len = sqrt(len2);
                    if (u * len <= 2 * tol || (1 - u) * len <= 2 * tol)
                        continue;
                    double f[3] = {r[0] - u * d[0], r[1] - u * d[1], r[2] - u * d[2]};
                    if (f[0] * f[0] + f[1] * f[1] + f[2] * f[2] > tol * tol)
                        continue;
                    bool dup = false;
                    for (uint32_t m = 0; m < np && !dup; m++)
                        dup = fabs(pt[m] - u) * len <= tol;
                    if (dup || np == 64)
                        continue;
                    uint32_t at = np++;
                    while (at && pt[at - 1] > u) {
                        pt[at] = pt[at - 1];
                        memcpy(pp[at], pp[at - 1], sizeof pp[0]);
                        at--;
                    }
                    pt[at] = u;
                    memcpy(pp[at], v, sizeof pp[0]);
                }
            for (uint32_t m = 0; m < np; m++)
                memcpy(ring[rn++], pp[m], sizeof ring[0]);
        }
        if (out_n + rn > cap) {
            while (out_n + rn > cap)
                cap *= 2;
            out = realloc(out, cap * sizeof *out);
            assert_non_null(out);
        }
        if (rn == 3) {
            out[out_n++] = t[i];
            continue;
        }
        double g[3];
        for (int k = 0; k < 3; k++)
            g[k] = (t[i].v[0][k] + t[i].v[1][k] + t[i].v[2][k]) / 3;
        for (uint32_t m = 0; m < rn; m++) {
            memcpy(out[out_n].v[0], g, sizeof g);
            memcpy(out[out_n].v[1], ring[m], sizeof g);
            memcpy(out[out_n].v[2], ring[(m + 1) % rn], sizeof g);
            out_n++;
        }
    }
    free(t);
    *nt = out_n;
    return out;
}

static uint32_t keep_closed(tri3 *t, uint32_t nt)
{
    size_t nv = 3 * (size_t)nt;
    vkey *vk = malloc((nv ? nv : 1) * sizeof *vk);
    uint32_t *id = malloc((nv ? nv : 1) * sizeof *id), *par = malloc((nv ? nv : 1) * sizeof *par);
    ekey *ek = malloc((nv ? nv : 1) * sizeof *ek);
    uint8_t *bad = calloc(nv ? nv : 1, 1);
    assert_true(vk && id && par && ek && bad);
    double zmin = INFINITY;
    for (size_t i = 0; i < nv; i++) {
        const double *p = t[i / 3].v[i % 3];
        for (int k = 0; k < 3; k++)
            vk[i].k[k] = llround(p[k] * 1e4);
        vk[i].id = (uint32_t)i;
        zmin = fmin(zmin, p[2]);
    }
    qsort(vk, nv, sizeof *vk, vkey_cmp);
    uint32_t n = 0;
    for (size_t i = 0; i < nv; i++) {
        if (i > 0 && vkey_cmp(&vk[i], &vk[i - 1]) != 0)
            n++;
        id[vk[i].id] = n;
    }
    for (size_t i = 0; i < nv; i++)
        par[i] = (uint32_t)i;
    for (uint32_t i = 0; i < nt; i++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = root_of(par, id[3 * i + k]), b = root_of(par, id[3 * i + (k + 1) % 3]);
            par[a > b ? a : b] = a < b ? a : b;
            uint32_t u = id[3 * i + k], w = id[3 * i + (k + 1) % 3];
            ek[3 * i + k] = (ekey){u < w ? u : w, u < w ? w : u, i};
        }
    qsort(ek, nv, sizeof *ek, ekey_cmp);
    /* peel: drop triangles with an edge no other live triangle has (not in the lowest plane),
     * round after round until none is left (a fin, a ledge glued along an edge) */
    uint8_t *gone = calloc(nt ? nt : 1, 1);
    assert_non_null(gone);
    for (bool again = true; again;) {
        again = false;
        for (size_t i = 0; i < nv;) {
            size_t j = i, live = 0, last = 0;
            while (j < nv && ek[j].a == ek[i].a && ek[j].b == ek[i].b) {
                if (!gone[ek[j].t])
                    live++, last = j;
                j++;
            }
            if (live == 1) {
                const tri3 *tr = &t[ek[last].t];
                int ends = 0;
                for (int k = 0; k < 3; k++) {
                    uint32_t v = id[3 * ek[last].t + k];
                    if ((v == ek[last].a || v == ek[last].b) && fabs(tr->v[k][2] - zmin) < 1e-4)
                        ends++;
                }
                if (ends < 2)
                    gone[ek[last].t] = 1, again = true;
            }
            i = j;
        }
    }
    /* the live edges: dead triangles' entries dropped */
    size_t m = 0;
    for (size_t i = 0; i < nv; i++)
        if (!gone[ek[i].t])
            ek[m++] = ek[i];
    nv = m;
    for (size_t i = 0; i < nv;) {
        size_t j = i + 1;
        while (j < nv && ek[j].a == ek[i].a && ek[j].b == ek[i].b)
            j++;
        bool base;
        /* a border edge in the lowest plane: both its ends there */
        const tri3 *tr = &t[ek[i].t];
        int ends = 0;
        for (int k = 0; k < 3; k++) {
            uint32_t v = id[3 * ek[i].t + k];
            if ((v == ek[i].a || v == ek[i].b) && fabs(tr->v[k][2] - zmin) < 1e-4)
                ends++;
        }
        base = ends >= 2;
        if (!(j - i == 2 || (j - i == 1 && base)))
            bad[root_of(par, ek[i].a)] = 1;
        i = j;
    }
    uint32_t kept = 0;
    for (uint32_t i = 0; i < nt; i++)
        if (!gone[i] && !bad[root_of(par, id[3 * i])])
            t[kept++] = t[i];
    free(vk), free(id), free(par), free(ek), free(bad), free(gone);
    return kept;
}

static bool inside(const tri3 *t, uint32_t nt, const double p[3], sl_rng *rng)
{
    for (int attempt = 0; attempt < 16; attempt++) {
        double d[3], l = 0;
        do {
            for (int k = 0; k < 3; k++)
                d[k] = 2 * sl_rng_double(rng) - 1;
            l = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        } while (l < 0.01 || l > 1 || d[2] < 0.1);
        /* upward only: a surface closed but for holes in its lowest plane is closed for them */
        int r = parity(t, nt, p, d);
        if (r >= 0)
            return r == 1;
    }
    fail_msg("point (%g, %g, %g): every ray passed near an edge", p[0], p[1], p[2]);
    return false;
}

sl_synth_check sl_synth_check_object(sl_scene s, uint32_t object, uint32_t n)
{
    sl_synth_check c;
    memset(&c, 0, sizeof c);
    sl_object_view ov = sl_scene_object(s, object);
    sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
    tri3 *t = malloc((mv.triangle_count ? mv.triangle_count : 1) * sizeof *t);
    assert_non_null(t);
    double vol = 0;
    for (uint32_t i = 0; i < mv.triangle_count; i++) {
        for (int k = 0; k < 3; k++)
            world(&ov, mv.positions + 3 * (size_t)mv.indices[3 * i + k], t[i].v[k]);
        const double *a = t[i].v[0], *b = t[i].v[1], *d = t[i].v[2];
        vol += a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0]) + a[2] * (b[0] * d[1] - b[1] * d[0]);
    }
    c.mesh_volume = fabs(vol) / 6;
    uint32_t nt = mv.triangle_count;
    /* T-junctions split as the synthesis splits them (within a quarter of its default weld, 1e-6
     * of the scene's diagonal: the vertices exporters put on an edge lie on it to float rounding) */
    sl_aabb sb = sl_scene_bounds(s);
    double dx = sb.max.x - sb.min.x, dy = sb.max.y - sb.min.y, dz = sb.max.z - sb.min.z;
    t = split_t(t, &nt, 0.25e-6 * sqrt(dx * dx + dy * dy + dz * dz));
    nt = keep_closed(t, nt);
    sl_rng rng;
    sl_rng_seed(&rng, 1234 + object, 5);
    for (uint32_t i = 0; i < sl_scene_occluder_count(s); i++) {
        sl_occluder_view oc = sl_scene_occluder(s, i);
        if (oc.object != object)
            continue;
        sl_mesh_view bm = sl_scene_mesh(s, oc.mesh);
        assert_int_equal(bm.vertex_count % 8, 0);
        assert_int_equal(bm.triangle_count, bm.vertex_count / 8 * 12);
        for (uint32_t b = 0; b < bm.vertex_count / 8; b++) {
            const float *lo = bm.positions + 24 * (size_t)b, *hi = lo + 21;
            c.boxes++;
            c.box_volume += ((double)hi[0] - lo[0]) * ((double)hi[1] - lo[1]) * ((double)hi[2] - lo[2]);
            for (uint32_t z = 0; z <= n; z++)
                for (uint32_t y = 0; y <= n; y++)
                    for (uint32_t x = 0; x <= n; x++) {
                        /* the occluder's own transform (identity for synthesised ones) */
                        float fp[3] = {lo[0] + (hi[0] - lo[0]) * (float)x / (float)n,
                                       lo[1] + (hi[1] - lo[1]) * (float)y / (float)n,
                                       lo[2] + (hi[2] - lo[2]) * (float)z / (float)n};
                        sl_vec3 w = sl_affine_point(&oc.transform, (sl_vec3){fp[0], fp[1], fp[2]});
                        double p[3] = {w.x, w.y, w.z};
                        c.points++;
                        if (!inside(t, nt, p, &rng))
                            c.outside_points++;
                    }
            for (uint32_t v = 0; v < 3 * nt; v++) { /* the closed parts' vertices */
                const double *p = t[v / 3].v[v % 3];
                bool in = true;
                for (int k = 0; k < 3 && in; k++)
                    in = p[k] > lo[k] && p[k] < hi[k];
                c.vertices_inside += in;
            }
        }
    }
    free(t);
    return c;
}

sl_synth_views sl_synth_run_views(sl_scene s, const char *method, const char *options, const sl_camera *cams,
                                  uint32_t n)
{
    return sl_synth_run_views_judged(s, method, options, cams, n, 0, SL_ORACLE_SAMPLES_CENTER);
}

sl_synth_views sl_synth_run_views_judged(sl_scene s, const char *method, const char *options, const sl_camera *cams,
                                         uint32_t n, uint32_t scale, sl_oracle_samples samples)
{
    sl_synth_views r;
    memset(&r, 0, sizeof r);
    sl_error err;
    sl_oracle o;
    sl_culler c;
    sl_oracle_options oo = sl_oracle_default_options();
    if (scale && n) {
        oo.width = cams[0].width * scale;
        oo.height = cams[0].height * scale;
        oo.samples = samples;
        oo.sample_count = 4;
        oo.jitter_seed = 20261202;
    }
    if (sl_oracle_create(s, scale ? &oo : NULL, NULL, &o, &err) != SL_OK)
        fail_msg("oracle: %s", err.message);
    if (sl_culler_create(method, s, options, NULL, &c, &err) != SL_OK)
        fail_msg("%s: %s", method, err.message);
    uint32_t no = sl_scene_object_count(s);
    uint32_t *out = malloc((no ? no : 1) * sizeof *out);
    assert_non_null(out);
    for (uint32_t f = 0; f < n; f++) {
        sl_oracle_frame fr;
        if (sl_oracle_render(o, &cams[f], &fr, &err) != SL_OK)
            fail_msg("oracle frame %u: %s", f, err.message);
        uint32_t k;
        if (sl_culler_cull(c, &cams[f], out, no, &k, &err) != SL_OK)
            fail_msg("%s frame %u: %s", method, f, err.message);
        sl_cull_metrics mt;
        uint32_t missed[4], mpx[4];
        if (sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err) != SL_OK)
            fail_msg("metrics: %s", err.message);
        if (mt.missed_count && !r.missed)
            print_message("%s %s: frame %u missed %u objects (first %u, %u pixels); eye (%.3f, %.3f, %.3f) yaw %.4f "
                          "pitch %.4f\n",
                          method, options ? options : "", f, mt.missed_count, missed[0], mpx[0],
                          (double)cams[f].position.x, (double)cams[f].position.y, (double)cams[f].position.z,
                          (double)cams[f].yaw, (double)cams[f].pitch);
        r.kept += k;
        r.visible += fr.visible_count;
        r.missed += mt.missed_count;
        r.frames++;
    }
    r.overestimation = r.visible ? (double)r.kept / (double)r.visible : 0;
    free(out);
    sl_culler_destroy(c);
    sl_oracle_destroy(o);
    return r;
}

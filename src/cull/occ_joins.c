/* Joins across shared prism walls: see occ_joins.h. */
#include "occ_joins.h"

#include "occluders.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    double x, y;
} jvec2;

/* Half-widths tried (metres into each side), largest first, and the margins along the wall kept
 * from the ends of the shared segment (in units of the half-width, after a minimum). */
static const double g_widths[] = {6.0, 3.0, 1.5, 0.75, 0.4, 0.2};
static const double g_margins[] = {0.0, 0.5, 1.0, 2.0};

/* Does segment (s_a, u_a) -> (s_b, u_b) meet the closed rectangle [s0, s1] x [u0, u1]?
 * (Liang-Barsky; touching counts.) */
static bool seg_meets_rect(double sa, double ua, double sb, double ub, double s0, double s1, double u0, double u1)
{
    double t0 = 0, t1 = 1;
    const double p[4] = {-(sb - sa), sb - sa, -(ub - ua), ub - ua};
    const double q[4] = {sa - s0, s1 - sa, ua - u0, u1 - ua};
    for (int k = 0; k < 4; k++) {
        if (p[k] == 0) {
            if (q[k] < 0)
                return false;
            continue;
        }
        double r = q[k] / p[k];
        if (p[k] < 0)
            t0 = r > t0 ? r : t0;
        else
            t1 = r < t1 ? r : t1;
        if (t0 > t1)
            return false;
    }
    return true;
}

static bool point_in_poly_f(jvec2 p, const float *xy, uint32_t n)
{
    bool in = false;
    for (uint32_t i = 0, j = n - 1; i < n; j = i++) {
        double xi = xy[2 * i], yi = xy[2 * i + 1], xj = xy[2 * j], yj = xy[2 * j + 1];
        if ((yi > p.y) != (yj > p.y) && p.x < (xj - xi) * (p.y - yi) / (yj - yi) + xi)
            in = !in;
    }
    return in;
}

/* Is the closed rectangle {o + s t + u w : s0 <= s <= s1, u0 <= u <= u1} (t, w orthonormal)
 * inside the closed simple polygon xy[0..n)? Sufficient test: no edge but `skip` (SL_NONE: none)
 * meets it and its centre is strictly inside. Then the rectangle less the skipped edge is one
 * connected set free of the boundary, so inside; the skipped edge is boundary, inside the closed
 * polygon. (Callers only skip an edge that lies on a side of the rectangle or outside it.) */
static bool rect_in_poly(jvec2 o, jvec2 t, jvec2 w, double s0, double s1, double u0, double u1, const float *xy,
                         uint32_t n, uint32_t skip)
{
    for (uint32_t i = 0; i < n; i++) {
        if (i == skip)
            continue;
        uint32_t j = (i + 1) % n;
        double ax = xy[2 * i] - o.x, ay = xy[2 * i + 1] - o.y, bx = xy[2 * j] - o.x, by = xy[2 * j + 1] - o.y;
        if (seg_meets_rect(ax * t.x + ay * t.y, ax * w.x + ay * w.y, bx * t.x + by * t.y, bx * w.x + by * w.y, s0, s1,
                           u0, u1))
            return false;
    }
    double sc = 0.5 * (s0 + s1), uc = 0.5 * (u0 + u1);
    return point_in_poly_f((jvec2){o.x + sc * t.x + uc * w.x, o.y + sc * t.y + uc * w.y}, xy, n);
}

typedef struct jbuild {
    const sl_allocator *a;
    sl_array joins;  /* sl_occ_join */
    sl_array owner;  /* uint32_t per join */
    double inset;
    uint32_t across, inside;
    bool oom;
} jbuild;

static void push_join(jbuild *b, uint32_t owner, uint32_t partner, jvec2 o, jvec2 t, jvec2 w, double s0, double s1,
                      double u0, double u1, double z0, double z1)
{
    sl_occ_join j;
    memset(&j, 0, sizeof j);
    j.partner = partner;
    j.z0 = (float)z0;
    j.box = sl_aabb_empty();
    const double su[4][2] = {{s0, u0}, {s1, u0}, {s1, u1}, {s0, u1}}; /* CCW: w is t turned left */
    for (int k = 0; k < 4; k++) {
        j.top[k][0] = (float)(o.x + su[k][0] * t.x + su[k][1] * w.x);
        j.top[k][1] = (float)(o.y + su[k][0] * t.y + su[k][1] * w.y);
        j.top[k][2] = (float)z1;
        sl_aabb_grow(&j.box, (sl_vec3){j.top[k][0], j.top[k][1], j.top[k][2]});
        sl_aabb_grow(&j.box, (sl_vec3){j.top[k][0], j.top[k][1], j.z0});
    }
    if (!sl_array_push(b->a, &b->joins, sizeof j, &j, 1) || !sl_array_push(b->a, &b->owner, sizeof owner, &owner, 1))
        b->oom = true;
}

/* Float rounding of a join's vertices must stay well inside the margins kept (as add_prism). */
static bool coords_ok(const jbuild *b, jvec2 o, double reach, double z0, double z1)
{
    double maxc = fmax(fmax(fabs(o.x), fabs(o.y)) + reach, fmax(fabs(z0), fabs(z1)));
    return maxc * 4.0 * FLT_EPSILON <= 0.25 * b->inset;
}

/* Across edge ia of footprint A (its interior on the left, +w) and edge ib of footprint B,
 * antiparallel on the same line: a join owned by proxy pa, partner pb. */
static void try_across(jbuild *b, uint32_t pa, const sl_footprint_view *A, uint32_t ia, uint32_t pb,
                       const sl_footprint_view *B, uint32_t ib)
{
    const float *a0 = A->xy + 2 * ia, *a1 = A->xy + 2 * ((ia + 1) % A->vertex_count);
    const float *b0 = B->xy + 2 * ib, *b1 = B->xy + 2 * ((ib + 1) % B->vertex_count);
    double ex = (double)a1[0] - a0[0], ey = (double)a1[1] - a0[1], len = sqrt(ex * ex + ey * ey);
    double fx = (double)b1[0] - b0[0], fy = (double)b1[1] - b0[1], lenb = sqrt(fx * fx + fy * fy);
    if (!(len > 0.5) || !(lenb > 0.5))
        return;
    jvec2 t = {ex / len, ey / len}, w = {-t.y, t.x}, o = {a0[0], a0[1]};
    if (!((t.x * fx + t.y * fy) / lenb < -(1.0 - 1e-8)))
        return; /* not antiparallel */
    /* B's endpoints on A's side of a's line or on it (no gap between the footprints): the cross
     * product is exact but for its last rounding, so "on the line" allows only that */
    double eb[2];
    for (int k = 0; k < 2; k++) {
        const float *p = k ? b1 : b0;
        double px = (double)p[0] - a0[0], py = (double)p[1] - a0[1];
        double cr = ex * py - ey * px, bound = 8.0 * DBL_EPSILON * (fabs(ex * py) + fabs(ey * px));
        if (cr < -bound)
            return;
        eb[k] = cr / len;
        if (eb[k] > 1e-3)
            return; /* not on one line */
    }
    double sb0 = ((double)b0[0] - a0[0]) * t.x + ((double)b0[1] - a0[1]) * t.y;
    double sb1 = ((double)b1[0] - a0[0]) * t.x + ((double)b1[1] - a0[1]) * t.y;
    double ov0 = fmax(0.0, fmin(sb0, sb1)), ov1 = fmin(len, fmax(sb0, sb1));
    const double d = b->inset;
    double z0 = fmax((double)A->base_z, (double)B->base_z) + d, z1 = fmin((double)A->roof_z, (double)B->roof_z) - d;
    if (!(ov1 - ov0 > 4 * d + 0.2) || !(z1 - z0 > 0.01))
        return;
    for (size_t wi = 0; wi < sizeof g_widths / sizeof g_widths[0]; wi++) {
        double hw = g_widths[wi];
        for (size_t mi = 0; mi < sizeof g_margins / sizeof g_margins[0]; mi++) {
            double m = fmax(0.5 * d, g_margins[mi] * hw);
            double s0 = ov0 + m, s1 = ov1 - m;
            if (!(s1 - s0 > 2 * d + 0.1))
                break;
            if (!coords_ok(b, o, len + hw, z0, z1))
                return;
            /* A's half on its interior side of a, B's on the other; each less its own wall edge,
             * which lies on the common side (a) or on A's side of it (b, within A's half) */
            if (rect_in_poly(o, t, w, s0, s1, 0.0, hw, A->xy, A->vertex_count, ia) &&
                rect_in_poly(o, t, w, s0, s1, -hw, 0.0, B->xy, B->vertex_count, ib)) {
                push_join(b, pa, pb, o, t, w, s0 + 0.5 * d, s1 - 0.5 * d, -hw + d, hw - d, z0, z1);
                b->across++;
                return;
            }
        }
    }
}

/* Across the edge p -> q that two convex roof pieces of prism proxy pi share (a diagonal of its
 * footprint's decomposition): a join inside footprint F, between heights z0 and z1 (the prism's). */
static void try_inside(jbuild *b, uint32_t pi, const sl_footprint_view *F, sl_vec3 p, sl_vec3 q, double z0,
                       double z1)
{
    double ex = (double)q.x - p.x, ey = (double)q.y - p.y, len = sqrt(ex * ex + ey * ey);
    if (!(len > 0.5) || !(z1 - z0 > 0.01))
        return;
    jvec2 t = {ex / len, ey / len}, w = {-t.y, t.x}, o = {p.x, p.y};
    const double d = b->inset;
    for (size_t wi = 0; wi < sizeof g_widths / sizeof g_widths[0]; wi++) {
        double hw = g_widths[wi];
        for (size_t mi = 0; mi < sizeof g_margins / sizeof g_margins[0]; mi++) {
            double m = fmax(0.5 * d, g_margins[mi] * hw);
            double s0 = m, s1 = len - m;
            if (!(s1 - s0 > 2 * d + 0.1))
                break;
            if (!coords_ok(b, o, len + hw, z0, z1))
                return;
            if (rect_in_poly(o, t, w, s0, s1, -hw, hw, F->xy, F->vertex_count, SL_NONE)) {
                push_join(b, pi, pi, o, t, w, s0 + 0.5 * d, s1 - 0.5 * d, -hw + d, hw - d, z0, z1);
                b->inside++;
                return;
            }
        }
    }
}

typedef struct fp_entry {
    uint32_t proxy;
    float min_x, max_x, min_y, max_y;
} fp_entry;

static int cmp_fp(const void *x, const void *y)
{
    const fp_entry *a = x, *b = y;
    if (a->min_x != b->min_x)
        return a->min_x < b->min_x ? -1 : 1;
    return a->proxy < b->proxy ? -1 : a->proxy > b->proxy;
}

static int cmp_owner(const void *x, const void *y)
{
    const uint32_t *a = x, *b = y;
    return a[0] < b[0] ? -1 : a[0] > b[0] ? 1 : (a[1] < b[1] ? -1 : a[1] > b[1]);
}

sl_status sl_occ_joins_build(const sl_occ_set *s, double inset, const sl_allocator *a, sl_occ_joins **out,
                             sl_error *err)
{
    *out = NULL;
    jbuild b;
    memset(&b, 0, sizeof b);
    b.a = a;
    b.inset = fmax(inset, 0.01);
    /* 1. inside one prism: pairs of convex roof pieces with a common edge */
    for (uint32_t p = 0; p < s->proxy_count && !b.oom; p++) {
        const sl_occ_proxy *pr = &s->proxies[p];
        if (pr->kind != SL_OCC_PRISM)
            continue;
        sl_footprint_view F = sl_scene_footprint(s->scene, pr->source);
        for (uint32_t i = 0; i < pr->face_count; i++) {
            const sl_occ_face *fi = &s->faces[pr->face_first + i];
            if (!(fi->normal.z > 0.5f) || fi->count < 3)
                continue;
            for (uint32_t j = i + 1; j < pr->face_count; j++) {
                const sl_occ_face *fj = &s->faces[pr->face_first + j];
                if (!(fj->normal.z > 0.5f) || fj->count < 3)
                    continue;
                for (uint32_t e = 0; e < fi->count; e++) {
                    sl_vec3 p0 = s->face_verts[fi->first + e], p1 = s->face_verts[fi->first + (e + 1) % fi->count];
                    for (uint32_t k = 0; k < fj->count; k++) {
                        sl_vec3 q0 = s->face_verts[fj->first + k], q1 = s->face_verts[fj->first + (k + 1) % fj->count];
                        if (p0.x == q1.x && p0.y == q1.y && p1.x == q0.x && p1.y == q0.y)
                            try_inside(&b, p, &F, p0, p1, (double)pr->box.min.z, (double)p0.z);
                    }
                }
            }
        }
    }
    /* 2. across party walls: prisms whose footprints' boxes touch (sweep along x) */
    uint32_t np = 0;
    for (uint32_t p = 0; p < s->proxy_count; p++)
        np += s->proxies[p].kind == SL_OCC_PRISM;
    fp_entry *fe = np ? sl_alloc(a, np * sizeof *fe) : NULL;
    if (np && !fe)
        b.oom = true;
    uint32_t k = 0;
    for (uint32_t p = 0; p < s->proxy_count && fe; p++) {
        if (s->proxies[p].kind != SL_OCC_PRISM)
            continue;
        sl_footprint_view F = sl_scene_footprint(s->scene, s->proxies[p].source);
        fp_entry e = {p, INFINITY, -INFINITY, INFINITY, -INFINITY};
        for (uint32_t i = 0; i < F.vertex_count; i++) {
            e.min_x = fminf(e.min_x, F.xy[2 * i]), e.max_x = fmaxf(e.max_x, F.xy[2 * i]);
            e.min_y = fminf(e.min_y, F.xy[2 * i + 1]), e.max_y = fmaxf(e.max_y, F.xy[2 * i + 1]);
        }
        fe[k++] = e;
    }
    if (fe)
        qsort(fe, np, sizeof *fe, cmp_fp);
    for (uint32_t i = 0; i < np && !b.oom; i++) {
        sl_footprint_view A = sl_scene_footprint(s->scene, s->proxies[fe[i].proxy].source);
        for (uint32_t j = i + 1; j < np && fe[j].min_x <= fe[i].max_x + 1e-3f && !b.oom; j++) {
            if (fe[j].min_y > fe[i].max_y + 1e-3f || fe[j].max_y < fe[i].min_y - 1e-3f)
                continue;
            sl_footprint_view B = sl_scene_footprint(s->scene, s->proxies[fe[j].proxy].source);
            uint32_t pa = fe[i].proxy < fe[j].proxy ? fe[i].proxy : fe[j].proxy;
            uint32_t pb = pa == fe[i].proxy ? fe[j].proxy : fe[i].proxy;
            const sl_footprint_view *FA = pa == fe[i].proxy ? &A : &B, *FB = pa == fe[i].proxy ? &B : &A;
            for (uint32_t ea = 0; ea < FA->vertex_count; ea++)
                for (uint32_t eb = 0; eb < FB->vertex_count; eb++)
                    try_across(&b, pa, FA, ea, pb, FB, eb);
        }
    }
    sl_free(a, fe, np * sizeof *fe);
    sl_status st = SL_OK;
    size_t n = b.joins.count;
    if (b.oom) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for joins");
        goto done;
    }
    if (!n)
        goto done;
    sl_occ_joins *j = sl_calloc(a, 1, sizeof *j);
    uint32_t *order = sl_alloc(a, 2 * n * sizeof(uint32_t));
    if (j) {
        j->proxy_count = s->proxy_count;
        j->count = (uint32_t)n;
        j->first = sl_calloc(a, (size_t)s->proxy_count + 1, sizeof(uint32_t));
        j->joins = sl_alloc(a, n * sizeof(sl_occ_join));
    }
    if (!j || !order || !j->first || !j->joins) {
        sl_free(a, order, 2 * n * sizeof(uint32_t));
        sl_occ_joins_destroy(j, a);
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluders: out of memory for joins");
        goto done;
    }
    /* grouped by owner, in the order found within one owner */
    const uint32_t *own = b.owner.data;
    for (size_t i = 0; i < n; i++)
        order[2 * i] = own[i], order[2 * i + 1] = (uint32_t)i;
    qsort(order, n, 2 * sizeof(uint32_t), cmp_owner);
    const sl_occ_join *src = b.joins.data;
    for (size_t i = 0; i < n; i++) {
        j->joins[i] = src[order[2 * i + 1]];
        j->first[order[2 * i] + 1]++;
    }
    for (uint32_t p = 0; p < s->proxy_count; p++)
        j->first[p + 1] += j->first[p];
    j->across = b.across;
    j->inside = b.inside;
    sl_free(a, order, 2 * n * sizeof(uint32_t));
    *out = j;
done:
    sl_array_free(a, &b.joins, sizeof(sl_occ_join));
    sl_array_free(a, &b.owner, sizeof(uint32_t));
    return st;
}

void sl_occ_joins_destroy(sl_occ_joins *j, const sl_allocator *a)
{
    if (!j)
        return;
    sl_free(a, j->first, ((size_t)j->proxy_count + 1) * sizeof(uint32_t));
    sl_free(a, j->joins, (size_t)j->count * sizeof(sl_occ_join));
    sl_free(a, j, sizeof *j);
}

bool sl_occ_join_usable(const sl_occ_set *s, uint32_t owner, const sl_occ_join *j, const sl_occ_view *v)
{
    if (j->partner != owner && !sl_occ_usable(s, j->partner, v))
        return false;
    float g = 1e-3f + 1e-6f * (fabsf(v->eye.x) + fabsf(v->eye.y) + fabsf(v->eye.z));
    return !sl_occ_point_in_box(v->eye, &j->box, g) && sl_occ_near_clear(v, &j->box);
}

/* City generator: 2D polygon helpers (offsets, convexity, ear clipping) and the scratch mesh
 * builder with its flat-shaded primitives. Polygons are small (<= GC_MAX_POLY vertices), so the
 * quadratic algorithms here are the fast ones. */
#include "gen_city_internal.h"

/* ---- 2D polygons ---- */

bool gc_line_isect(sl_dvec2 p, sl_dvec2 d, sl_dvec2 q, sl_dvec2 e, sl_dvec2 *out)
{
    double den = sl_d2_cross(d, e);
    double scale = sl_d2_len(d) * sl_d2_len(e);
    if (!(fabs(den) > 1e-9 * scale))
        return false;
    double t = sl_d2_cross(sl_d2_sub(q, p), e) / den;
    *out = sl_d2_add(p, sl_d2_scale(d, t));
    return true;
}

double gc_area(const sl_dvec2 *p, int n)
{
    double a = 0;
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        a += p[i].x * p[j].y - p[j].x * p[i].y;
    }
    return 0.5 * a;
}

bool gc_convex(const sl_dvec2 *p, int n)
{
    for (int i = 0; i < n; i++) {
        sl_dvec2 a = p[(i + n - 1) % n], b = p[i], c = p[(i + 1) % n];
        if (!(sl_d2_cross(sl_d2_sub(b, a), sl_d2_sub(c, b)) > 1e-9))
            return false;
    }
    return true;
}

static int orient2(sl_dvec2 a, sl_dvec2 b, sl_dvec2 c)
{
    double v = sl_d2_cross(sl_d2_sub(b, a), sl_d2_sub(c, a));
    return (v > 0) - (v < 0);
}

static bool seg_touch(sl_dvec2 a, sl_dvec2 b, sl_dvec2 c, sl_dvec2 d)
{
    int o1 = orient2(a, b, c), o2 = orient2(a, b, d), o3 = orient2(c, d, a), o4 = orient2(c, d, b);
    if (o1 != o2 && o3 != o4)
        return true;
    /* collinear overlap */
    if (o1 == 0 && o2 == 0) {
        sl_dvec2 u = sl_d2_sub(b, a);
        double t0 = sl_d2_dot(sl_d2_sub(c, a), u), t1 = sl_d2_dot(sl_d2_sub(d, a), u), l = sl_d2_dot(u, u);
        return !(SL_MAX(t0, t1) < 0 || SL_MIN(t0, t1) > l);
    }
    return false;
}

bool gc_simple(const sl_dvec2 *p, int n)
{
    for (int i = 0; i < n; i++)
        for (int j = i + 2; j < n; j++) {
            if (i == 0 && j == n - 1)
                continue;
            if (seg_touch(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]))
                return false;
        }
    return true;
}

double gc_min_edge(const sl_dvec2 *p, int n)
{
    double m = INFINITY;
    for (int i = 0; i < n; i++)
        m = fmin(m, sl_d2_len(sl_d2_sub(p[(i + 1) % n], p[i])));
    return m;
}

bool gc_offset(const sl_dvec2 *p, int n, const double *off, sl_dvec2 *out)
{
    for (int i = 0; i < n; i++) {
        int h = (i + n - 1) % n;
        sl_dvec2 dh = sl_d2_sub(p[i], p[h]), di = sl_d2_sub(p[(i + 1) % n], p[i]);
        sl_dvec2 nh = sl_d2_left(sl_d2_unit(dh)), ni = sl_d2_left(sl_d2_unit(di));
        sl_dvec2 ph = sl_d2_add(p[h], sl_d2_scale(nh, off[h])), pi = sl_d2_add(p[i], sl_d2_scale(ni, off[i]));
        if (!gc_line_isect(ph, dh, pi, di, &out[i])) {
            /* collinear neighbours: the moved vertex is the mean of both moved positions */
            sl_dvec2 a = sl_d2_add(p[i], sl_d2_scale(nh, off[h])), b = sl_d2_add(p[i], sl_d2_scale(ni, off[i]));
            out[i] = sl_d2_lerp(a, b, 0.5);
        }
    }
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        sl_dvec2 eo = sl_d2_sub(p[j], p[i]), en = sl_d2_sub(out[j], out[i]);
        if (!(sl_d2_dot(eo, en) > 0) || !(sl_d2_len(en) > 0.05))
            return false;
    }
    return gc_area(out, n) > 0.01;
}

bool gc_offset_all(const sl_dvec2 *p, int n, double off, sl_dvec2 *out)
{
    double o[GC_MAX_POLY];
    for (int i = 0; i < n; i++)
        o[i] = off;
    return gc_offset(p, n, o, out);
}

double gc_max_inset(const sl_dvec2 *p, int n)
{
    sl_dvec2 tmp[GC_MAX_POLY];
    double lo = 0, hi = sqrt(fabs(gc_area(p, n)));
    for (int it = 0; it < 24; it++) {
        double mid = 0.5 * (lo + hi);
        if (gc_offset_all(p, n, mid, tmp) && gc_convex(tmp, n))
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

bool gc_inside_convex(const sl_dvec2 *p, int n, sl_dvec2 q, double margin)
{
    for (int i = 0; i < n; i++) {
        sl_dvec2 d = sl_d2_sub(p[(i + 1) % n], p[i]);
        double l = sl_d2_len(d);
        if (!(l > 0) || sl_d2_cross(d, sl_d2_sub(q, p[i])) / l < margin)
            return false;
    }
    return true;
}

static bool in_triangle(sl_dvec2 a, sl_dvec2 b, sl_dvec2 c, sl_dvec2 q)
{
    return sl_d2_cross(sl_d2_sub(b, a), sl_d2_sub(q, a)) >= 0 && sl_d2_cross(sl_d2_sub(c, b), sl_d2_sub(q, b)) >= 0 &&
           sl_d2_cross(sl_d2_sub(a, c), sl_d2_sub(q, c)) >= 0;
}

int gc_triangulate(const sl_dvec2 *p, int n, uint8_t tri[][3])
{
    uint8_t v[GC_MAX_POLY];
    int m = n, t = 0;
    for (int i = 0; i < n; i++)
        v[i] = (uint8_t)i;
    while (m > 3) {
        int ear = -1;
        for (int k = 0; k < m && ear < 0; k++) {
            sl_dvec2 a = p[v[(k + m - 1) % m]], b = p[v[k]], c = p[v[(k + 1) % m]];
            if (!(sl_d2_cross(sl_d2_sub(b, a), sl_d2_sub(c, b)) > 1e-12))
                continue; /* reflex or flat: not an ear */
            bool empty = true;
            for (int q = 0; q < m && empty; q++) {
                if (q == k || q == (k + 1) % m || q == (k + m - 1) % m)
                    continue;
                sl_dvec2 r = p[v[q]];
                /* a vertex coinciding with a corner (touching polygons) does not block the ear */
                if ((r.x == a.x && r.y == a.y) || (r.x == c.x && r.y == c.y))
                    continue;
                if (in_triangle(a, b, c, r))
                    empty = false;
            }
            if (empty)
                ear = k;
        }
        if (ear < 0)
            ear = 0; /* only for degenerate input: still terminates with n-2 triangles */
        tri[t][0] = v[(ear + m - 1) % m], tri[t][1] = v[ear], tri[t][2] = v[(ear + 1) % m];
        t++;
        for (int k = ear; k < m - 1; k++)
            v[k] = v[k + 1];
        m--;
    }
    tri[t][0] = v[0], tri[t][1] = v[1], tri[t][2] = v[2];
    return t + 1;
}

/* ---- mesh builder ---- */

void gc_mesh_init(gc_mesh *m, const sl_allocator *a)
{
    memset(m, 0, sizeof *m);
    m->alloc = a;
}

void gc_mesh_free(gc_mesh *m)
{
    sl_free(m->alloc, m->pos, (size_t)m->cap_v * 3 * sizeof(float));
    sl_free(m->alloc, m->nrm, (size_t)m->cap_v * 3 * sizeof(float));
    sl_free(m->alloc, m->idx, (size_t)m->cap_t * 3 * sizeof(uint32_t));
    m->pos = m->nrm = NULL;
    m->idx = NULL;
    m->cap_v = m->cap_t = m->nv = m->nt = 0;
}

bool gc_mesh_reserve(gc_mesh *m, uint32_t nv, uint32_t nt)
{
    if (m->oom)
        return false;
    if ((uint64_t)m->nv + nv > m->cap_v) {
        uint64_t cap = m->cap_v ? m->cap_v : 4096;
        while (cap < (uint64_t)m->nv + nv)
            cap *= 2;
        if (cap > UINT32_MAX / 4) {
            m->oom = true;
            return false;
        }
        /* grow both vertex arrays or neither, so that one capacity describes both */
        size_t ob = (size_t)m->cap_v * 3 * sizeof(float), nb = (size_t)cap * 3 * sizeof(float);
        float *p = sl_alloc(m->alloc, nb), *q = sl_alloc(m->alloc, nb);
        if (!p || !q) {
            sl_free(m->alloc, p, nb);
            sl_free(m->alloc, q, nb);
            m->oom = true;
            return false;
        }
        if (m->nv) {
            memcpy(p, m->pos, (size_t)m->nv * 3 * sizeof(float));
            memcpy(q, m->nrm, (size_t)m->nv * 3 * sizeof(float));
        }
        sl_free(m->alloc, m->pos, ob);
        sl_free(m->alloc, m->nrm, ob);
        m->pos = p, m->nrm = q;
        m->cap_v = (uint32_t)cap;
    }
    if ((uint64_t)m->nt + nt > m->cap_t) {
        uint64_t cap = m->cap_t ? m->cap_t : 4096;
        while (cap < (uint64_t)m->nt + nt)
            cap *= 2;
        if (cap > UINT32_MAX / 4) {
            m->oom = true;
            return false;
        }
        uint32_t *p = sl_realloc(m->alloc, m->idx, (size_t)m->cap_t * 3 * sizeof(uint32_t), (size_t)cap * 3 * sizeof(uint32_t));
        if (!p) {
            m->oom = true;
            return false;
        }
        m->idx = p;
        m->cap_t = (uint32_t)cap;
    }
    return true;
}

void gc_face(gc_mesh *m, const sl_dvec3 *p, int n, sl_dvec3 want)
{
    /* Newell's normal: robust for any planar polygon, and its length is twice the area */
    sl_dvec3 nn = {0, 0, 0};
    for (int i = 0; i < n; i++) {
        sl_dvec3 a = p[i], b = p[(i + 1) % n];
        nn.x += (a.y - b.y) * (a.z + b.z);
        nn.y += (a.z - b.z) * (a.x + b.x);
        nn.z += (a.x - b.x) * (a.y + b.y);
    }
    double l = sqrt(sl_d3_dot(nn, nn));
    if (!(l > 1e-9))
        return;
    nn = sl_d3_scale(nn, 1.0 / l);
    bool flip = sl_d3_dot(nn, want) < 0;
    if (flip)
        nn = sl_d3_scale(nn, -1.0);
    if (!gc_mesh_reserve(m, (uint32_t)n, (uint32_t)(n - 2)))
        return;
    uint32_t base = m->nv;
    for (int i = 0; i < n; i++)
        gc_vert(m, p[flip ? n - 1 - i : i], nn);
    for (int i = 1; i + 1 < n; i++)
        gc_tri_idx(m, base, base + (uint32_t)i, base + (uint32_t)i + 1);
}

void gc_quad(gc_mesh *m, sl_dvec3 a, sl_dvec3 b, sl_dvec3 c, sl_dvec3 d, sl_dvec3 want)
{
    sl_dvec3 p[4] = {a, b, c, d};
    gc_face(m, p, 4, want);
}

void gc_tri(gc_mesh *m, sl_dvec3 a, sl_dvec3 b, sl_dvec3 c, sl_dvec3 want)
{
    sl_dvec3 p[3] = {a, b, c};
    gc_face(m, p, 3, want);
}

void gc_cap(gc_mesh *m, const sl_dvec2 *p, int n, double z, bool up)
{
    uint8_t tri[GC_MAX_POLY][3];
    int nt;
    if (gc_convex(p, n)) {
        for (int i = 1; i + 1 < n; i++)
            tri[i - 1][0] = 0, tri[i - 1][1] = (uint8_t)i, tri[i - 1][2] = (uint8_t)(i + 1);
        nt = n - 2;
    } else {
        nt = gc_triangulate(p, n, tri);
    }
    if (!gc_mesh_reserve(m, (uint32_t)n, (uint32_t)nt))
        return;
    sl_dvec3 nn = sl_d3(0, 0, up ? 1 : -1);
    uint32_t base = m->nv;
    for (int i = 0; i < n; i++)
        gc_vert(m, sl_d3_of_d2(p[i], z), nn);
    for (int t = 0; t < nt; t++) {
        if (up)
            gc_tri_idx(m, base + tri[t][0], base + tri[t][1], base + tri[t][2]);
        else
            gc_tri_idx(m, base + tri[t][0], base + tri[t][2], base + tri[t][1]);
    }
}

void gc_prism(gc_mesh *m, const sl_dvec2 *p, int n, double z0, double z1, bool top, bool bottom)
{
    sl_dvec3 none = {0, 0, 0};
    for (int i = 0; i < n; i++) {
        sl_dvec2 a = p[i], b = p[(i + 1) % n];
        gc_quad(m, sl_d3_of_d2(a, z0), sl_d3_of_d2(b, z0), sl_d3_of_d2(b, z1), sl_d3_of_d2(a, z1), none);
    }
    if (top)
        gc_cap(m, p, n, z1, true);
    if (bottom)
        gc_cap(m, p, n, z0, false);
}

void gc_box(gc_mesh *m, sl_dvec3 lo, sl_dvec3 hi, bool bottom)
{
    sl_dvec2 r[4] = {{lo.x, lo.y}, {hi.x, lo.y}, {hi.x, hi.y}, {lo.x, hi.y}};
    gc_prism(m, r, 4, lo.z, hi.z, true, bottom);
}

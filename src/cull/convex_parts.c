/* Convex parts of an occluder mesh: see convex_parts.h. */
#include "convex_parts.h"

#include "core/sl_core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct weld_key {
    float p[3];
    uint32_t i;
} weld_key;

static int cmp_weld(const void *a, const void *b)
{
    const weld_key *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x->p[k] != y->p[k])
            return x->p[k] < y->p[k] ? -1 : 1;
    return x->i < y->i ? -1 : x->i > y->i;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

static void dsub(const double *a, const double *b, double *o)
{
    o[0] = a[0] - b[0], o[1] = a[1] - b[1], o[2] = a[2] - b[2];
}

static void dcross(const double *a, const double *b, double *o)
{
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}

static double ddot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Check one component (triangles comp[0..nt), welded vertex ids) and, when convex, append it. */
static bool try_part(const double (*wp)[3], const uint32_t *weld, const uint32_t *idx, const uint32_t *comp,
                     uint32_t nt, uint32_t *local, sl_occ_cparts *o, sl_occ_cpart *part, uint32_t *vids,
                     uint32_t *ltri, uint64_t *edges)
{
    if (nt < 3 || nt > SL_OCC_CPART_MAX_TRIS)
        return false;
    uint32_t nv = 0;
    bool ok = true;
    for (uint32_t t = 0; t < nt && ok; t++)
        for (int k = 0; k < 3 && ok; k++) {
            uint32_t w = weld[idx[3 * comp[t] + k]];
            if (local[w] == UINT32_MAX) {
                if (nv == SL_OCC_CPART_MAX_VERTS) {
                    ok = false;
                    break;
                }
                local[w] = nv;
                vids[nv++] = w;
            }
            ltri[3 * t + k] = local[w];
        }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], wp[vids[i]][k]);
            hi[k] = fmax(hi[k], wp[vids[i]][k]);
        }
    double ext = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                      (hi[2] - lo[2]) * (hi[2] - lo[2]));
    double tol = 1e-6 * ext, dev = 0;
    if (!(ext > 0) || !isfinite(ext))
        ok = false;
    /* edges: each used twice (closed) or once (a hole's) */
    uint32_t ne = 0;
    for (uint32_t t = 0; t < nt && ok; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = ltri[3 * t + k], b = ltri[3 * t + (k + 1) % 3];
            if (a == b)
                ok = false;
            edges[ne++] = a < b ? ((uint64_t)a << 32 | b) : ((uint64_t)b << 32 | a);
        }
    uint32_t nbound = 0;
    bool onb[SL_OCC_CPART_MAX_VERTS] = {false};
    if (ok) {
        qsort(edges, ne, sizeof *edges, cmp_u64);
        for (uint32_t i = 0; i < ne && ok;) {
            uint32_t j = i;
            while (j < ne && edges[j] == edges[i])
                j++;
            if (j - i > 2)
                ok = false;
            else if (j - i == 1) {
                nbound++;
                onb[edges[i] >> 32] = onb[(uint32_t)edges[i]] = true;
            }
            i = j;
        }
    }
    /* convex: every vertex on the inner side of every triangle's plane; wind outward */
    for (uint32_t t = 0; t < nt && ok; t++) {
        const double *a = wp[vids[ltri[3 * t]]], *b = wp[vids[ltri[3 * t + 1]]], *c = wp[vids[ltri[3 * t + 2]]];
        double u[3], w[3], n[3];
        dsub(b, a, u);
        dsub(c, a, w);
        dcross(u, w, n);
        double len = sqrt(ddot(n, n));
        if (!(len > 1e-12 * ext * ext)) {
            ok = false;
            break;
        }
        double smax = -INFINITY, smin = INFINITY;
        for (uint32_t i = 0; i < nv; i++) {
            double d[3];
            dsub(wp[vids[i]], a, d);
            double s = ddot(n, d) / len;
            smax = fmax(smax, s);
            smin = fmin(smin, s);
        }
        if (smax <= tol)
            dev = fmax(dev, smax);
        else if (smin >= -tol) {
            dev = fmax(dev, -smin);
            uint32_t x = ltri[3 * t + 1];
            ltri[3 * t + 1] = ltri[3 * t + 2];
            ltri[3 * t + 2] = x;
        } else
            ok = false;
    }
    part->holes = 0;
    if (ok && nbound) {
        /* the holes: boundary vertices labelled by the loops of edges used once */
        uint32_t lab[SL_OCC_CPART_MAX_VERTS];
        for (uint32_t i = 0; i < nv; i++)
            lab[i] = i;
        for (bool changed = true; changed;) {
            changed = false;
            for (uint32_t i = 0; i < ne;) {
                uint32_t j = i;
                while (j < ne && edges[j] == edges[i])
                    j++;
                if (j - i == 1) {
                    uint32_t a = (uint32_t)(edges[i] >> 32), b = (uint32_t)edges[i];
                    uint32_t l = lab[a] < lab[b] ? lab[a] : lab[b];
                    if (lab[a] != l || lab[b] != l)
                        lab[a] = lab[b] = l, changed = true;
                }
                i = j;
            }
        }
        bool done_lab[SL_OCC_CPART_MAX_VERTS] = {false};
        for (uint32_t g = 0; g < nv && ok; g++) {
            if (!onb[g] || done_lab[lab[g]])
                continue;
            done_lab[lab[g]] = true;
            if (part->holes == SL_OCC_CPART_MAX_HOLES) {
                ok = false;
                break;
            }
            const uint32_t L = lab[g];
            /* one supporting plane through every vertex of the loop */
            uint32_t b0 = g, b1 = UINT32_MAX, b2 = UINT32_MAX;
            double best = 0;
            for (uint32_t i = 0; i < nv; i++) {
                double d[3];
                dsub(wp[vids[i]], wp[vids[b0]], d);
                if (onb[i] && lab[i] == L && ddot(d, d) > best)
                    best = ddot(d, d), b1 = i;
            }
            best = 0;
            for (uint32_t i = 0; i < nv && b1 != UINT32_MAX; i++) {
                double d[3], e[3], n[3];
                dsub(wp[vids[b1]], wp[vids[b0]], d);
                dsub(wp[vids[i]], wp[vids[b0]], e);
                dcross(d, e, n);
                if (onb[i] && lab[i] == L && ddot(n, n) > best)
                    best = ddot(n, n), b2 = i;
            }
            if (b1 == UINT32_MAX || b2 == UINT32_MAX || !(sqrt(best) > 1e-6 * ext * ext)) {
                ok = false;
                break;
            }
            double u[3], w[3], n[3];
            dsub(wp[vids[b1]], wp[vids[b0]], u);
            dsub(wp[vids[b2]], wp[vids[b0]], w);
            dcross(u, w, n);
            double len = sqrt(ddot(n, n)), smax = -INFINITY, smin = INFINITY, far_in = 0;
            for (uint32_t i = 0; i < nv; i++) {
                double d[3];
                dsub(wp[vids[i]], wp[vids[b0]], d);
                double sd = ddot(n, d) / len;
                if (onb[i] && lab[i] == L && fabs(sd) > tol)
                    ok = false;
                smax = fmax(smax, sd);
                smin = fmin(smin, sd);
                far_in = fmax(far_in, fabs(sd));
            }
            uint32_t *hv = part->hole_v[part->holes];
            if (!ok || !(far_in > 1e-3 * ext))
                ok = false; /* not planar, or flat */
            else if (smax <= tol) {
                hv[0] = b0, hv[1] = b1, hv[2] = b2;
                dev = fmax(dev, smax);
            } else if (smin >= -tol) {
                hv[0] = b0, hv[1] = b2, hv[2] = b1;
                dev = fmax(dev, -smin);
            } else
                ok = false;
            part->holes++;
        }
    }
    for (uint32_t i = 0; i < nv; i++)
        local[vids[i]] = UINT32_MAX;
    if (!ok)
        return false;
    part->vfirst = o->vert_count;
    part->vcount = nv;
    part->tfirst = o->tri_count;
    part->tcount = nt;
    part->dev = dev;
    for (uint32_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++)
            o->pos[3 * (size_t)(o->vert_count + i) + (size_t)k] = (float)wp[vids[i]][k];
    memcpy(o->tri + 3 * (size_t)o->tri_count, ltri, 3 * (size_t)nt * sizeof(uint32_t));
    memcpy(o->src + o->tri_count, comp, nt * sizeof(uint32_t));
    o->vert_count += nv;
    o->tri_count += nt;
    o->parts[o->part_count++] = *part;
    return true;
}

sl_status sl_occ_cparts_build(const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt, const sl_allocator *a,
                              sl_occ_cparts *o)
{
    memset(o, 0, sizeof *o);
    o->built = true;
    size_t nv1 = nv ? nv : 1, nt1 = nt ? nt : 1;
    o->cap = nt1;
    weld_key *keys = sl_alloc(a, nv1 * sizeof *keys);
    uint32_t *weld = sl_alloc(a, nv1 * sizeof(uint32_t)), *parent = sl_alloc(a, nv1 * sizeof(uint32_t));
    uint32_t *local = sl_alloc(a, nv1 * sizeof(uint32_t)), *order = sl_alloc(a, nt1 * sizeof(uint32_t));
    double(*wp)[3] = sl_alloc(a, nv1 * sizeof *wp);
    o->parts = sl_alloc(a, nt1 * sizeof *o->parts);
    o->pos = sl_alloc(a, 3 * (size_t)3 * nt1 * sizeof(float));
    o->tri = sl_alloc(a, 3 * nt1 * sizeof(uint32_t));
    o->src = sl_alloc(a, nt1 * sizeof(uint32_t));
    o->rest = sl_alloc(a, nt1 * sizeof(uint32_t));
    uint32_t vids[SL_OCC_CPART_MAX_VERTS], ltri[3 * SL_OCC_CPART_MAX_TRIS];
    uint64_t edges[3 * SL_OCC_CPART_MAX_TRIS];
    sl_status st = SL_OK;
    if (!keys || !weld || !parent || !local || !order || !wp || !o->parts || !o->pos || !o->tri || !o->src ||
        !o->rest) {
        st = SL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    /* weld equal positions */
    for (uint32_t i = 0; i < nv; i++) {
        memcpy(keys[i].p, pos + 3 * (size_t)i, sizeof keys[i].p);
        keys[i].i = i;
    }
    qsort(keys, nv, sizeof *keys, cmp_weld);
    uint32_t nw = 0;
    for (uint32_t i = 0; i < nv; i++) {
        if (i == 0 || memcmp(keys[i].p, keys[i - 1].p, sizeof keys[i].p) != 0) {
            for (int k = 0; k < 3; k++)
                wp[nw][k] = keys[i].p[k];
            nw++;
        }
        weld[keys[i].i] = nw - 1;
    }
    for (uint32_t i = 0; i < nw; i++)
        parent[i] = i, local[i] = UINT32_MAX;
    /* components through welded vertices (a triangle with a bad index goes to the rest) */
    for (uint32_t t = 0; t < nt; t++) {
        if (idx[3 * t] >= nv || idx[3 * t + 1] >= nv || idx[3 * t + 2] >= nv)
            continue;
        uint32_t r0 = uf_find(parent, weld[idx[3 * t]]);
        for (int k = 1; k < 3; k++) {
            uint32_t rk = uf_find(parent, weld[idx[3 * t + k]]);
            if (rk != r0)
                parent[rk] = r0;
        }
    }
    /* triangles ordered by component root (counting sort through `local` as counters) */
    uint32_t nvalid = 0;
    for (uint32_t t = 0; t < nt; t++) {
        if (idx[3 * t] >= nv || idx[3 * t + 1] >= nv || idx[3 * t + 2] >= nv)
            o->rest[o->rest_count++] = t;
        else
            order[nvalid++] = t;
    }
    uint32_t *root = sl_alloc(a, nt1 * sizeof(uint32_t));
    if (!root) {
        st = SL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    for (uint32_t i = 0; i < nvalid; i++)
        root[i] = uf_find(parent, weld[idx[3 * order[i]]]);
    /* insertion-free grouping: sort (root, triangle) pairs */
    uint64_t *pairs = sl_alloc(a, nt1 * sizeof(uint64_t));
    if (!pairs) {
        sl_free(a, root, nt1 * sizeof(uint32_t));
        st = SL_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    for (uint32_t i = 0; i < nvalid; i++)
        pairs[i] = (uint64_t)root[i] << 32 | order[i];
    qsort(pairs, nvalid, sizeof *pairs, cmp_u64);
    for (uint32_t i = 0; i < nvalid;) {
        uint32_t j = i;
        while (j < nvalid && (pairs[j] >> 32) == (pairs[i] >> 32))
            j++;
        for (uint32_t k = i; k < j; k++)
            order[k - i] = (uint32_t)pairs[k];
        sl_occ_cpart part;
        memset(&part, 0, sizeof part);
        if (!try_part((const double(*)[3])wp, weld, idx, order, j - i, local, o, &part, vids, ltri, edges))
            for (uint32_t k = 0; k < j - i; k++)
                o->rest[o->rest_count++] = order[k];
        i = j;
    }
    sl_free(a, pairs, nt1 * sizeof(uint64_t));
    sl_free(a, root, nt1 * sizeof(uint32_t));
done:
    sl_free(a, keys, nv1 * sizeof *keys);
    sl_free(a, weld, nv1 * sizeof(uint32_t));
    sl_free(a, parent, nv1 * sizeof(uint32_t));
    sl_free(a, local, nv1 * sizeof(uint32_t));
    sl_free(a, order, nt1 * sizeof(uint32_t));
    sl_free(a, wp, nv1 * sizeof *wp);
    if (st != SL_OK)
        sl_occ_cparts_free(o, a);
    return st;
}

void sl_occ_cparts_free(sl_occ_cparts *o, const sl_allocator *a)
{
    size_t nt1 = o->cap;
    sl_free(a, o->parts, nt1 * sizeof *o->parts);
    sl_free(a, o->pos, 3 * (size_t)3 * nt1 * sizeof(float));
    sl_free(a, o->tri, 3 * nt1 * sizeof(uint32_t));
    sl_free(a, o->src, nt1 * sizeof(uint32_t));
    sl_free(a, o->rest, nt1 * sizeof(uint32_t));
    memset(o, 0, sizeof *o);
}

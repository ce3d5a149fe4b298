/* City generator, ground: every square metre of the extent is covered by exactly one ground
 * piece, draped on the terrain when there is one:
 *  - street segments and intersections, merged into one GROUND object per GC_TILE tile (compact
 *    objects that cull well, and far fewer of them than pieces);
 *  - one GROUND object per block (courtyards, lot ground under the buildings), park, square and
 *    river cell (both banks and the quay walls);
 *  - one WATER object per river cell (continuous under the bridges);
 *  - one GROUND object per bridge: deck and parapets over the water. */
#include "gen_city_internal.h"

#define COLOR_STREET 0x5A5A5EFFu
#define COLOR_BLOCK 0x9C9484FFu
#define COLOR_PLAZA 0xB5AE9EFFu
#define COLOR_PARK 0x5E8C3EFFu
#define COLOR_SQUARE 0xCBBFA6FFu
#define COLOR_BANK 0x8E9A76FFu
#define COLOR_WATER 0x3B6E9EFFu
#define COLOR_BRIDGE 0x8C8478FFu

/* Drape a convex quad (or triangle) on the terrain: a bilinear grid of about one terrain cell,
 * smooth normals from the height field. Without terrain: one flat face. */
static void drape(gc_city *c, const sl_dvec2 *p, int n, double lift)
{
    gc_mesh *m = &c->mesh;
    sl_dvec3 up = {0, 0, 1};
    if (!c->has_terrain) {
        sl_dvec3 pts[4];
        for (int k = 0; k < n; k++)
            pts[k] = sl_d3_of_d2(p[k], lift);
        gc_face(m, pts, n, up);
        return;
    }
    sl_dvec2 q[4] = {p[0], p[1], p[2], n == 3 ? p[2] : p[3]};
    double lu = fmax(sl_d2_len(sl_d2_sub(q[1], q[0])), sl_d2_len(sl_d2_sub(q[2], q[3])));
    double lv = fmax(sl_d2_len(sl_d2_sub(q[3], q[0])), sl_d2_len(sl_d2_sub(q[2], q[1])));
    int nu = (int)SL_CLAMP(ceil(lu / c->tcell), 1.0, 64.0), nv = (int)SL_CLAMP(ceil(lv / c->tcell), 1.0, 64.0);
    if (!gc_mesh_reserve(m, (uint32_t)((nu + 1) * (nv + 1)), (uint32_t)(2 * nu * nv)))
        return;
    uint32_t base = m->nv;
    for (int v = 0; v <= nv; v++)
        for (int u = 0; u <= nu; u++) {
            double s = (double)u / nu, t = (double)v / nv;
            sl_dvec2 a = sl_d2_lerp(sl_d2_lerp(q[0], q[1], s), sl_d2_lerp(q[3], q[2], s), t);
            gc_vert(m, sl_d3_of_d2(a, gc_ground(c, a.x, a.y) + lift), gc_ground_normal(c, a.x, a.y));
        }
    for (int v = 0; v < nv; v++)
        for (int u = 0; u < nu; u++) {
            uint32_t a = base + (uint32_t)(v * (nu + 1) + u), b = a + 1, d = a + (uint32_t)(nu + 1), e = d + 1;
            const float *pa = m->pos + 3 * (size_t)a, *pb = m->pos + 3 * (size_t)b, *pe = m->pos + 3 * (size_t)e,
                        *pd = m->pos + 3 * (size_t)d;
            /* the collapsed side of a triangle gives zero-area triangles: skip them */
            double c1 = ((double)pb[0] - pa[0]) * ((double)pe[1] - pa[1]) - ((double)pb[1] - pa[1]) * ((double)pe[0] - pa[0]);
            double c2 = ((double)pe[0] - pa[0]) * ((double)pd[1] - pa[1]) - ((double)pe[1] - pa[1]) * ((double)pd[0] - pa[0]);
            if (c1 > 1e-6)
                gc_tri_idx(m, a, b, e);
            if (c2 > 1e-6)
                gc_tri_idx(m, a, e, d);
        }
}

typedef struct piece {
    sl_dvec2 p[4];
    int n;
    uint32_t tile;
} piece;

static sl_status street_tiles(gc_city *c)
{
    int nx = c->nx, ny = c->ny;
    uint32_t ntx = (uint32_t)ceil((c->x1 - c->x0) / GC_TILE), nty = (uint32_t)ceil((c->y1 - c->y0) / GC_TILE);
    sl_array pieces = {0};
    uint32_t *start = sl_calloc(c->alloc, (size_t)ntx * nty + 1, sizeof(uint32_t));
    uint32_t *order = NULL;
    sl_status st = SL_OK;
    if (!start)
        goto oom;
    for (int pass = 0; pass < 3; pass++) {
        int ni = pass == 0 ? nx : pass == 1 ? nx + 1 : nx, nj = pass == 0 ? ny + 1 : ny;
        for (int j = 0; j < nj; j++)
            for (int i = 0; i < ni; i++) {
                piece pc;
                memset(&pc, 0, sizeof pc);
                if (pass < 2) {
                    const gc_edge *e = pass == 0 ? gc_hedge(c, i, j) : gc_vedge(c, i, j);
                    if (!(e->flags & GC_EDGE_STREET) || (e->flags & GC_EDGE_BRIDGE))
                        continue;
                    gc_edge_quad(c, pass == 0, i, j, pc.p);
                    pc.n = 4;
                } else {
                    pc.n = gc_node_poly(c, i, j, pc.p);
                    if (!pc.n)
                        continue;
                }
                sl_dvec2 ctr = {0, 0};
                for (int k = 0; k < pc.n; k++)
                    ctr = sl_d2_add(ctr, sl_d2_scale(pc.p[k], 1.0 / pc.n));
                uint32_t tx = (uint32_t)SL_CLAMP((ctr.x - c->x0) / GC_TILE, 0.0, (double)ntx - 1);
                uint32_t ty = (uint32_t)SL_CLAMP((ctr.y - c->y0) / GC_TILE, 0.0, (double)nty - 1);
                pc.tile = ty * ntx + tx;
                if (!sl_array_push(c->alloc, &pieces, sizeof pc, &pc, 1))
                    goto oom;
                start[pc.tile + 1]++;
            }
    }
    /* counting sort by tile: stable, so the order inside a tile is the lattice order */
    for (size_t t = 0; t < (size_t)ntx * nty; t++)
        start[t + 1] += start[t];
    order = sl_alloc(c->alloc, (pieces.count ? pieces.count : 1) * sizeof(uint32_t));
    if (!order)
        goto oom;
    {
        uint32_t *fill = sl_calloc(c->alloc, (size_t)ntx * nty, sizeof(uint32_t));
        if (!fill)
            goto oom;
        for (size_t k = 0; k < pieces.count; k++) {
            uint32_t t = SL_AT(pieces, piece, k).tile;
            order[start[t] + fill[t]++] = (uint32_t)k;
        }
        sl_free(c->alloc, fill, (size_t)ntx * nty * sizeof(uint32_t));
    }
    for (size_t t = 0; t < (size_t)ntx * nty; t++) {
        if (start[t] == start[t + 1])
            continue;
        gc_mesh_reset(&c->mesh);
        for (uint32_t k = start[t]; k < start[t + 1]; k++) {
            const piece *pc = &SL_AT(pieces, piece, order[k]);
            drape(c, pc->p, pc->n, 0.0);
        }
        if (!gc_commit_object(c, SL_KIND_GROUND, 0, COLOR_STREET, NULL)) {
            st = c->err ? c->err->status : SL_ERROR_INTERNAL;
            goto done;
        }
    }
    goto done;
oom:
    st = sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory for the street ground");
done:
    sl_free(c->alloc, order, (pieces.count ? pieces.count : 1) * sizeof(uint32_t));
    sl_free(c->alloc, start, ((size_t)ntx * nty + 1) * sizeof(uint32_t));
    sl_array_free(c->alloc, &pieces, sizeof(piece));
    return st;
}

/* Vertical wall from the water up to the bank along a water edge a->b, facing the water. */
static void quay_wall(gc_city *c, sl_dvec2 a, sl_dvec2 b)
{
    sl_dvec2 d = sl_d2_sub(b, a);
    sl_dvec3 want = sl_d3(-d.y, d.x, 0);
    gc_quad(&c->mesh, sl_d3_of_d2(a, GC_WATER_Z), sl_d3_of_d2(b, GC_WATER_Z), sl_d3_of_d2(b, 0.0), sl_d3_of_d2(a, 0.0),
            want);
}

/* Points where the line p + t*d crosses the two water edges, ordered along d. */
static bool water_span(sl_dvec2 p, sl_dvec2 d, const sl_dvec2 w[4], sl_dvec2 *s0, sl_dvec2 *s1)
{
    sl_dvec2 a, b;
    if (!gc_line_isect(p, d, w[0], sl_d2_sub(w[1], w[0]), &a) || !gc_line_isect(p, d, w[3], sl_d2_sub(w[2], w[3]), &b))
        return false;
    if (sl_d2_dot(sl_d2_sub(b, a), d) < 0) {
        sl_dvec2 t = a;
        a = b, b = t;
    }
    *s0 = a, *s1 = b;
    return sl_d2_len(sl_d2_sub(b, a)) > 0.5;
}

static sl_status bridge(gc_city *c, int i, int j)
{
    gc_mesh *m = &c->mesh;
    gc_mesh_reset(m);
    sl_dvec2 q[4];
    gc_edge_quad(c, false, i, j, q);
    double top = 0.15, bot = -0.9;
    sl_dvec3 up = {0, 0, 1}, down = {0, 0, -1}, none = {0, 0, 0};
    sl_dvec3 t4[4], b4[4];
    for (int k = 0; k < 4; k++)
        t4[k] = sl_d3_of_d2(q[k], top), b4[k] = sl_d3_of_d2(q[k], bot);
    gc_face(m, t4, 4, up);
    gc_face(m, b4, 4, down);
    for (int k = 0; k < 4; k++)
        gc_quad(m, b4[k], b4[(k + 1) & 3], t4[(k + 1) & 3], t4[k], none);
    /* parapets along both kerbs, over the water only (the banks stay walkable) */
    sl_dvec2 lo[4], hi[4], wr[4], wl[4];
    gc_river_quads(c, i, j, lo, hi, wr);
    gc_river_quads(c, i - 1, j, lo, hi, wl);
    for (int side = 0; side < 2; side++) {
        sl_dvec2 a = side == 0 ? q[0] : q[2], b = side == 0 ? q[1] : q[3];
        sl_dvec2 d = sl_d2_sub(b, a), s0, s1;
        if (!water_span(a, d, side == 0 ? wr : wl, &s0, &s1))
            continue;
        sl_dvec2 in = sl_d2_scale(sl_d2_left(sl_d2_unit(d)), 0.3);
        sl_dvec2 poly[4] = {s0, s1, sl_d2_add(s1, in), sl_d2_add(s0, in)};
        gc_prism(m, poly, 4, top, top + 1.1, true, false);
    }
    return gc_commit_object(c, SL_KIND_GROUND, 0, COLOR_BRIDGE, NULL) ? SL_OK : c->err->status;
}

sl_status gc_groundwork(gc_city *c)
{
    sl_status st = street_tiles(c);
    if (st != SL_OK)
        return st;
    uint64_t total = (uint64_t)c->nx * c->ny;
    for (int j = 0; j < c->ny; j++) {
        for (int i = 0; i < c->nx; i++) {
            gc_cell *cl = gc_cellp(c, i, j);
            gc_mesh_reset(&c->mesh);
            if (cl->type == GC_CELL_RIVER) {
                sl_dvec2 lo[4], hi[4], w[4];
                if (gc_river_quads(c, i, j, lo, hi, w)) {
                    drape(c, lo, 4, 0.0);
                    drape(c, hi, 4, 0.0);
                }
                quay_wall(c, w[0], w[1]);
                quay_wall(c, w[2], w[3]);
                if (!gc_commit_object(c, SL_KIND_GROUND, 0, COLOR_BANK, NULL))
                    return c->err->status;
                gc_mesh_reset(&c->mesh);
                sl_dvec3 wq[4];
                for (int k = 0; k < 4; k++)
                    wq[k] = sl_d3_of_d2(w[k], GC_WATER_Z);
                gc_face(&c->mesh, wq, 4, sl_d3(0, 0, 1));
                if (!gc_commit_object(c, SL_KIND_WATER, 0, COLOR_WATER, NULL))
                    return c->err->status;
                continue;
            }
            uint32_t color = cl->type == GC_CELL_PARK     ? COLOR_PARK
                             : cl->type == GC_CELL_SQUARE ? COLOR_SQUARE
                             : cl->type == GC_CELL_PLAZA || cl->type == GC_CELL_TOWER ? COLOR_PLAZA
                                                                                        : COLOR_BLOCK;
            drape(c, cl->ground, 4, 0.0);
            if (!gc_commit_object(c, SL_KIND_GROUND, 0, color, NULL))
                return c->err->status;
        }
        if (!sl_progress_report(&c->opt->progress, "city: ground", (uint64_t)(j + 1) * c->nx, total))
            return sl_fail(c->err, SL_ERROR_CANCELLED, "city: cancelled while generating the ground");
    }
    if (c->river_row >= 0)
        for (int i = 1; i < c->nx; i++)
            if (gc_vedge(c, i, c->river_row)->flags & GC_EDGE_BRIDGE)
                if ((st = bridge(c, i, c->river_row)) != SL_OK)
                    return st;
    return SL_OK;
}

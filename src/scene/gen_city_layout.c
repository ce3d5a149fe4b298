/* City generator, layout: the jittered street lattice (spacings, avenues, quays, bridges, dropped
 * segments), the cell types, the cell quads every other part derives its regions from, the
 * terrain height field, and finally the street network handed to the scene (free-space polygons
 * and the centre-line graph). */
#include "gen_city_internal.h"

#include <stdlib.h>

static const int corner_di[4] = {0, 1, 1, 0};
static const int corner_dj[4] = {0, 0, 1, 1};

void gc_rng(const gc_city *c, uint32_t purpose, uint32_t a, uint32_t b, sl_rng *out)
{
    uint32_t key[4] = {purpose, a, b, 0x63697479u};
    sl_rng_seed(out, c->opt->seed, sl_hash64(key, sizeof key, 0x5347454e43495459ull));
}

gc_edge *gc_cell_side_edge(gc_city *c, int i, int j, int k)
{
    switch (k) {
    case 0: return gc_hedge(c, i, j);
    case 1: return gc_vedge(c, i + 1, j);
    case 2: return gc_hedge(c, i, j + 1);
    default: return gc_vedge(c, i, j);
    }
}

bool gc_cell_side_border(const gc_city *c, int i, int j, int k)
{
    switch (k) {
    case 0: return j == 0;
    case 1: return i == c->nx - 1;
    case 2: return j == c->ny - 1;
    default: return i == 0;
    }
}

void gc_side_line(const gc_city *c, int i, int j, int k, double off, sl_dvec2 *p, sl_dvec2 *d)
{
    int k2 = (k + 1) & 3;
    sl_dvec2 a = gc_node(c, i + corner_di[k], j + corner_dj[k]), b = gc_node(c, i + corner_di[k2], j + corner_dj[k2]);
    *d = sl_d2_sub(b, a);
    *p = sl_d2_add(a, sl_d2_scale(sl_d2_left(sl_d2_unit(*d)), off));
}

bool gc_cell_quad(const gc_city *c, int i, int j, const double off[4], sl_dvec2 out[4])
{
    sl_dvec2 p[4], d[4];
    for (int k = 0; k < 4; k++)
        gc_side_line(c, i, j, k, off[k], &p[k], &d[k]);
    for (int k = 0; k < 4; k++) {
        int h = (k + 3) & 3;
        if (!gc_line_isect(p[h], d[h], p[k], d[k], &out[k]))
            return false;
    }
    return gc_convex(out, 4) && gc_area(out, 4) > 1.0;
}

void gc_edge_quad(gc_city *c, bool horizontal, int i, int j, sl_dvec2 out[4])
{
    if (horizontal) {
        const gc_cell *below = gc_cellp(c, i, j - 1), *above = gc_cellp(c, i, j);
        out[0] = below->ground[3], out[1] = below->ground[2], out[2] = above->ground[1], out[3] = above->ground[0];
    } else {
        const gc_cell *left = gc_cellp(c, i - 1, j), *right = gc_cellp(c, i, j);
        out[0] = right->ground[0], out[1] = right->ground[3], out[2] = left->ground[2], out[3] = left->ground[1];
    }
}

static double half_width(gc_city *c, int i, int j, int k)
{
    const gc_edge *e = gc_cell_side_edge(c, i, j, k);
    return (e->flags & GC_EDGE_STREET) ? 0.5 * e->width : 0.0;
}

static sl_dvec2 isect_or(sl_dvec2 p, sl_dvec2 d, sl_dvec2 q, sl_dvec2 e)
{
    sl_dvec2 r = p;
    gc_line_isect(p, d, q, e, &r);
    return r;
}

bool gc_river_quads(gc_city *c, int i, int j, sl_dvec2 lo[4], sl_dvec2 hi[4], sl_dvec2 water[4])
{
    const sl_dvec2 *g = gc_cellp(c, i, j)->ground;
    double bank = c->opt->bank_width;
    sl_dvec2 pwb, dwb, pwt, dwt;
    gc_side_line(c, i, j, 0, half_width(c, i, j, 0) + bank, &pwb, &dwb);
    gc_side_line(c, i, j, 2, half_width(c, i, j, 2) + bank, &pwt, &dwt);
    /* banks end at the cell's sides (a bridge's kerb or the divider between river cells); the
     * water runs on under bridges to the bridge's centre line */
    sl_dvec2 pl = g[3], dl = sl_d2_sub(g[0], g[3]), pr = g[1], dr = sl_d2_sub(g[2], g[1]);
    sl_dvec2 pl0 = pl, dl0 = dl, pr0 = pr, dr0 = dr;
    if (gc_cell_side_edge(c, i, j, 3)->flags & GC_EDGE_STREET)
        gc_side_line(c, i, j, 3, 0, &pl0, &dl0);
    if (gc_cell_side_edge(c, i, j, 1)->flags & GC_EDGE_STREET)
        gc_side_line(c, i, j, 1, 0, &pr0, &dr0);
    lo[0] = g[0], lo[1] = g[1];
    lo[2] = isect_or(pwb, dwb, pr, dr), lo[3] = isect_or(pwb, dwb, pl, dl);
    hi[0] = isect_or(pwt, dwt, pl, dl), hi[1] = isect_or(pwt, dwt, pr, dr);
    hi[2] = g[2], hi[3] = g[3];
    water[0] = isect_or(pwb, dwb, pl0, dl0), water[1] = isect_or(pwb, dwb, pr0, dr0);
    water[2] = isect_or(pwt, dwt, pr0, dr0), water[3] = isect_or(pwt, dwt, pl0, dl0);
    return bank > 0.05 && gc_convex(lo, 4) && gc_convex(hi, 4);
}

/* ---- the lattice ---- */

/* Number of cells along a length: near length/mean, but never so many that a spacing would fall
 * below block_size_min. */
static int cell_count(const sl_city_options *o, double length)
{
    double mean = 0.5 * ((double)o->block_size_min + o->block_size_max);
    long n = lround(length / mean), most = (long)floor(length / o->block_size_min);
    return (int)SL_MAX(2L, SL_MIN(n, most));
}

/* Positions of n+1 lattice lines from `from` over `length`: spacings drawn in [min,max], then
 * their excess over the minimum is scaled so that they fill the length exactly; no spacing falls
 * below block_size_min. */
static void line_positions(gc_city *c, uint32_t axis, int n, double from, double length, double *pos)
{
    sl_rng r;
    gc_rng(c, GC_RNG_SPACING, axis, 0, &r);
    double lo = c->opt->block_size_min, sum = 0;
    for (int i = 0; i < n; i++) {
        pos[i + 1] = sl_rng_range(&r, c->opt->block_size_min, c->opt->block_size_max) - lo;
        sum += pos[i + 1];
    }
    double spare = length - n * lo, acc = 0;
    pos[0] = from;
    for (int i = 0; i < n; i++) {
        acc += sum > 0 ? pos[i + 1] * spare / sum : spare / n;
        pos[i + 1] = from + (i + 1) * lo + acc;
    }
    pos[n] = from + length;
}

/* Mark about length/spacing lines nearest to evenly spread targets; never a forbidden line, nor
 * a neighbour of a forbidden or marked one (so no block lies between two avenues or between an
 * avenue and a quay). */
static uint32_t pick_lines(const double *pos, int n, double spacing, const uint8_t *forbidden, uint8_t *flag)
{
    if (!(spacing > 0) || n < 2)
        return 0;
    double from = pos[0], length = pos[n] - pos[0];
    int count = (int)floor(length / spacing + 0.5);
    if (count < 1)
        count = 1;
    uint32_t picked = 0;
    for (int k = 0; k < count; k++) {
        double target = from + length * (k + 0.5) / count;
        int best = -1;
        for (int i = 1; i < n; i++) {
            bool blocked = (forbidden && (forbidden[i] || forbidden[i - 1] || forbidden[i + 1])) || flag[i - 1] ||
                           flag[i + 1] || flag[i];
            if (!blocked && (best < 0 || fabs(pos[i] - target) < fabs(pos[best] - target)))
                best = i;
        }
        if (best >= 0) {
            flag[best] = 1;
            picked++;
        }
    }
    return picked;
}

static int uf_find(uint32_t *p, int x)
{
    while ((int)p[x] != x) {
        p[x] = p[p[x]];
        x = (int)p[x];
    }
    return x;
}

sl_status gc_layout(gc_city *c)
{
    const sl_city_options *o = c->opt;
    const sl_allocator *a = c->alloc;
    double W = c->x1 - c->x0, H = c->y1 - c->y0;
    double river_span = o->river ? (double)o->river_width + 2.0 * o->bank_width + o->avenue_width : 0.0;
    int nx = cell_count(o, W);
    int ny_land = cell_count(o, H - river_span);
    int ny = ny_land + (o->river ? 1 : 0);
    c->nx = nx, c->ny = ny;
    c->river_row = o->river ? ny_land / 2 : -1;
    int jr = c->river_row;

    size_t nn = (size_t)(nx + 1) * (ny + 1);
    double *X = sl_calloc(a, (size_t)nx + 1, sizeof(double)), *Y = sl_calloc(a, (size_t)ny + 1, sizeof(double));
    double *Yl = sl_calloc(a, (size_t)ny_land + 1, sizeof(double));
    c->node = sl_calloc(a, nn, sizeof(sl_dvec2));
    c->hedge = sl_calloc(a, (size_t)nx * (ny + 1), sizeof(gc_edge));
    c->vedge = sl_calloc(a, (size_t)(nx + 1) * ny, sizeof(gc_edge));
    c->cell = sl_calloc(a, (size_t)nx * ny, sizeof(gc_cell));
    c->vline_avenue = sl_calloc(a, (size_t)nx + 1, 1);
    c->hline_avenue = sl_calloc(a, (size_t)ny + 1, 1);
    uint8_t *hforbid = sl_calloc(a, (size_t)ny + 1, 1), *bridge = sl_calloc(a, (size_t)nx + 1, 1);
    uint8_t *deg = sl_calloc(a, nn, 1);
    uint32_t *uf = sl_calloc(a, (size_t)nx * ny + 1, sizeof(uint32_t));
    float *vwidth = sl_calloc(a, (size_t)nx + 1, sizeof(float)), *hwidth = sl_calloc(a, (size_t)ny + 1, sizeof(float));
    sl_status st = SL_OK;
    if (!X || !Y || !Yl || !c->node || !c->hedge || !c->vedge || !c->cell || !c->vline_avenue || !c->hline_avenue ||
        !hforbid || !bridge || !deg || !uf || !vwidth || !hwidth) {
        st = sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory for a %d x %d lattice", nx, ny);
        goto done;
    }

    /* line positions: the river row is one fixed-width row inserted in the middle */
    line_positions(c, 0, nx, c->x0, W, X);
    line_positions(c, 1, ny_land, c->y0, H - river_span, Yl);
    for (int j = 0, k = 0; j <= ny; j++) {
        if (j == 0)
            Y[j] = c->y0;
        else if (jr >= 0 && j == jr + 1)
            Y[j] = Y[j - 1] + river_span;
        else {
            Y[j] = Y[j - 1] + (Yl[k + 1] - Yl[k]);
            k++;
        }
    }
    Y[ny] = c->y1;

    /* avenues (straight: their nodes move only along them), quays and bridges */
    hforbid[0] = hforbid[ny] = 1;
    if (jr >= 0)
        hforbid[jr] = hforbid[jr + 1] = 1;
    pick_lines(X, nx, o->avenue_spacing, NULL, c->vline_avenue);
    pick_lines(Y, ny, o->avenue_spacing, hforbid, c->hline_avenue);
    if (jr >= 0) {
        c->hline_avenue[jr] = c->hline_avenue[jr + 1] = 1;
        if (o->bridge_spacing > 0) {
            pick_lines(X, nx, o->bridge_spacing, NULL, bridge);
            for (int i = 1; i < nx; i++)
                if (c->vline_avenue[i])
                    bridge[i] = 1;
        }
    }
    {
        sl_rng r;
        gc_rng(c, GC_RNG_LINE, 0, 0, &r);
        for (int i = 1; i < nx; i++)
            vwidth[i] = c->vline_avenue[i] ? o->avenue_width : sl_rng_range(&r, o->street_width_min, o->street_width_max);
        gc_rng(c, GC_RNG_LINE, 1, 0, &r);
        for (int j = 1; j < ny; j++)
            hwidth[j] = c->hline_avenue[j] ? o->avenue_width : sl_rng_range(&r, o->street_width_min, o->street_width_max);
    }

    /* nodes: jitter off the avenues. The river meanders: the quays follow a sine, and the rows
     * around them follow it less and less over six rows (and never near the border), so two
     * neighbouring rows never differ by more than amp/6 = 0.1 block_size_min (the allowance
     * sl_city_options_validate makes). The sine is taken at the column's unjittered position,
     * so the rows of one column move together. */
    double amp = 0, lambda = 1, phase = 0;
    if (jr >= 0) {
        sl_rng r;
        gc_rng(c, GC_RNG_RIVER, 0, 0, &r);
        amp = SL_MIN(0.6 * o->block_size_min, 40.0);
        lambda = W * sl_rng_range(&r, 0.5f, 0.9f);
        phase = sl_rng_range(&r, 0.0f, (float)(2 * GC_PI));
    }
    /* the meander (oldtown; none in the grid presets): line j of one direction is moved across
     * itself by meander * sin(2 pi s / wavelength + phase_j), s the position along the line; the
     * phase drifts by at most GC_MEANDER_DRIFT from one line to the next, so neighbouring lines
     * bend together and the blocks between them vary in depth by a few metres */
    double *hphase = NULL, *vphase = NULL;
    if (o->meander > 0) {
        hphase = sl_calloc(a, (size_t)ny + 1, sizeof(double));
        vphase = sl_calloc(a, (size_t)nx + 1, sizeof(double));
        if (!hphase || !vphase) {
            sl_free(a, hphase, ((size_t)ny + 1) * sizeof(double));
            sl_free(a, vphase, ((size_t)nx + 1) * sizeof(double));
            st = sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory for a %d x %d lattice", nx, ny);
            goto done;
        }
        sl_rng r;
        gc_rng(c, GC_RNG_MEANDER, 0, 0, &r);
        hphase[0] = sl_rng_range(&r, 0.0f, (float)(2 * GC_PI));
        for (int j = 1; j <= ny; j++)
            hphase[j] = hphase[j - 1] + sl_rng_range(&r, -(float)GC_MEANDER_DRIFT, (float)GC_MEANDER_DRIFT);
        gc_rng(c, GC_RNG_MEANDER, 1, 0, &r);
        vphase[0] = sl_rng_range(&r, 0.0f, (float)(2 * GC_PI));
        for (int i = 1; i <= nx; i++)
            vphase[i] = vphase[i - 1] + sl_rng_range(&r, -(float)GC_MEANDER_DRIFT, (float)GC_MEANDER_DRIFT);
    }
    for (int j = 0; j <= ny; j++) {
        double weight = 0;
        if (jr >= 0) {
            int dr = j < jr ? jr - j : j > jr + 1 ? j - jr - 1 : 0, db = SL_MIN(j, ny - j);
            weight = SL_MAX(0.0, SL_MIN(1.0 - dr / 6.0, db / 6.0));
        }
        for (int i = 0; i <= nx; i++) {
            sl_rng r;
            gc_rng(c, GC_RNG_NODE, (uint32_t)i, (uint32_t)j, &r);
            double jx = sl_rng_range(&r, -1, 1), jy = sl_rng_range(&r, -1, 1);
            double x = X[i], y = Y[j];
            if (i > 0 && i < nx && !c->vline_avenue[i])
                x += o->jitter * SL_MIN(X[i] - X[i - 1], X[i + 1] - X[i]) * jx;
            if (j > 0 && j < ny && !c->hline_avenue[j])
                y += o->jitter * SL_MIN(Y[j] - Y[j - 1], Y[j + 1] - Y[j]) * jy;
            y += weight * amp * sin(2 * GC_PI * (X[i] - c->x0) / lambda + phase);
            if (o->meander > 0) {
                if (i > 0 && i < nx)
                    x += o->meander * sin(2 * GC_PI * (Y[j] - c->y0) / o->meander_wavelength + vphase[i]);
                if (j > 0 && j < ny)
                    y += o->meander * sin(2 * GC_PI * (X[i] - c->x0) / o->meander_wavelength + hphase[j]);
            }
            c->node[(size_t)j * (nx + 1) + i] = sl_d2(x, y);
        }
    }
    if (o->meander > 0) {
        sl_free(a, hphase, ((size_t)ny + 1) * sizeof(double));
        sl_free(a, vphase, ((size_t)nx + 1) * sizeof(double));
    }

    /* edges */
    for (int j = 0; j <= ny; j++)
        for (int i = 0; i < nx; i++) {
            gc_edge *e = gc_hedge(c, i, j);
            if (j > 0 && j < ny) {
                e->width = hwidth[j];
                e->flags = GC_EDGE_STREET | (c->hline_avenue[j] ? GC_EDGE_AVENUE : 0);
            }
        }
    for (int j = 0; j < ny; j++)
        for (int i = 0; i <= nx; i++) {
            gc_edge *e = gc_vedge(c, i, j);
            if (i > 0 && i < nx && (j != jr || bridge[i])) {
                e->width = vwidth[i];
                e->flags = GC_EDGE_STREET | (c->vline_avenue[i] ? GC_EDGE_AVENUE : 0) | (j == jr ? GC_EDGE_BRIDGE : 0);
                if (j == jr)
                    c->n_bridges++;
            }
        }

    /* drop some minor segments: never a graph bridge (the cells on both sides must belong to
     * different faces, tracked by union-find with the border cells forming the outer face) and
     * never below degree 3, so no dead ends appear and the network stays connected */
    for (size_t k = 0; k <= (size_t)nx * ny; k++)
        uf[k] = (uint32_t)k;
    int outer = nx * ny;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++)
            if (i == 0 || j == 0 || i == nx - 1 || j == ny - 1 || j == jr)
                uf[uf_find(uf, j * nx + i)] = (uint32_t)uf_find(uf, outer);
    for (int j = 0; j <= ny; j++)
        for (int i = 0; i < nx; i++)
            if (gc_hedge(c, i, j)->flags & GC_EDGE_STREET)
                deg[(size_t)j * (nx + 1) + i]++, deg[(size_t)j * (nx + 1) + i + 1]++;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i <= nx; i++)
            if (gc_vedge(c, i, j)->flags & GC_EDGE_STREET)
                deg[(size_t)j * (nx + 1) + i]++, deg[(size_t)(j + 1) * (nx + 1) + i]++;
    if (o->style == SL_CITY_STYLE_OLDTOWN) {
        /* the brick pattern: the lattice is cut into districts of `district` x `district` cells;
         * in each, one direction (drawn per district) loses every other segment, staggered from
         * row to row, so streets of that direction end in T-junctions after one block. The same
         * rules as for dropped segments below keep the network connected without dead ends. */
        int nd = (int)o->district;
        for (int pass = 0; pass < 2; pass++) {
            bool horizontal = pass == 0;
            int ni = horizontal ? nx : nx + 1, nj = horizontal ? ny + 1 : ny;
            for (int j = 0; j < nj; j++)
                for (int i = 0; i < ni; i++) {
                    gc_edge *e = horizontal ? gc_hedge(c, i, j) : gc_vedge(c, i, j);
                    if (!(e->flags & GC_EDGE_STREET) || (e->flags & (GC_EDGE_AVENUE | GC_EDGE_BRIDGE)) || !((i + j) & 1))
                        continue;
                    sl_rng r;
                    gc_rng(c, GC_RNG_DISTRICT, (uint32_t)(i / nd), (uint32_t)(j / nd), &r);
                    if ((sl_rng_float(&r) < 0.5f) != horizontal)
                        continue;
                    size_t na = (size_t)j * (nx + 1) + i, nb = horizontal ? na + 1 : na + (size_t)(nx + 1);
                    int ca = horizontal ? (j - 1) * nx + i : j * nx + i - 1, cb = j * nx + i;
                    if (deg[na] < 4 || deg[nb] < 4)
                        continue;
                    int ra = uf_find(uf, ca), rb = uf_find(uf, cb);
                    if (ra == rb)
                        continue;
                    uf[ra] = (uint32_t)rb;
                    deg[na]--, deg[nb]--;
                    e->flags = 0;
                    e->width = 0;
                }
        }
    }
    if (o->street_removal > 0) {
        for (int pass = 0; pass < 2; pass++) {
            bool horizontal = pass == 0;
            int ni = horizontal ? nx : nx + 1, nj = horizontal ? ny + 1 : ny;
            for (int j = 0; j < nj; j++)
                for (int i = 0; i < ni; i++) {
                    gc_edge *e = horizontal ? gc_hedge(c, i, j) : gc_vedge(c, i, j);
                    if (!(e->flags & GC_EDGE_STREET) || (e->flags & (GC_EDGE_AVENUE | GC_EDGE_BRIDGE)))
                        continue;
                    sl_rng r;
                    gc_rng(c, GC_RNG_REMOVE, (uint32_t)(horizontal ? 0 : 1) << 31 | (uint32_t)i, (uint32_t)j, &r);
                    if (!(sl_rng_float(&r) < o->street_removal))
                        continue;
                    size_t na = (size_t)j * (nx + 1) + i, nb = horizontal ? na + 1 : na + (size_t)(nx + 1);
                    int ca = horizontal ? (j - 1) * nx + i : j * nx + i - 1, cb = j * nx + i;
                    if (deg[na] < 4 || deg[nb] < 4)
                        continue;
                    int ra = uf_find(uf, ca), rb = uf_find(uf, cb);
                    if (ra == rb)
                        continue;
                    uf[ra] = (uint32_t)rb;
                    deg[na]--, deg[nb]--;
                    e->flags = 0;
                    e->width = 0;
                }
        }
    }

    /* cell types and ground quads */
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            gc_cell *cl = gc_cellp(c, i, j);
            if (j == jr) {
                cl->type = GC_CELL_RIVER;
            } else {
                sl_rng r;
                gc_rng(c, GC_RNG_CELL, (uint32_t)i, (uint32_t)j, &r);
                float u = sl_rng_float(&r);
                if (u < o->park_fraction)
                    cl->type = GC_CELL_PARK;
                else if (u < o->park_fraction + o->square_fraction)
                    cl->type = GC_CELL_SQUARE;
                else if (u < o->park_fraction + o->square_fraction + o->tower_fraction)
                    cl->type = GC_CELL_TOWER;
                else
                    cl->type = GC_CELL_BLOCK;
            }
            double off[4];
            for (int k = 0; k < 4; k++)
                off[k] = half_width(c, i, j, k);
            if (!gc_cell_quad(c, i, j, off, cl->ground)) {
                st = sl_fail(c->err, SL_ERROR_INVALID_ARGUMENT,
                             "city: cell (%d,%d) collapses: streets up to %g m wide do not fit between lattice "
                             "lines %g..%g m apart with jitter %g (lower the widths or the jitter, or raise "
                             "block_size_min)",
                             i, j, (double)SL_MAX(o->street_width_max, o->avenue_width), (double)o->block_size_min,
                             (double)o->block_size_max, (double)o->jitter);
                goto done;
            }
        }

    /* Where two cells meet across a lattice edge that is not a street (dropped, or between river
     * cells), their corners at each end would be the crossings of their own kerbs with the
     * lattice line: two nearby points whose order flips when the line leans against a bending
     * street. Both cells take the midpoint instead, so the intersection polygon there degenerates
     * cleanly to a triangle and every region still tiles the extent. */
    for (int j = 1; j < ny; j++)
        for (int i = 0; i < nx; i++)
            if (!(gc_hedge(c, i, j)->flags & GC_EDGE_STREET)) {
                sl_dvec2 *ga = gc_cellp(c, i, j)->ground, *gb = gc_cellp(c, i, j - 1)->ground;
                ga[0] = gb[3] = sl_d2_lerp(ga[0], gb[3], 0.5);
                ga[1] = gb[2] = sl_d2_lerp(ga[1], gb[2], 0.5);
            }
    for (int j = 0; j < ny; j++)
        for (int i = 1; i < nx; i++)
            if (!(gc_vedge(c, i, j)->flags & GC_EDGE_STREET)) {
                sl_dvec2 *ga = gc_cellp(c, i, j)->ground, *gb = gc_cellp(c, i - 1, j)->ground;
                ga[0] = gb[1] = sl_d2_lerp(ga[0], gb[1], 0.5);
                ga[3] = gb[2] = sl_d2_lerp(ga[3], gb[2], 0.5);
            }
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++)
            if (!gc_convex(gc_cellp(c, i, j)->ground, 4)) {
                st = sl_fail(c->err, SL_ERROR_INVALID_ARGUMENT,
                             "city: cell (%d,%d) is not convex after joining it to its neighbour across a dropped "
                             "street (lower the jitter)", i, j);
                goto done;
            }

done:
    sl_free(a, X, ((size_t)nx + 1) * sizeof(double));
    sl_free(a, Y, ((size_t)ny + 1) * sizeof(double));
    sl_free(a, Yl, ((size_t)ny_land + 1) * sizeof(double));
    sl_free(a, hforbid, (size_t)ny + 1);
    sl_free(a, bridge, (size_t)nx + 1);
    sl_free(a, deg, nn);
    sl_free(a, uf, ((size_t)nx * ny + 1) * sizeof(uint32_t));
    sl_free(a, vwidth, ((size_t)nx + 1) * sizeof(float));
    sl_free(a, hwidth, ((size_t)ny + 1) * sizeof(float));
    return st;
}

/* ---- terrain ---- */

static double lattice_value(uint64_t seed, uint32_t octave, int64_t ix, int64_t iy)
{
    struct {
        uint64_t seed;
        int64_t ix, iy;
        uint32_t octave, pad;
    } k;
    memset(&k, 0, sizeof k); /* padding is hashed too: keep it zero */
    k.seed = seed, k.ix = ix, k.iy = iy, k.octave = octave;
    return (double)(sl_hash64(&k, sizeof k, 0x7465727261696eull) >> 11) * (1.0 / 9007199254740992.0);
}

/* Smooth value noise in [0,1] with unit lattice spacing. */
static double value_noise(uint64_t seed, uint32_t octave, double x, double y)
{
    double fx = floor(x), fy = floor(y);
    int64_t ix = (int64_t)fx, iy = (int64_t)fy;
    double u = x - fx, v = y - fy;
    u = u * u * (3 - 2 * u), v = v * v * (3 - 2 * v);
    double a = lattice_value(seed, octave, ix, iy), b = lattice_value(seed, octave, ix + 1, iy);
    double cc = lattice_value(seed, octave, ix, iy + 1), d = lattice_value(seed, octave, ix + 1, iy + 1);
    return (a * (1 - u) + b * u) * (1 - v) + (cc * (1 - u) + d * u) * v;
}

/* y of the river's centre line at x (between the two quay lines, through their nodes). */
static double river_center(const gc_city *c, double x)
{
    int jr = c->river_row;
    for (int i = 0; i < c->nx; i++) {
        sl_dvec2 a0 = gc_node(c, i, jr), b0 = gc_node(c, i + 1, jr);
        sl_dvec2 a1 = gc_node(c, i, jr + 1), b1 = gc_node(c, i + 1, jr + 1);
        if (x <= b0.x || i == c->nx - 1) {
            double t0 = SL_CLAMP((x - a0.x) / (b0.x - a0.x), 0.0, 1.0), t1 = SL_CLAMP((x - a1.x) / (b1.x - a1.x), 0.0, 1.0);
            return 0.5 * (a0.y + (b0.y - a0.y) * t0 + a1.y + (b1.y - a1.y) * t1);
        }
    }
    return 0.5 * (c->y0 + c->y1);
}

sl_status gc_terrain(gc_city *c)
{
    const sl_city_options *o = c->opt;
    if (!o->terrain || !(o->relief > 0))
        return SL_OK;
    double W = c->x1 - c->x0, H = c->y1 - c->y0;
    c->tcell = GC_TERRAIN_CELL;
    c->tnx = (uint32_t)ceil(W / c->tcell) + 1;
    c->tny = (uint32_t)ceil(H / c->tcell) + 1;
    size_t n = (size_t)c->tnx * c->tny;
    c->theight = sl_calloc(c->alloc, n, sizeof(float));
    double *raw = sl_calloc(c->alloc, n, sizeof(double));
    if (!c->theight || !raw) {
        sl_free(c->alloc, raw, n * sizeof(double));
        return sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory for a %u x %u terrain", c->tnx, c->tny);
    }
    sl_rng r;
    gc_rng(c, GC_RNG_TERRAIN, 0, 0, &r);
    uint64_t nseed = ((uint64_t)sl_rng_u32(&r) << 32) | sl_rng_u32(&r);
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < n; k++) {
        double x = c->x0 + (double)(k % c->tnx) * c->tcell, y = c->y0 + (double)(k / c->tnx) * c->tcell;
        double v = 0.55 * value_noise(nseed, 0, x / 700.0, y / 700.0) + 0.30 * value_noise(nseed, 1, x / 260.0, y / 260.0) +
                   0.15 * value_noise(nseed, 2, x / 110.0, y / 110.0);
        raw[k] = v;
        lo = fmin(lo, v), hi = fmax(hi, v);
    }
    /* the river zone (water, banks, quays and a margin) stays flat at 0; the ground rises from it
     * over a few hundred metres, so water never has to climb */
    double flat = 0, ramp = 250.0;
    if (c->river_row >= 0)
        flat = 0.5 * ((double)o->river_width + 2.0 * o->bank_width + o->avenue_width) + 0.5 * o->avenue_width + 12.0;
    for (uint32_t i = 0; i < c->tnx; i++) {
        double x = c->x0 + i * c->tcell, yc = c->river_row >= 0 ? river_center(c, x) : 0;
        for (uint32_t j = 0; j < c->tny; j++) {
            size_t k = (size_t)j * c->tnx + i;
            double g = 1.0;
            if (c->river_row >= 0) {
                double d = fabs(c->y0 + j * c->tcell - yc);
                double t = SL_CLAMP((d - flat) / ramp, 0.0, 1.0);
                g = t * t * (3 - 2 * t);
            }
            c->theight[k] = (float)(o->relief * g * (hi > lo ? (raw[k] - lo) / (hi - lo) : 0.0));
        }
    }
    sl_free(c->alloc, raw, n * sizeof(double));
    c->has_terrain = true;
    sl_terrain_desc td = {c->tnx, c->tny, (float)c->x0, (float)c->y0, (float)c->tcell, c->theight};
    return sl_scene_set_terrain(c->scene, &td, c->err);
}

double gc_ground(const gc_city *c, double x, double y)
{
    if (!c->has_terrain)
        return 0.0;
    double fx = SL_CLAMP((x - c->x0) / c->tcell, 0.0, (double)(c->tnx - 1));
    double fy = SL_CLAMP((y - c->y0) / c->tcell, 0.0, (double)(c->tny - 1));
    uint32_t i = (uint32_t)fx, j = (uint32_t)fy;
    if (i >= c->tnx - 1)
        i = c->tnx - 2;
    if (j >= c->tny - 1)
        j = c->tny - 2;
    double u = fx - i, v = fy - j;
    const float *h = c->theight + (size_t)j * c->tnx + i;
    return (h[0] * (1 - u) + h[1] * u) * (1 - v) + (h[c->tnx] * (1 - u) + h[c->tnx + 1] * u) * v;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double gc_ground_min_poly(const gc_city *c, const sl_dvec2 *p, int n)
{
    if (!c->has_terrain)
        return 0.0;
    /* A bilinear patch has no interior minimum (its Hessian is indefinite or zero), and along a
     * grid line it is linear; so the minimum over the polygon lies at a grid sample inside it or
     * on its boundary, where each piece of an edge within one cell is a parabola. */
    double m = INFINITY, xa = INFINITY, ya = INFINITY, xb = -INFINITY, yb = -INFINITY;
    for (int e = 0; e < n; e++) {
        sl_dvec2 a = p[e], b = p[(e + 1) % n];
        xa = fmin(xa, a.x), xb = fmax(xb, a.x), ya = fmin(ya, a.y), yb = fmax(yb, a.y);
        double ts[256];
        int nt = 0;
        ts[nt++] = 0, ts[nt++] = 1;
        for (int axis = 0; axis < 2; axis++) {
            double u0 = axis ? a.y : a.x, u1 = axis ? b.y : b.x, origin = axis ? c->y0 : c->x0;
            if (fabs(u1 - u0) < 1e-12)
                continue;
            double lo = fmin(u0, u1), hi = fmax(u0, u1);
            for (double g = origin + ceil((lo - origin) / c->tcell) * c->tcell; g < hi && nt < 256; g += c->tcell)
                ts[nt++] = (g - u0) / (u1 - u0);
        }
        qsort(ts, (size_t)nt, sizeof ts[0], cmp_double);
        for (int k = 0; k + 1 < nt; k++) {
            double t0 = ts[k], t1 = ts[k + 1];
            sl_dvec2 q0 = sl_d2_lerp(a, b, t0), q1 = sl_d2_lerp(a, b, t1), qm = sl_d2_lerp(a, b, 0.5 * (t0 + t1));
            double f0 = gc_ground(c, q0.x, q0.y), f1 = gc_ground(c, q1.x, q1.y), fm = gc_ground(c, qm.x, qm.y);
            double C = 2 * (f0 + f1 - 2 * fm), B = f1 - f0 - C;
            m = fmin(m, fmin(f0, f1));
            if (C > 1e-12) {
                double s = -B / (2 * C);
                if (s > 0 && s < 1)
                    m = fmin(m, f0 - B * B / (4 * C));
            }
        }
    }
    long i0 = (long)ceil((xa - c->x0) / c->tcell), i1 = (long)floor((xb - c->x0) / c->tcell);
    long j0 = (long)ceil((ya - c->y0) / c->tcell), j1 = (long)floor((yb - c->y0) / c->tcell);
    i0 = SL_MAX(i0, 0L), j0 = SL_MAX(j0, 0L), i1 = SL_MIN(i1, (long)c->tnx - 1), j1 = SL_MIN(j1, (long)c->tny - 1);
    for (long j = j0; j <= j1; j++)
        for (long i = i0; i <= i1; i++) {
            double x = c->x0 + (double)i * c->tcell, y = c->y0 + (double)j * c->tcell;
            bool in = false;
            for (int e = 0, f = n - 1; e < n; f = e++)
                if ((p[e].y > y) != (p[f].y > y) && x < (p[f].x - p[e].x) * (y - p[e].y) / (p[f].y - p[e].y) + p[e].x)
                    in = !in;
            if (in)
                m = fmin(m, c->theight[(size_t)j * c->tnx + (size_t)i]);
        }
    return m;
}

sl_dvec3 gc_ground_normal(const gc_city *c, double x, double y)
{
    if (!c->has_terrain)
        return sl_d3(0, 0, 1);
    double e = 1.0;
    double dx = (gc_ground(c, x + e, y) - gc_ground(c, x - e, y)) / (2 * e);
    double dy = (gc_ground(c, x, y + e) - gc_ground(c, x, y - e)) / (2 * e);
    double l = sqrt(dx * dx + dy * dy + 1);
    return sl_d3(-dx / l, -dy / l, 1 / l);
}

/* ---- street network ---- */

int gc_node_poly(gc_city *c, int i, int j, sl_dvec2 out[4])
{
    if (i <= 0 || j <= 0 || i >= c->nx || j >= c->ny)
        return 0;
    sl_dvec2 p[4] = {gc_cellp(c, i, j)->ground[0], gc_cellp(c, i - 1, j)->ground[1],
                     gc_cellp(c, i - 1, j - 1)->ground[2], gc_cellp(c, i, j - 1)->ground[3]};
    int n = 0;
    for (int k = 0; k < 4; k++) {
        if (n > 0 && sl_d2_len(sl_d2_sub(p[k], out[n - 1])) < 1e-3)
            continue;
        out[n++] = p[k];
    }
    if (n > 1 && sl_d2_len(sl_d2_sub(out[n - 1], out[0])) < 1e-3)
        n--;
    if (n < 3 || !(gc_area(out, n) > 0.05))
        return 0;
    return n;
}

/* Cells whose whole ground is free space. */
static bool is_open_cell(uint32_t type)
{
    return type == GC_CELL_PARK || type == GC_CELL_SQUARE || type == GC_CELL_PLAZA;
}

static sl_status add_poly(gc_city *c, const sl_dvec2 *p, int n)
{
    float xy[2 * GC_MAX_POLY];
    for (int k = 0; k < n; k++)
        xy[2 * k] = (float)p[k].x, xy[2 * k + 1] = (float)p[k].y;
    return sl_scene_add_street_polygon(c->scene, xy, (uint32_t)n, c->err);
}

sl_status gc_streets(gc_city *c)
{
    int nx = c->nx, ny = c->ny;
    sl_status st;
    sl_dvec2 q[4];
    /* free space: street segments, intersections, squares and parks, river banks */
    for (int j = 1; j < ny; j++)
        for (int i = 0; i < nx; i++)
            if (gc_hedge(c, i, j)->flags & GC_EDGE_STREET) {
                gc_edge_quad(c, true, i, j, q);
                if ((st = add_poly(c, q, 4)) != SL_OK)
                    return st;
            }
    for (int j = 0; j < ny; j++)
        for (int i = 1; i < nx; i++)
            if (gc_vedge(c, i, j)->flags & GC_EDGE_STREET) {
                gc_edge_quad(c, false, i, j, q);
                if ((st = add_poly(c, q, 4)) != SL_OK)
                    return st;
            }
    for (int j = 1; j < ny; j++)
        for (int i = 1; i < nx; i++) {
            int n = gc_node_poly(c, i, j, q);
            if (n && (st = add_poly(c, q, n)) != SL_OK)
                return st;
        }
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            gc_cell *cl = gc_cellp(c, i, j);
            if (is_open_cell(cl->type) && (st = add_poly(c, cl->ground, 4)) != SL_OK)
                return st;
            if (cl->type == GC_CELL_RIVER) {
                sl_dvec2 lo[4], hi[4], w[4];
                if (gc_river_quads(c, i, j, lo, hi, w) &&
                    ((st = add_poly(c, lo, 4)) != SL_OK || (st = add_poly(c, hi, 4)) != SL_OK))
                    return st;
            }
        }

    /* centre-line graph: lattice nodes that carry a street, then one centre node per square/park */
    size_t nn = (size_t)(nx + 1) * (ny + 1);
    uint32_t *map = sl_alloc(c->alloc, nn * sizeof(uint32_t));
    sl_array nodes = {0}, edges = {0};
    st = SL_OK;
    if (!map) {
        st = sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory for the street graph");
        goto done;
    }
    for (size_t k = 0; k < nn; k++)
        map[k] = SL_NONE;
    for (int pass = 0; pass < 2; pass++) {
        bool horizontal = pass == 0;
        int ni = horizontal ? nx : nx + 1, nj = horizontal ? ny + 1 : ny;
        for (int j = 0; j < nj; j++)
            for (int i = 0; i < ni; i++) {
                const gc_edge *e = horizontal ? gc_hedge(c, i, j) : gc_vedge(c, i, j);
                if (e->flags & GC_EDGE_STREET) {
                    map[(size_t)j * (nx + 1) + i] = 0;
                    map[horizontal ? (size_t)j * (nx + 1) + i + 1 : (size_t)(j + 1) * (nx + 1) + i] = 0;
                }
            }
    }
    for (size_t k = 0; k < nn; k++)
        if (map[k] == 0) {
            sl_street_node sn = {(float)c->node[k].x, (float)c->node[k].y};
            map[k] = (uint32_t)nodes.count;
            if (!sl_array_push(c->alloc, &nodes, sizeof sn, &sn, 1))
                goto oom;
        }
    for (int pass = 0; pass < 2; pass++) {
        bool horizontal = pass == 0;
        int ni = horizontal ? nx : nx + 1, nj = horizontal ? ny + 1 : ny;
        for (int j = 0; j < nj; j++)
            for (int i = 0; i < ni; i++) {
                const gc_edge *e = horizontal ? gc_hedge(c, i, j) : gc_vedge(c, i, j);
                if (!(e->flags & GC_EDGE_STREET))
                    continue;
                size_t na = (size_t)j * (nx + 1) + i, nb = horizontal ? na + 1 : na + (size_t)(nx + 1);
                sl_street_edge se = {map[na], map[nb], e->width,
                                     ((e->flags & GC_EDGE_AVENUE) ? SL_STREET_AVENUE : 0u) |
                                         ((e->flags & GC_EDGE_BRIDGE) ? SL_STREET_BRIDGE : 0u)};
                if (!sl_array_push(c->alloc, &edges, sizeof se, &se, 1))
                    goto oom;
            }
    }
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            gc_cell *cl = gc_cellp(c, i, j);
            if (!is_open_cell(cl->type))
                continue;
            sl_dvec2 ctr = sl_d2_scale(
                sl_d2_add(sl_d2_add(cl->ground[0], cl->ground[1]), sl_d2_add(cl->ground[2], cl->ground[3])), 0.25);
            sl_street_node sn = {(float)ctr.x, (float)ctr.y};
            uint32_t id = (uint32_t)nodes.count;
            if (!sl_array_push(c->alloc, &nodes, sizeof sn, &sn, 1))
                goto oom;
            for (int k = 0; k < 4; k++) {
                uint32_t other = map[(size_t)(j + corner_dj[k]) * (nx + 1) + i + corner_di[k]];
                if (other == SL_NONE)
                    continue;
                sl_street_edge se = {id, other, 3.0f, SL_STREET_SQUARE};
                if (!sl_array_push(c->alloc, &edges, sizeof se, &se, 1))
                    goto oom;
            }
        }
    st = sl_scene_set_street_graph(c->scene, nodes.data, (uint32_t)nodes.count, edges.data, (uint32_t)edges.count, c->err);
    goto done;
oom:
    st = sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory for the street graph");
done:
    sl_free(c->alloc, map, nn * sizeof(uint32_t));
    sl_array_free(c->alloc, &nodes, sizeof(sl_street_node));
    sl_array_free(c->alloc, &edges, sizeof(sl_street_edge));
    return st;
}

/* City generator, buildings: blocks are split into lots, one building per lot, each extruded
 * from its footprint with façade detail by level (see gen.h), added as one BUILDING object with
 * its 2.5D footprint.
 *
 * Lots. A block's lot area is its cell quad held back from the streets by GC_SETBACK (and from
 * the extent border; not from a dropped street, where the neighbours' walls touch). Large blocks
 * are perimeter blocks in the Viennese manner: a ring of buildings 11-16 m deep around a
 * courtyard, cut across at random frontage widths; a corner may stay uncut so that the lot
 * turns it (an L; two corners make a U). Small blocks are cut into slabs across their longer
 * axis. Lots share their party walls exactly, so a block's frontage has no slits to see through.
 *
 * Buildings. Every edge of a lot carries a tag: STREET (faces a street, a square or the border),
 * COURT (faces the courtyard), PARTY (shared with a neighbour) or BLANK (faces the neighbouring
 * block across a dropped street). Windows go on STREET façades (and COURT ones at level 4),
 * ledges and cornices on all but PARTY/BLANK walls, roofs slope only away from exterior walls
 * (party walls rise as fire walls), so roofs of neighbours meet without overlapping. */
#include "gen_city_internal.h"

enum { ROOF_FLAT = 0, ROOF_MANSARD, ROOF_HIP, ROOF_GABLE };

typedef struct lot {
    sl_dvec2 p[GC_MAX_POLY];
    uint8_t tag[GC_MAX_POLY];
    int n;
} lot;

typedef struct bldg {
    lot f;                          /* wall polygon (CCW) and edge tags */
    uint8_t windows[GC_MAX_POLY];   /* edge carries recessed windows */
    bool tower;
    int roof;
    int floors;
    double base, eave, gf, fh, bay;
    double roof_r, roof_slope;      /* inset and rise per metre of inset */
    uint32_t color;
    sl_dvec2 cell[4]; /* the cell's ground quad: no protrusion may leave it */
} bldg;

static const uint32_t facade_palette[] = {0xE8D8B0FFu, 0xD9C28FFFu, 0xC9A66BFFu, 0xE6E0D4FFu, 0xBFB8AAFFu,
                                          0xD8B4A0FFu, 0xC8CFC0FFu, 0xE3CFA0FFu, 0xA9A294FFu, 0xD4C6B0FFu};
static const uint32_t tower_palette[] = {0x8FA3B0FFu, 0x9EAAB2FFu, 0xB8BCBFFFu, 0x7D8C99FFu};

static bool exterior(uint8_t tag) { return tag == GC_TAG_STREET || tag == GC_TAG_COURT; }

/* ---- a local frame on one wall: u along the wall, v = z, w outward ---- */

typedef struct frame {
    sl_dvec2 a, u, w;
} frame;

static frame wall_frame(sl_dvec2 a, sl_dvec2 b)
{
    frame f;
    f.a = a;
    f.u = sl_d2_unit(sl_d2_sub(b, a));
    f.w = sl_d2(f.u.y, -f.u.x); /* right of the direction: outward for a CCW footprint */
    return f;
}

static inline sl_dvec3 fp(const frame *f, double u, double v, double w)
{
    return sl_d3(f->a.x + f->u.x * u + f->w.x * w, f->a.y + f->u.y * u + f->w.y * w, v);
}

/* A wall panel [u0,u1]x[v0,v1] with a recessed opening [wu0,wu1]x[wv0,wv1]: the frame around the
 * opening shares its 8 vertices (one flat face), then jambs, sill, lintel and the back. */
static void panel(gc_mesh *m, const frame *f, double u0, double u1, double v0, double v1, double wu0, double wu1,
                  double wv0, double wv1, bool sill)
{
    sl_dvec3 out = sl_d3(f->w.x, f->w.y, 0), uu = sl_d3(f->u.x, f->u.y, 0);
    sl_dvec3 up = {0, 0, 1}, down = {0, 0, -1};
    if (gc_mesh_reserve(m, 8, 8)) {
        uint32_t b = m->nv;
        gc_vert(m, fp(f, u0, v0, 0), out), gc_vert(m, fp(f, u1, v0, 0), out);
        gc_vert(m, fp(f, u1, v1, 0), out), gc_vert(m, fp(f, u0, v1, 0), out);
        gc_vert(m, fp(f, wu0, wv0, 0), out), gc_vert(m, fp(f, wu1, wv0, 0), out);
        gc_vert(m, fp(f, wu1, wv1, 0), out), gc_vert(m, fp(f, wu0, wv1, 0), out);
        /* outer o0..o3 = b..b+3, inner i0..i3 = b+4..b+7; CCW seen from outside */
        gc_tri_idx(m, b + 0, b + 1, b + 5), gc_tri_idx(m, b + 0, b + 5, b + 4);
        gc_tri_idx(m, b + 1, b + 2, b + 6), gc_tri_idx(m, b + 1, b + 6, b + 5);
        gc_tri_idx(m, b + 2, b + 3, b + 7), gc_tri_idx(m, b + 2, b + 7, b + 6);
        gc_tri_idx(m, b + 3, b + 0, b + 4), gc_tri_idx(m, b + 3, b + 4, b + 7);
    }
    double d = -GC_RECESS;
    gc_quad(m, fp(f, wu0, wv0, 0), fp(f, wu1, wv0, 0), fp(f, wu1, wv0, d), fp(f, wu0, wv0, d), up);
    gc_quad(m, fp(f, wu0, wv1, 0), fp(f, wu1, wv1, 0), fp(f, wu1, wv1, d), fp(f, wu0, wv1, d), down);
    gc_quad(m, fp(f, wu0, wv0, 0), fp(f, wu0, wv1, 0), fp(f, wu0, wv1, d), fp(f, wu0, wv0, d), uu);
    gc_quad(m, fp(f, wu1, wv0, 0), fp(f, wu1, wv1, 0), fp(f, wu1, wv1, d), fp(f, wu1, wv0, d), sl_d3_scale(uu, -1));
    gc_quad(m, fp(f, wu0, wv0, d), fp(f, wu1, wv0, d), fp(f, wu1, wv1, d), fp(f, wu0, wv1, d), out);
    if (sill) {
        double s0 = wu0 - 0.08, s1 = wu1 + 0.08, z0 = wv0 - 0.1, z1 = wv0, w = 0.12;
        gc_quad(m, fp(f, s0, z0, w), fp(f, s1, z0, w), fp(f, s1, z1, w), fp(f, s0, z1, w), out);
        gc_quad(m, fp(f, s0, z1, 0), fp(f, s1, z1, 0), fp(f, s1, z1, w), fp(f, s0, z1, w), up);
        gc_quad(m, fp(f, s0, z0, 0), fp(f, s1, z0, 0), fp(f, s1, z0, w), fp(f, s0, z0, w), down);
        gc_quad(m, fp(f, s0, z0, 0), fp(f, s0, z1, 0), fp(f, s0, z1, w), fp(f, s0, z0, w), sl_d3_scale(uu, -1));
        gc_quad(m, fp(f, s1, z0, 0), fp(f, s1, z1, 0), fp(f, s1, z1, w), fp(f, s1, z0, w), uu);
    }
}

static int bays(const bldg *b, double len) { return (int)floor(len / b->bay); }

static void wall(gc_mesh *m, const bldg *b, int e, uint32_t detail)
{
    sl_dvec2 A = b->f.p[e], B = b->f.p[(e + 1) % b->f.n];
    sl_dvec3 none = {0, 0, 0};
    if (!b->windows[e]) {
        gc_quad(m, sl_d3_of_d2(A, b->base), sl_d3_of_d2(B, b->base), sl_d3_of_d2(B, b->eave), sl_d3_of_d2(A, b->eave),
                none);
        return;
    }
    frame f = wall_frame(A, B);
    double len = sl_d2_len(sl_d2_sub(B, A));
    int nb = bays(b, len);
    double pw = len / nb;
    bool street = b->f.tag[e] == GC_TAG_STREET;
    for (int r = 0; r <= b->floors; r++) {
        double v0 = r == 0 ? b->base : b->base + b->gf + (r - 1) * b->fh;
        double v1 = r == 0 ? b->base + b->gf : v0 + b->fh;
        for (int k = 0; k < nb; k++) {
            double u0 = k * pw, u1 = u0 + pw, uc = 0.5 * (u0 + u1);
            if (r == 0 && street) {
                /* shop windows and doors */
                double hw = 0.31 * pw;
                panel(m, &f, u0, u1, v0, v1, uc - hw, uc + hw, v0 + 0.45, v1 - 0.8, false);
            } else {
                double hw = 0.22 * pw, wv0 = v0 + 0.9, wv1 = wv0 + SL_MIN(1.7, (v1 - v0) - 1.35);
                panel(m, &f, u0, u1, v0, v1, uc - hw, uc + hw, wv0, wv1, detail >= 4);
            }
        }
    }
}

/* A horizontal band (ledge, cornice) around the exterior walls, delta outward, from zlo to zhi,
 * cut square at party walls. */
static void band(gc_mesh *m, const bldg *b, double delta, double zlo, double zhi)
{
    const lot *f = &b->f;
    double off[GC_MAX_POLY] = {0};
    sl_dvec2 o[GC_MAX_POLY];
    int n = f->n;
    for (int e = 0; e < n; e++)
        off[e] = exterior(f->tag[e]) ? -delta : 0.0;
    if (!gc_offset(f->p, n, off, o))
        return;
    sl_dvec3 up = {0, 0, 1}, down = {0, 0, -1};
    for (int e = 0; e < n; e++) {
        if (off[e] == 0)
            continue;
        int e1 = (e + 1) % n, e0 = (e + n - 1) % n;
        sl_dvec2 A = f->p[e], B = f->p[e1], A2 = o[e], B2 = o[e1];
        sl_dvec2 U = sl_d2_unit(sl_d2_sub(B, A)), W = sl_d2(U.y, -U.x);
        /* at a party wall the band ends on the party line, unless that line leans outward over
         * the wall's end (a mitre cut): then it ends square. Either way it stays inside the
         * cell's ground quad, so it never reaches into the street or a park next door. */
        if (off[e0] == 0 && sl_d2_dot(sl_d2_sub(A2, A), U) < 0)
            A2 = sl_d2_add(A, sl_d2_scale(W, delta));
        if (off[e1] == 0 && sl_d2_dot(sl_d2_sub(B2, B), U) > 0)
            B2 = sl_d2_add(B, sl_d2_scale(W, delta));
        sl_dvec2 P0 = sl_d2_add(A, sl_d2_scale(W, delta));
        double tlo = -INFINITY, thi = INFINITY;
        for (int k = 0; k < 4; k++) {
            sl_dvec2 nk = sl_d2_left(sl_d2_sub(b->cell[(k + 1) & 3], b->cell[k]));
            double ca = sl_d2_dot(sl_d2_sub(P0, b->cell[k]), nk), cb = sl_d2_dot(U, nk);
            if (cb > 1e-12)
                tlo = fmax(tlo, -ca / cb);
            else if (cb < -1e-12)
                thi = fmin(thi, -ca / cb);
        }
        double ta = sl_d2_dot(sl_d2_sub(A2, P0), U), tb = sl_d2_dot(sl_d2_sub(B2, P0), U);
        if (ta < tlo)
            A2 = sl_d2_add(P0, sl_d2_scale(U, tlo));
        if (tb > thi)
            B2 = sl_d2_add(P0, sl_d2_scale(U, thi));
        sl_dvec3 out = sl_d3(U.y, -U.x, 0), uu = sl_d3(U.x, U.y, 0);
        gc_quad(m, sl_d3_of_d2(A2, zlo), sl_d3_of_d2(B2, zlo), sl_d3_of_d2(B2, zhi), sl_d3_of_d2(A2, zhi), out);
        gc_quad(m, sl_d3_of_d2(A, zhi), sl_d3_of_d2(B, zhi), sl_d3_of_d2(B2, zhi), sl_d3_of_d2(A2, zhi), up);
        gc_quad(m, sl_d3_of_d2(A, zlo), sl_d3_of_d2(B, zlo), sl_d3_of_d2(B2, zlo), sl_d3_of_d2(A2, zlo), down);
        if (off[e0] == 0)
            gc_quad(m, sl_d3_of_d2(A, zlo), sl_d3_of_d2(A2, zlo), sl_d3_of_d2(A2, zhi), sl_d3_of_d2(A, zhi),
                    sl_d3_scale(uu, -1));
        if (off[e1] == 0)
            gc_quad(m, sl_d3_of_d2(B, zlo), sl_d3_of_d2(B2, zlo), sl_d3_of_d2(B2, zhi), sl_d3_of_d2(B, zhi), uu);
    }
}

/* Tower curtain wall: vertical fins at every bay line. */
static void fins(gc_mesh *m, const bldg *b)
{
    sl_dvec3 up = {0, 0, 1}, down = {0, 0, -1};
    for (int e = 0; e < b->f.n; e++) {
        sl_dvec2 A = b->f.p[e], B = b->f.p[(e + 1) % b->f.n];
        double len = sl_d2_len(sl_d2_sub(B, A));
        int nb = bays(b, len);
        if (nb < 2)
            continue;
        frame f = wall_frame(A, B);
        sl_dvec3 out = sl_d3(f.w.x, f.w.y, 0), uu = sl_d3(f.u.x, f.u.y, 0);
        double z0 = b->base + b->gf, z1 = b->eave, w = 0.35;
        for (int k = 1; k < nb; k++) {
            double u = len * k / nb, u0 = u - 0.12, u1 = u + 0.12;
            gc_quad(m, fp(&f, u0, z0, w), fp(&f, u1, z0, w), fp(&f, u1, z1, w), fp(&f, u0, z1, w), out);
            gc_quad(m, fp(&f, u0, z0, 0), fp(&f, u0, z1, 0), fp(&f, u0, z1, w), fp(&f, u0, z0, w), sl_d3_scale(uu, -1));
            gc_quad(m, fp(&f, u1, z0, 0), fp(&f, u1, z1, 0), fp(&f, u1, z1, w), fp(&f, u1, z0, w), uu);
            gc_quad(m, fp(&f, u0, z1, 0), fp(&f, u1, z1, 0), fp(&f, u1, z1, w), fp(&f, u0, z1, w), up);
            gc_quad(m, fp(&f, u0, z0, 0), fp(&f, u1, z0, 0), fp(&f, u1, z0, w), fp(&f, u0, z0, w), down);
        }
    }
}

/* Inset of the roof: exterior edges move in by r, party/blank edges stay (fire walls). */
static bool roof_inset(const bldg *b, double r, sl_dvec2 *out)
{
    double off[GC_MAX_POLY] = {0};
    for (int e = 0; e < b->f.n; e++)
        off[e] = exterior(b->f.tag[e]) ? r : 0.0;
    return gc_offset(b->f.p, b->f.n, off, out) && gc_simple(out, b->f.n);
}

static double roof_max_inset(const bldg *b)
{
    sl_dvec2 tmp[GC_MAX_POLY];
    double lo = 0, hi = sqrt(fabs(gc_area(b->f.p, b->f.n)));
    for (int it = 0; it < 20; it++) {
        double mid = 0.5 * (lo + hi);
        if (roof_inset(b, mid, tmp))
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

static void roof_sloped(gc_mesh *m, const bldg *b, double r, double rise)
{
    const lot *f = &b->f;
    sl_dvec2 in[GC_MAX_POLY];
    if (!(r > 0.3) || !roof_inset(b, r, in)) {
        gc_cap(m, f->p, f->n, b->eave, true);
        return;
    }
    double z0 = b->eave, z1 = b->eave + rise;
    for (int e = 0; e < f->n; e++) {
        int e1 = (e + 1) % f->n;
        sl_dvec2 U = sl_d2_unit(sl_d2_sub(f->p[e1], f->p[e]));
        /* slopes face outward and up; a fire wall on a party edge faces outward */
        sl_dvec3 want = exterior(f->tag[e]) ? sl_d3(U.y, -U.x, 1) : sl_d3(U.y, -U.x, 0);
        gc_quad(m, sl_d3_of_d2(f->p[e], z0), sl_d3_of_d2(f->p[e1], z0), sl_d3_of_d2(in[e1], z1), sl_d3_of_d2(in[e], z1),
                want);
    }
    gc_cap(m, in, f->n, z1, true);
}

static void roof_gable(gc_mesh *m, const bldg *b)
{
    const lot *f = &b->f;
    /* gable ends on the pair of opposite edges with more party walls (else the shorter pair) */
    int party02 = (f->tag[0] == GC_TAG_PARTY) + (f->tag[2] == GC_TAG_PARTY);
    int party13 = (f->tag[1] == GC_TAG_PARTY) + (f->tag[3] == GC_TAG_PARTY);
    double l02 = sl_d2_len(sl_d2_sub(f->p[1], f->p[0])) + sl_d2_len(sl_d2_sub(f->p[3], f->p[2]));
    double l13 = sl_d2_len(sl_d2_sub(f->p[2], f->p[1])) + sl_d2_len(sl_d2_sub(f->p[0], f->p[3]));
    int s = party02 != party13 ? (party02 > party13 ? 0 : 1) : (l02 <= l13 ? 0 : 1);
    sl_dvec2 p0 = f->p[s], p1 = f->p[s + 1], p2 = f->p[(s + 2) & 3], p3 = f->p[(s + 3) & 3];
    double span = 0.5 * (sl_d2_len(sl_d2_sub(p1, p0)) + sl_d2_len(sl_d2_sub(p3, p2)));
    double z0 = b->eave, z1 = b->eave + 0.5 * span * b->roof_slope;
    sl_dvec3 m0 = sl_d3_of_d2(sl_d2_lerp(p0, p1, 0.5), z1), m2 = sl_d3_of_d2(sl_d2_lerp(p2, p3, 0.5), z1);
    sl_dvec2 u01 = sl_d2_unit(sl_d2_sub(p1, p0)), u12 = sl_d2_unit(sl_d2_sub(p2, p1)),
             u23 = sl_d2_unit(sl_d2_sub(p3, p2)), u30 = sl_d2_unit(sl_d2_sub(p0, p3));
    sl_dvec3 w1 = sl_d3(u12.y, -u12.x, 1), w3 = sl_d3(u30.y, -u30.x, 1);
    gc_tri(m, sl_d3_of_d2(p1, z0), sl_d3_of_d2(p2, z0), m2, w1);
    gc_tri(m, sl_d3_of_d2(p1, z0), m2, m0, w1);
    gc_tri(m, sl_d3_of_d2(p3, z0), sl_d3_of_d2(p0, z0), m0, w3);
    gc_tri(m, sl_d3_of_d2(p3, z0), m0, m2, w3);
    gc_tri(m, sl_d3_of_d2(p0, z0), sl_d3_of_d2(p1, z0), m0, sl_d3(u01.y, -u01.x, 0));
    gc_tri(m, sl_d3_of_d2(p2, z0), sl_d3_of_d2(p3, z0), m2, sl_d3(u23.y, -u23.x, 0));
}

/* Build the mesh, add the object and its footprint. */
static sl_status emit_building(gc_city *c, bldg *b)
{
    uint32_t detail = c->opt->detail;
    gc_mesh *m = &c->mesh;
    gc_mesh_reset(m);
    lot *f = &b->f;
    for (int e = 0; e < f->n; e++) {
        double len = sl_d2_len(sl_d2_sub(f->p[(e + 1) % f->n], f->p[e]));
        b->windows[e] = detail >= 3 && !b->tower &&
                        (f->tag[e] == GC_TAG_STREET || (f->tag[e] == GC_TAG_COURT && detail >= 4)) && bays(b, len) >= 1 &&
                        len / bays(b, len) >= 2.6;
    }
    for (int e = 0; e < f->n; e++)
        wall(m, b, e, detail);
    if (detail >= 2) {
        int every = b->tower ? (detail >= 4 ? 1 : 3) : 1;
        for (int k = 0; k < b->floors; k++)
            if (k % every == 0) {
                double z = b->base + b->gf + k * b->fh;
                band(m, b, GC_LEDGE, z - 0.15, z + 0.15);
            }
    }
    if (detail >= 3 && b->tower)
        fins(m, b);
    if (detail >= 1 && !b->tower)
        band(m, b, GC_CORNICE, b->eave - 0.5, b->eave);
    int roof = detail >= 1 ? b->roof : ROOF_FLAT;
    if (roof == ROOF_GABLE && (f->n != 4 || !gc_convex(f->p, 4)))
        roof = ROOF_MANSARD;
    switch (roof) {
    case ROOF_MANSARD: {
        double r = SL_MIN(b->roof_r, 0.9 * roof_max_inset(b));
        roof_sloped(m, b, r, r * b->roof_slope);
        break;
    }
    case ROOF_HIP: {
        double r = 0.92 * roof_max_inset(b);
        roof_sloped(m, b, r, r * b->roof_slope);
        break;
    }
    case ROOF_GABLE:
        roof_gable(m, b);
        break;
    default:
        gc_cap(m, f->p, f->n, b->eave, true);
        if (detail >= 1 && b->tower) {
            /* a plant room on the roof */
            sl_dvec2 in[GC_MAX_POLY];
            double r = 0.3 * gc_max_inset(f->p, f->n);
            if (r > 1 && gc_offset_all(f->p, f->n, r, in) && gc_convex(in, f->n))
                gc_prism(m, in, f->n, b->eave, b->eave + 3.5, true, false);
        }
        break;
    }
    uint32_t object;
    if (!gc_commit_object(c, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER, b->color, &object))
        return c->err ? c->err->status : SL_ERROR_INTERNAL;
    /* the occluder must lie inside the building: walls with recesses move in by their depth */
    double off[GC_MAX_POLY] = {0};
    sl_dvec2 fpoly[GC_MAX_POLY];
    for (int e = 0; e < f->n; e++)
        off[e] = b->windows[e] ? GC_RECESS : 0.0;
    if (!gc_offset(f->p, f->n, off, fpoly))
        memcpy(fpoly, f->p, sizeof(sl_dvec2) * (size_t)f->n);
    float xy[2 * GC_MAX_POLY];
    for (int k = 0; k < f->n; k++)
        xy[2 * k] = (float)fpoly[k].x, xy[2 * k + 1] = (float)fpoly[k].y;
    sl_footprint_desc fd = {xy, (uint32_t)f->n, (float)b->base, (float)b->eave, object};
    sl_status st = sl_scene_add_footprint(c->scene, &fd, NULL, c->err);
    if (st != SL_OK)
        return st;
    c->n_buildings++;
    return SL_OK;
}

/* ---- lots ---- */

typedef struct cut {
    double key;     /* side + position along it in [0,1) */
    sl_dvec2 outer, inner;
} cut;

static void lot_push(lot *l, sl_dvec2 p, uint8_t tag)
{
    if (l->n > 0 && sl_d2_len(sl_d2_sub(p, l->p[l->n - 1])) < 1e-6) {
        l->tag[l->n - 1] = tag;
        return;
    }
    if (l->n < GC_MAX_POLY) {
        l->p[l->n] = p;
        l->tag[l->n] = tag;
        l->n++;
    }
}

/* Perimeter lots of outer quad B around inner quad I; returns the lot count. */
static int perimeter_lots(sl_rng *r, const sl_dvec2 B[4], const sl_dvec2 I[4], const uint8_t stag[4], double depth,
                          double lotw, lot *lots, int max_lots)
{
    bool merged[4];
    for (int k = 0; k < 4; k++)
        merged[k] = sl_rng_float(r) < 0.3f;
    /* interior cut positions are drawn once; corner merging is then repaired until valid */
    cut inner_cuts[4][32];
    int ninner[4] = {0, 0, 0, 0};
    for (int k = 0; k < 4; k++) {
        sl_dvec2 a = B[k], b = B[(k + 1) & 3];
        double len = sl_d2_len(sl_d2_sub(b, a));
        sl_dvec2 U = sl_d2_unit(sl_d2_sub(b, a));
        sl_dvec2 ia = I[k], ib = I[(k + 1) & 3];
        double ilen = sl_d2_len(sl_d2_sub(ib, ia));
        sl_dvec2 iu = sl_d2_unit(sl_d2_sub(ib, ia));
        long nseg = SL_MAX(1L, lround(len / lotw));
        double last = -1e9;
        for (long q = 1; q < nseg && ninner[k] < 32; q++) {
            double s = len * (double)q / (double)nseg + sl_rng_range(r, -0.15f, 0.15f) * len / (double)nseg;
            if (s < depth + 3 || s > len - depth - 3 || s - last < 6)
                continue;
            sl_dvec2 P = sl_d2_add(a, sl_d2_scale(U, s));
            double t = sl_d2_dot(sl_d2_sub(P, ia), iu);
            if (t < 3 || t > ilen - 3)
                continue;
            cut cu = {k + s / len, P, sl_d2_add(ia, sl_d2_scale(iu, t))};
            inner_cuts[k][ninner[k]++] = cu;
            last = s;
        }
    }
    cut cuts[4 * 33];
    int nc = 0;
    for (int attempt = 0; attempt < 8; attempt++) {
        nc = 0;
        for (int k = 0; k < 4; k++) {
            if (!merged[k]) {
                cut cu = {(double)k, B[k], I[k]};
                cuts[nc++] = cu;
            }
            for (int q = 0; q < ninner[k]; q++)
                cuts[nc++] = inner_cuts[k][q];
        }
        if (nc < 2) {
            for (int k = 0; k < 4; k++)
                merged[k] = false;
            continue;
        }
        /* a lot may turn at most two corners (a U); unmerge the first corner of a longer run */
        bool ok = true;
        for (int q = 0; q < nc && ok; q++) {
            double ka = cuts[q].key, kb = cuts[(q + 1) % nc].key;
            if (kb <= ka)
                kb += 4;
            int turned = 0, first = -1;
            for (int m = (int)floor(ka) + 1; m < kb; m++) {
                if (first < 0)
                    first = m & 3;
                turned++;
            }
            if (turned > 2) {
                merged[first] = false;
                ok = false;
            }
        }
        if (ok)
            break;
    }
    int nl = 0;
    for (int q = 0; q < nc && nl < max_lots; q++) {
        const cut *a = &cuts[q], *b = &cuts[(q + 1) % nc];
        double ka = a->key, kb = b->key;
        if (kb <= ka)
            kb += 4;
        lot *l = &lots[nl];
        l->n = 0;
        int side = (int)floor(ka) & 3;
        lot_push(l, a->outer, stag[side]);
        int corners[4], ncor = 0;
        for (int m = (int)floor(ka) + 1; m < kb && ncor < 4; m++)
            corners[ncor++] = m & 3;
        for (int k = 0; k < ncor; k++)
            lot_push(l, B[corners[k]], stag[corners[k]]);
        lot_push(l, b->outer, GC_TAG_PARTY);
        lot_push(l, b->inner, GC_TAG_COURT);
        for (int k = ncor - 1; k >= 0; k--)
            lot_push(l, I[corners[k]], GC_TAG_COURT);
        lot_push(l, a->inner, GC_TAG_PARTY);
        if (l->n >= 3 && gc_area(l->p, l->n) > 20 && gc_simple(l->p, l->n))
            nl++;
    }
    return nl;
}

/* Slabs across the longer axis of quad B. */
static int slab_lots(sl_rng *r, const sl_dvec2 B[4], const uint8_t stag[4], double lotw, lot *lots, int max_lots)
{
    double l02 = sl_d2_len(sl_d2_sub(B[1], B[0])) + sl_d2_len(sl_d2_sub(B[3], B[2]));
    double l13 = sl_d2_len(sl_d2_sub(B[2], B[1])) + sl_d2_len(sl_d2_sub(B[0], B[3]));
    int s = l02 >= l13 ? 0 : 1;
    sl_dvec2 q0 = B[s], q1 = B[s + 1], q2 = B[(s + 2) & 3], q3 = B[(s + 3) & 3];
    uint8_t t0 = stag[s], t1 = stag[s + 1], t2 = stag[(s + 2) & 3], t3 = stag[(s + 3) & 3];
    double len = 0.5 * (s == 0 ? l02 : l13);
    long n = SL_MAX(1L, lround(len / lotw));
    if (n > max_lots)
        n = max_lots;
    double ts[65];
    ts[0] = 0, ts[n] = 1;
    for (long q = 1; q < n; q++)
        ts[q] = ((double)q + sl_rng_range(r, -0.2f, 0.2f)) / (double)n;
    for (long q = 0; q < n; q++) {
        lot *l = &lots[q];
        l->n = 0;
        double ta = ts[q], tb = ts[q + 1];
        lot_push(l, sl_d2_lerp(q0, q1, ta), t0);
        lot_push(l, sl_d2_lerp(q0, q1, tb), q == n - 1 ? t1 : GC_TAG_PARTY);
        lot_push(l, sl_d2_lerp(q3, q2, tb), t2);
        lot_push(l, sl_d2_lerp(q3, q2, ta), q == 0 ? t3 : GC_TAG_PARTY);
    }
    return (int)n;
}

static void set_height(gc_city *c, bldg *b, double height)
{
    if (height < b->gf + 0.5 * b->fh) {
        b->floors = 0;
        b->gf = SL_CLAMP(height, 3.0, 6.0);
    } else {
        b->floors = (int)lround((height - b->gf) / b->fh);
    }
    /* the base is the lowest ground under the footprint (a centimetre lower, so that float
     * rounding never lifts a corner off the ground): walls reach into the slope, never float */
    b->base = c->has_terrain ? gc_ground_min_poly(c, b->f.p, b->f.n) - 0.01 : 0.0;
    b->eave = b->base + b->gf + b->floors * b->fh;
}

static sl_status block(gc_city *c, int i, int j)
{
    const sl_city_options *o = c->opt;
    gc_cell *cl = gc_cellp(c, i, j);
    double off[4];
    uint8_t stag[4];
    for (int k = 0; k < 4; k++) {
        const gc_edge *e = gc_cell_side_edge(c, i, j, k);
        bool street = (e->flags & GC_EDGE_STREET) != 0, border = gc_cell_side_border(c, i, j, k);
        off[k] = street || border ? GC_SETBACK : 0.0;
        stag[k] = street || border ? GC_TAG_STREET : GC_TAG_BLANK;
    }
    /* lots live inside the cell's ground quad, so they can never reach into the street */
    sl_dvec2 B[4];
    if (!gc_offset(cl->ground, 4, off, B) || !gc_convex(B, 4) || gc_min_edge(B, 4) < 6 || gc_area(B, 4) < 100) {
        cl->type = GC_CELL_PLAZA; /* too small to build on: left open */
        c->n_plazas++;
        return SL_OK;
    }
    sl_rng r;
    gc_rng(c, GC_RNG_BLOCK, (uint32_t)i, (uint32_t)j, &r);
    double hb = sl_rng_range(&r, o->height_min, o->height_max);
    double gf = sl_rng_range(&r, 4.0f, 5.0f), fh = sl_rng_range(&r, 3.1f, 3.7f);
    double lotw = sl_rng_range(&r, 13.0f, 24.0f), depth = sl_rng_range(&r, 11.0f, 15.5f);

    if (cl->type == GC_CELL_TOWER) {
        sl_dvec2 T[4];
        double margin = SL_MAX(6.0, sl_rng_range(&r, 0.12f, 0.22f) * gc_min_edge(B, 4));
        if (gc_offset_all(B, 4, margin, T) && gc_convex(T, 4) && gc_min_edge(T, 4) >= 10) {
            bldg b;
            memset(&b, 0, sizeof b);
            b.tower = true;
            memcpy(b.cell, cl->ground, sizeof b.cell);
            if (sl_rng_float(&r) < 0.5f) {
                double ch = 0.18 * gc_min_edge(T, 4);
                for (int k = 0; k < 4; k++) {
                    sl_dvec2 prev = T[(k + 3) & 3], next = T[(k + 1) & 3];
                    b.f.p[2 * k] = sl_d2_add(T[k], sl_d2_scale(sl_d2_unit(sl_d2_sub(prev, T[k])), ch));
                    b.f.p[2 * k + 1] = sl_d2_add(T[k], sl_d2_scale(sl_d2_unit(sl_d2_sub(next, T[k])), ch));
                }
                b.f.n = 8;
            } else {
                memcpy(b.f.p, T, sizeof T);
                b.f.n = 4;
            }
            for (int k = 0; k < b.f.n; k++)
                b.f.tag[k] = GC_TAG_STREET;
            b.gf = 5.0, b.fh = 3.6, b.bay = 3.0, b.roof = ROOF_FLAT;
            b.color = tower_palette[sl_rng_below(&r, (uint32_t)SL_COUNTOF(tower_palette))];
            set_height(c, &b, sl_rng_range(&r, o->tower_height_min, o->tower_height_max));
            c->n_towers++;
            c->n_blocks++;
            return emit_building(c, &b);
        }
        cl->type = GC_CELL_BLOCK; /* no room for a plaza: an ordinary block */
    }

    c->n_blocks++;
    lot lots[64];
    int nl;
    sl_dvec2 I[4];
    if (gc_offset_all(B, 4, depth, I) && gc_convex(I, 4) && gc_min_edge(I, 4) >= 6 && gc_area(I, 4) >= 60) {
        nl = perimeter_lots(&r, B, I, stag, depth, lotw, lots, 64);
        gc_court court;
        memset(&court, 0, sizeof court);
        memcpy(court.q, I, sizeof I);
        court.cell = (uint32_t)(j * c->nx + i);
        if (!sl_array_push(c->alloc, &c->courts, sizeof court, &court, 1))
            return sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory");
    } else {
        nl = slab_lots(&r, B, stag, lotw, lots, 64);
    }
    for (int q = 0; q < nl; q++) {
        sl_rng rb;
        gc_rng(c, GC_RNG_BUILDING, (uint32_t)(j * c->nx + i), (uint32_t)q, &rb);
        bldg b;
        memset(&b, 0, sizeof b);
        b.f = lots[q];
        memcpy(b.cell, cl->ground, sizeof b.cell);
        b.gf = gf, b.fh = fh;
        b.bay = sl_rng_range(&rb, 3.8f, 4.7f);
        bool convex = gc_convex(b.f.p, b.f.n);
        float u = sl_rng_float(&rb);
        if (u < 0.45f)
            b.roof = ROOF_MANSARD;
        else if (u < 0.65f)
            b.roof = ROOF_HIP;
        else if (u < 0.8f)
            b.roof = convex && b.f.n == 4 ? ROOF_GABLE : ROOF_MANSARD;
        else
            b.roof = ROOF_FLAT;
        b.roof_r = sl_rng_range(&rb, 2.5f, 4.5f);
        b.roof_slope = b.roof == ROOF_MANSARD ? sl_rng_range(&rb, 1.0f, 1.6f) : sl_rng_range(&rb, 0.5f, 0.8f);
        b.color = facade_palette[sl_rng_below(&rb, (uint32_t)SL_COUNTOF(facade_palette))];
        double h = hb + sl_rng_range(&rb, -3.0f, 3.0f);
        if (sl_rng_float(&rb) < 0.1f)
            h += fh * (1 + sl_rng_below(&rb, 2));
        set_height(c, &b, SL_CLAMP(h, (double)o->height_min, (double)o->height_max + 2 * fh));
        sl_status st = emit_building(c, &b);
        if (st != SL_OK)
            return st;
    }
    return SL_OK;
}

sl_status gc_buildings(gc_city *c)
{
    uint64_t total = (uint64_t)c->nx * c->ny;
    for (int j = 0; j < c->ny; j++) {
        for (int i = 0; i < c->nx; i++) {
            uint32_t t = gc_cellp(c, i, j)->type;
            if (t == GC_CELL_BLOCK || t == GC_CELL_TOWER) {
                sl_status st = block(c, i, j);
                if (st != SL_OK)
                    return st;
            } else if (t == GC_CELL_PARK) {
                c->n_parks++;
            } else if (t == GC_CELL_SQUARE) {
                c->n_squares++;
            }
        }
        if (!sl_progress_report(&c->opt->progress, "city: buildings", (uint64_t)(j + 1) * c->nx, total))
            return sl_fail(c->err, SL_ERROR_CANCELLED, "city: cancelled while generating buildings");
    }
    return SL_OK;
}

/* cullmap: occluder shadows rasterized top-down into a cull map, then a scan of the grid cells in
 * the view frustum against it.
 *
 * P. Wonka, "Occlusion Culling for Real-Time Rendering of Urban Environments", PhD thesis, TU Wien
 * 2001, chapter 4 (P. Wonka and D. Schmalstieg, "Occluder Shadows for Fast Walkthroughs of Urban
 * Environments", Eurographics 1999): §4.2.1 occluder edges and their shadows, §4.2.2 and §4.3.2
 * the per-frame algorithm (select the occluders within a radius, reject back faces, render their
 * shadows into the cull map whose z-buffer keeps the highest shadow, traverse the cells of the
 * view frustum with the two-level test), §4.3.4 the sampling correction that keeps it conservative.
 *
 * One cull-map pixel is one scene-grid cell. Per frame:
 *  1. the cells of the frustum's ground plan are found (row spans) and the map is cleared there;
 *  2. occluder edges are gathered ring by ring around the eye (nearest first) within the radius
 *     and the frustum's azimuth range; an edge is used if it faces the eye (see urban_internal.h),
 *     and skipped if its façade already lies in the shadow of the edges drawn before it (then so
 *     does its own shadow); its shadow is rasterized by src/raster/cullmap_raster.c with its
 *     silhouette-chain neighbours as seam partners, so connected façades leave no crack; this
 *     first pass draws into a coarse map, one pixel per 8x8 cells, which settles the deep shadow
 *     far away cheaply;
 *  3. a second pass draws the same shadows (less those the maps now hide) into the fine map,
 *     which starts from the coarse values, skipping the 8x8 blocks the coarse map hides whole;
 *     both maps keep their unsaturated cells as bits, so that only those are visited, and leave
 *     out the wedges narrower than two of their cells even at the far end of the view (see thin());
 *  4. each cell of the spans whose highest object rises above its value (the larger of its fine
 *     and coarse values, both valid for the whole cell) has its objects tested individually (box
 *     top above the value, box inside the frustum), once per frame; hidden blocks are skipped.
 * The map value of a cell bounds from below the heights hidden over the whole cell, for anything at
 * or above the cell's lowest object (cullmap_raster.h), so an object is dropped only when every
 * cell of it in the frustum's plan hides its box. Orthographic cameras have no eye point: the
 * method then falls back to frustum culling over the grid. */
#include "urban_internal.h"

#include "sightline/image.h"
#include "sightline/urban.h"

#include <stdlib.h>

static const char g_help[] =
    "cell=NUMBER (default 12): scene-grid (and cull-map) cell size in metres (0.5..1000)\n"
    "radius=NUMBER (default 800): occluders farther than this (metres, in plan) are not used (1..1e6)\n";

typedef struct cullmap_config {
    float cell, radius;
} cullmap_config;

typedef struct cullmap_state {
    sl_allocator alloc;
    cullmap_config cfg;
    sl_urban_scene us;
    sl_cullmap_grid map;
    float *z;
    uint16_t *unsat;            /* per 8x8 block: cells still below their top (saturation) */
    sl_cullmap_part *part;      /* per cell: partial coverage by separate shadows */
    /* the coarse map: one cell per 8x8 block of the fine one (the fine map's saturation blocks);
     * drawn first, it settles the deep shadow far away, which the fine pass and the traversal then
     * skip block by block */
    sl_cullmap_grid cmap;
    float *cz, *ctop, *cfloor;
    uint16_t *cunsat;
    uint32_t cbnx, cbny;
    sl_cullmap_part *cpart;
    int32_t *cx0, *cx1;         /* bny entries: the coarse spans */
    /* the unsaturated cells as bits (sl_cullmap_grid.row_bits ...), fine and coarse */
    uint64_t *rbits, *bbits, *crbits, *cbbits;
    uint8_t *bcount, *cbcount;
    uint32_t words, cwords;
    double reach;               /* plan distance from the eye to the farthest corner of the spans' box */
    uint32_t cj0, cj1;
    sl_urban_mode_cache modes;  /* per edge: how it serves this frame */
    uint32_t *drawn;            /* edges drawn into the coarse map, in order; bit 31: reversed mode */
    uint32_t drawn_count;
    uint32_t bnx, bny;
    int32_t *x0, *x1;           /* ny entries: the frustum's spans */
    int32_t *ring_i0, *ring_i1; /* ny entries: per row, the columns of the occluder search */
    uint32_t j0, j1;            /* rows of the last frame's spans */
    bool have_spans;
    uint32_t frame;
    uint32_t *obj_stamp, *edge_stamp, *fp_excluded;
    uint32_t *sort_scratch;
    uint64_t edges_used, edges_hidden;
} cullmap_state;

static sl_status cullmap_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    cullmap_config *c = config;
    (void)g;
    sl_status st;
    if ((st = sl_opts_float(o, "cell", 12.0f, 0.5f, 1000.0f, &c->cell, err)) != SL_OK ||
        (st = sl_opts_float(o, "radius", 800.0f, 1.0f, 1e6f, &c->radius, err)) != SL_OK)
        return st;
    return SL_OK;
}

/* The coarse cells' highest and lowest points, and the lowest floor of the map: shadow values at
 * or below it hide nothing, so the rasterizer clips there (clipping only ever drops writes). */
static void set_heights(cullmap_state *s)
{
    const sl_urban_scene *u = &s->us;
    float lo = INFINITY;
    for (uint32_t c = 0; c < u->ncells; c++)
        lo = u->cell_floor[c] < lo ? u->cell_floor[c] : lo;
    s->map.useful_min = s->cmap.useful_min = lo < INFINITY ? lo : -INFINITY;
    for (uint32_t bj = 0; bj < s->bny; bj++)
        for (uint32_t bi = 0; bi < s->bnx; bi++) {
            float top = -INFINITY, fl = INFINITY;
            for (uint32_t j = bj << 3; j < SL_MIN((bj + 1) << 3, u->ny); j++)
                for (uint32_t i = bi << 3; i < SL_MIN((bi + 1) << 3, u->nx); i++) {
                    top = sl_urban_maxf(top, u->cell_top[j * u->nx + i]);
                    fl = sl_urban_minf(fl, u->cell_floor[j * u->nx + i]);
                }
            s->ctop[bj * s->bnx + bi] = top;
            s->cfloor[bj * s->bnx + bi] = fl;
        }
}

static void cullmap_destroy(void *state)
{
    cullmap_state *s = state;
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    const sl_urban_scene *u = &s->us;
    sl_free(a, s->z, (size_t)(u->ncells ? u->ncells : 1) * sizeof(float));
    sl_free(a, s->unsat, (size_t)s->bnx * s->bny * sizeof(uint16_t) + 2);
    sl_free(a, s->part, (size_t)(u->ncells ? u->ncells : 1) * sizeof(sl_cullmap_part));
    size_t nb = (size_t)s->bnx * s->bny;
    sl_free(a, s->cz, (nb ? nb : 1) * sizeof(float));
    sl_free(a, s->ctop, (nb ? nb : 1) * sizeof(float));
    sl_free(a, s->cfloor, (nb ? nb : 1) * sizeof(float));
    sl_free(a, s->cunsat, (size_t)s->cbnx * s->cbny * sizeof(uint16_t) + 2);
    sl_free(a, s->cpart, (nb ? nb : 1) * sizeof(sl_cullmap_part));
    sl_free(a, s->rbits, ((size_t)u->ny * s->words + 1) * sizeof(uint64_t));
    sl_free(a, s->bbits, ((size_t)s->bny * s->words + 1) * sizeof(uint64_t));
    sl_free(a, s->bcount, (size_t)s->bny * u->nx + 1);
    sl_free(a, s->crbits, ((size_t)s->bny * s->cwords + 1) * sizeof(uint64_t));
    sl_free(a, s->cbbits, ((size_t)s->cbny * s->cwords + 1) * sizeof(uint64_t));
    sl_free(a, s->cbcount, (size_t)s->cbny * s->bnx + 1);
    sl_free(a, s->cx0, (size_t)(s->bny ? s->bny : 1) * sizeof(int32_t));
    sl_free(a, s->cx1, (size_t)(s->bny ? s->bny : 1) * sizeof(int32_t));
    sl_free(a, s->drawn, (u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
    sl_free(a, s->modes.frame, (u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
    sl_free(a, s->modes.mode, u->edge_count ? u->edge_count : 1);
    sl_free(a, s->x0, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    sl_free(a, s->ring_i0, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    sl_free(a, s->ring_i1, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    sl_free(a, s->x1, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    size_t no = u->object_count ? u->object_count : 1;
    sl_free(a, s->obj_stamp, no * sizeof(uint32_t));
    sl_free(a, s->sort_scratch, no * sizeof(uint32_t));
    sl_free(a, s->edge_stamp, (u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
    sl_free(a, s->fp_excluded, (u->fp_count ? u->fp_count : 1) * sizeof(uint32_t));
    sl_urban_scene_free(&s->us);
    sl_free(a, s, sizeof *s);
}

static sl_status cullmap_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state,
                                sl_error *err)
{
    cullmap_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cullmap: out of memory");
    s->alloc = *alloc;
    s->cfg = *(const cullmap_config *)config;
    const sl_allocator *a = &s->alloc;
    sl_status st = sl_urban_scene_build(scene, s->cfg.cell, a, &s->us, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "cullmap");
        sl_free(a, s, sizeof *s);
        return st;
    }
    const sl_urban_scene *u = &s->us;
    size_t no = u->object_count ? u->object_count : 1;
    s->z = sl_alloc(a, (size_t)(u->ncells ? u->ncells : 1) * sizeof(float));
    s->bnx = (u->nx + 7) >> 3;
    s->bny = (u->ny + 7) >> 3;
    s->unsat = sl_calloc(a, (size_t)s->bnx * s->bny * sizeof(uint16_t) + 2, 1);
    s->part = sl_calloc(a, u->ncells ? u->ncells : 1, sizeof(sl_cullmap_part));
    size_t nb = (size_t)s->bnx * s->bny;
    s->cbnx = (s->bnx + 7) >> 3;
    s->cbny = (s->bny + 7) >> 3;
    s->cz = sl_alloc(a, (nb ? nb : 1) * sizeof(float));
    s->ctop = sl_alloc(a, (nb ? nb : 1) * sizeof(float));
    s->cfloor = sl_alloc(a, (nb ? nb : 1) * sizeof(float));
    s->cunsat = sl_calloc(a, (size_t)s->cbnx * s->cbny * sizeof(uint16_t) + 2, 1);
    s->cpart = sl_calloc(a, nb ? nb : 1, sizeof(sl_cullmap_part));
    s->words = (u->nx + 63) >> 6;
    s->cwords = (s->bnx + 63) >> 6;
    s->rbits = sl_calloc(a, (size_t)u->ny * s->words + 1, sizeof(uint64_t));
    s->bbits = sl_calloc(a, (size_t)s->bny * s->words + 1, sizeof(uint64_t));
    s->bcount = sl_calloc(a, (size_t)s->bny * u->nx + 1, 1);
    s->crbits = sl_calloc(a, (size_t)s->bny * s->cwords + 1, sizeof(uint64_t));
    s->cbbits = sl_calloc(a, (size_t)s->cbny * s->cwords + 1, sizeof(uint64_t));
    s->cbcount = sl_calloc(a, (size_t)s->cbny * s->bnx + 1, 1);
    s->cx0 = sl_alloc(a, (size_t)(s->bny ? s->bny : 1) * sizeof(int32_t));
    s->cx1 = sl_alloc(a, (size_t)(s->bny ? s->bny : 1) * sizeof(int32_t));
    s->drawn = sl_alloc(a, (u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
    s->modes.frame = sl_calloc(a, u->edge_count ? u->edge_count : 1, sizeof(uint32_t));
    s->modes.mode = sl_calloc(a, u->edge_count ? u->edge_count : 1, 1);
    s->x0 = sl_alloc(a, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    s->ring_i0 = sl_alloc(a, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    s->ring_i1 = sl_alloc(a, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    s->x1 = sl_alloc(a, (size_t)(u->ny ? u->ny : 1) * sizeof(int32_t));
    s->obj_stamp = sl_calloc(a, no, sizeof(uint32_t));
    s->sort_scratch = sl_alloc(a, no * sizeof(uint32_t));
    s->edge_stamp = sl_calloc(a, u->edge_count ? u->edge_count : 1, sizeof(uint32_t));
    s->fp_excluded = sl_calloc(a, u->fp_count ? u->fp_count : 1, sizeof(uint32_t));
    if (!s->z || !s->unsat || !s->ring_i0 || !s->ring_i1 || !s->rbits || !s->bbits || !s->bcount || !s->crbits ||
        !s->cbbits || !s->cbcount || !s->part || !s->cz || !s->ctop || !s->cfloor || !s->cunsat || !s->cpart ||
        !s->cx0 || !s->cx1 || !s->drawn || !s->modes.frame || !s->modes.mode || !s->x0 || !s->x1 || !s->obj_stamp ||
        !s->sort_scratch || !s->edge_stamp || !s->fp_excluded) {
        cullmap_destroy(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cullmap: out of memory for a %ux%u cull map", u->nx, u->ny);
    }
    for (uint32_t c = 0; c < u->ncells; c++)
        s->z[c] = -INFINITY;
    s->map.nx = u->nx;
    s->map.ny = u->ny;
    s->map.min_x = u->min_x;
    s->map.min_y = u->min_y;
    s->map.cell = u->cell;
    s->map.margin = u->margin;
    s->map.z = s->z;
    s->map.floor = u->cell_floor;
    s->map.top = u->cell_top;
    s->map.unsat = s->unsat;
    s->map.block_shift = 3;
    s->map.bnx = s->bnx;
    s->map.part = s->part;
    s->map.row_bits = s->rbits;
    s->map.band_bits = s->bbits;
    s->map.band_count = s->bcount;
    s->map.words = s->words;
    s->cmap = s->map;
    s->cmap.row_bits = s->crbits;
    s->cmap.band_bits = s->cbbits;
    s->cmap.band_count = s->cbcount;
    s->cmap.words = s->cwords;
    s->map.block_z = s->cz;     /* the coarse map's cells are the fine map's blocks */
    s->map.block_top = s->ctop;
    s->cmap.nx = s->bnx;
    s->cmap.ny = s->bny;
    s->cmap.cell = 8.0 * u->cell;
    s->cmap.z = s->cz;
    s->cmap.floor = s->cfloor;
    s->cmap.top = s->ctop;
    s->cmap.unsat = s->cunsat;
    s->cmap.bnx = s->cbnx;
    s->cmap.part = s->cpart;
    for (size_t b = 0; b < nb; b++)
        s->cz[b] = -INFINITY;
    set_heights(s);
    *state = s;
    return SL_OK;
}

static sl_status cullmap_scene_changed(void *state, sl_error *err)
{
    cullmap_state *s = state;
    sl_status st = sl_urban_scene_refresh(&s->us, err);
    if (st != SL_OK)
        sl_error_prefix(err, "cullmap");
    set_heights(s);
    return st;
}

/* Is cell c inside this frame's spans (so that its map value is this frame's)? */
static inline bool in_spans(const cullmap_state *s, uint32_t c)
{
    uint32_t j = c / s->us.nx, i = c % s->us.nx;
    return j >= s->j0 && j <= s->j1 && (int32_t)i >= s->x0[j - s->j0] && (int32_t)i <= s->x1[j - s->j0];
}

/* The cull-map value of cell c this frame: the larger of its own and its coarse cell's (both hold
 * for the whole cell; once the fine map is seeded its own value is the larger); -INFINITY outside
 * the spans. coarse_only: the fine map is not set up yet (the coarse pass). The fine values of the
 * blocks the coarse map hides whole are not set up (nor read: the coarse value hides all there). */
static inline float cell_value(const cullmap_state *s, uint32_t c, bool coarse_only)
{
    if (!in_spans(s, c))
        return -INFINITY;
    uint32_t j = c / s->us.nx, i = c % s->us.nx, b = (j >> 3) * s->bnx + (i >> 3);
    float zc = s->cz[b];
    return !coarse_only && zc < s->ctop[b] && s->z[c] > zc ? s->z[c] : zc;
}

/* Does the façade of edge e lie in the shadow already drawn (every cell it crosses hides its whole
 * height, from base to roof)? Then its own shadow hides nothing new. */
static bool edge_hidden(const cullmap_state *s, uint32_t e, bool coarse_only)
{
    const sl_urban_scene *u = &s->us;
    const sl_urban_edge *ed = &u->edges[e];
    const sl_urban_fp *f = &u->fps[ed->fp];
    if (!ed->cell_count)
        return false;
    for (uint32_t k = 0; k < ed->cell_count; k++) {
        uint32_t c = u->edge_cells[ed->cell_first + k];
        if (!(cell_value(s, c, coarse_only) >= f->roof) || !(u->cell_floor[c] <= f->base))
            return false;
    }
    return true;
}

/* Zero the fine map's saturation counts and bits on the blocks, bands and rows of the clip. */
static void clear_fine_counts(cullmap_state *s, const sl_cullmap_clip *clip)
{
    for (uint32_t bj = clip->j0 >> 3; bj <= clip->j1 >> 3; bj++) {
        memset(s->unsat + (size_t)bj * s->bnx + (clip->i0 >> 3), 0,
               (size_t)((clip->i1 >> 3) - (clip->i0 >> 3) + 1) * sizeof(uint16_t));
        memset(s->bbits + (size_t)bj * s->words, 0, s->words * sizeof(uint64_t));
        memset(s->bcount + (size_t)bj * s->us.nx, 0, s->us.nx);
    }
    memset(s->rbits + (size_t)clip->j0 * s->words, 0, (size_t)(clip->j1 - clip->j0 + 1) * s->words * sizeof(uint64_t));
}

/* Start the fine map from the coarse one on the clip's cells: each cell takes its block's coarse
 * value (valid over the whole block), and the unsaturated cells are counted per block (a cell is
 * saturated when its value reaches its highest point). Replaces sl_cullmap_clear for the fine map. */
static void seed_fine(cullmap_state *s, const sl_cullmap_clip *clip)
{
    const sl_urban_scene *u = &s->us;
    clear_fine_counts(s, clip);
    for (uint32_t j = clip->j0; j <= clip->j1; j++) {
        uint64_t *rb = s->rbits + (size_t)j * s->words, *bb = s->bbits + (size_t)(j >> 3) * s->words;
        int32_t a = clip->x0[j - clip->j0], b = clip->x1[j - clip->j0];
        if (a > b)
            continue;
        float *zrow = s->z + (size_t)j * u->nx;
        const float *trow = u->cell_top + (size_t)j * u->nx, *czrow = s->cz + (size_t)(j >> 3) * s->bnx;
        uint16_t *urow = s->unsat + (size_t)(j >> 3) * s->bnx;
        uint8_t *bc = s->bcount + (size_t)(j >> 3) * u->nx;
        const float *ctrow = s->ctop + (size_t)(j >> 3) * s->bnx;
        for (int32_t i = a; i <= b; i++) {
            float zc = czrow[i >> 3];
            if (zc >= ctrow[i >> 3]) { /* a block the coarse map hides whole: its fine values are never read */
                i |= 7;
                continue;
            }
            zrow[i] = zc;
            uint32_t un = zc < trow[i];
            urow[i >> 3] += (uint16_t)un;
            bc[i] += (uint8_t)un;
            rb[i >> 6] |= (uint64_t)un << (i & 63);
            bb[i >> 6] |= (uint64_t)un << (i & 63);
        }
    }
}

/* Rasterize the shadow of edge e (used in mode) with its chain neighbours as seam partners. */
static uint64_t draw_edge(cullmap_state *s, sl_cullmap_grid *map, const sl_urban_view *v, uint32_t e, int mode,
                          const sl_cullmap_clip *clip)
{
    const sl_urban_scene *u = &s->us;
    uint32_t before[SL_CULLMAP_MAX_SEAM], after[SL_CULLMAP_MAX_SEAM], nb = 0, na = 0;
    for (uint32_t c = e; nb < SL_CULLMAP_MAX_SEAM;) {
        c = sl_urban_chain_step(u, c, mode, -1, v, s->fp_excluded, s->frame, &s->modes);
        if (c == SL_NONE || c == e)
            break;
        before[nb++] = c;
    }
    for (uint32_t c = e; na < SL_CULLMAP_MAX_SEAM;) {
        c = sl_urban_chain_step(u, c, mode, +1, v, s->fp_excluded, s->frame, &s->modes);
        if (c == SL_NONE || c == e)
            break;
        after[na++] = c;
    }
    sl_shadow_edge win[2 * SL_CULLMAP_MAX_SEAM + 1];
    uint32_t n = 0;
    for (uint32_t k = nb; k > 0; k--)
        win[n++] = sl_urban_shadow_edge(u, before[k - 1], mode);
    uint32_t self = n;
    win[n++] = sl_urban_shadow_edge(u, e, mode);
    for (uint32_t k = 0; k < na; k++)
        win[n++] = sl_urban_shadow_edge(u, after[k], mode);
    return sl_cullmap_raster_wedge(map, v->eye, win, n, self, clip);
}

/* Is the shadow wedge of edge e narrower than two cells of the given size even at the far end of
 * the view (its angle's sine times the reach)? Its sides moved in by the sampling correction (by
 * at least half a cell each), it then holds few cells whole, only near that far end (none under
 * one cell), and its partial covers seldom close: measured on the generated cities, leaving such
 * wedges out changes the culling by under 1%, and they are most of the rasterization's cost (the
 * façades seen at grazing angles along a street, whose thin wedges follow the edges of the
 * visible corridor for its whole length). Leaving a shadow out only loses occlusion. */
static bool thin(const cullmap_state *s, const sl_urban_view *v, uint32_t e, double cell)
{
    const sl_urban_edge *ed = &s->us.edges[e];
    double ax = ed->ax - v->eye[0], ay = ed->ay - v->eye[1], bx = ed->bx - v->eye[0], by = ed->by - v->eye[1];
    return fabs(ax * by - ay * bx) * s->reach < 2.0 * cell * sqrt((ax * ax + ay * ay) * (bx * bx + by * by));
}

/* Gather, test and draw the occluders of one grid cell. */
static uint64_t draw_cell(cullmap_state *s, const sl_urban_view *v, uint32_t c, const sl_cullmap_clip *cclip)
{
    const sl_urban_scene *u = &s->us;
    uint64_t px = 0;
    const double r = s->cfg.radius, far = v->far;
    for (uint32_t k = u->cell_edge_start[c]; k < u->cell_edge_start[c + 1]; k++) {
        uint32_t e = u->cell_edges[k];
        if (s->edge_stamp[e] == s->frame)
            continue;
        s->edge_stamp[e] = s->frame;
        const sl_urban_edge *ed = &u->edges[e];
        int mode = sl_urban_edge_mode_cached(u, e, v, s->fp_excluded, s->frame, &s->modes);
        if (!mode)
            continue;
        double d = sl_urban_seg_dist(v, ed->ax, ed->ay, ed->bx, ed->by);
        if (d > r || d > far)
            continue;
        if (!v->full_az) { /* outside the azimuth range: its shadow misses the frustum */
            bool out = false;
            for (int q = 0; q < 2 && !out; q++) {
                const double *h = v->cone[q];
                out = h[0] * ed->ax + h[1] * ed->ay + h[2] < -1e-6 && h[0] * ed->bx + h[1] * ed->by + h[2] < -1e-6;
            }
            if (out)
                continue;
        }
        if (edge_hidden(s, e, true)) {
            s->edges_hidden++;
            continue;
        }
        s->edges_used++;
        if (!thin(s, v, e, s->cmap.cell))
            px += draw_edge(s, &s->cmap, v, e, mode, cclip);
        s->drawn[s->drawn_count++] = e | (mode < 0 ? 1u << 31 : 0);
    }
    return px;
}

/* Cell range of the plan box of the sector of the view's azimuth range within radius r. */
static void sector_box(const cullmap_state *s, const sl_urban_view *v, double r, int32_t *i0, int32_t *i1, int32_t *j0,
                       int32_t *j1)
{
    const sl_urban_scene *u = &s->us;
    double ex = v->eye[0], ey = v->eye[1];
    double bx0 = ex - r, bx1 = ex + r, by0 = ey - r, by1 = ey + r;
    if (!v->full_az) {
        double a0 = v->az0, a1 = v->az0 + v->az_span;
        bx0 = bx1 = ex;
        by0 = by1 = ey;
        double xs[2] = {ex + r * cos(a0), ex + r * cos(a1)}, ys[2] = {ey + r * sin(a0), ey + r * sin(a1)};
        for (int k = 0; k < 2; k++) {
            bx0 = sl_urban_min(bx0, xs[k]), bx1 = sl_urban_max(bx1, xs[k]);
            by0 = sl_urban_min(by0, ys[k]), by1 = sl_urban_max(by1, ys[k]);
        }
        /* the arc's extreme points on the axes it crosses */
        for (int q = 0; q < 8; q++) {
            double ang = q * (M_PI / 2);
            double d = fmod(ang - a0, SL_URBAN_TWO_PI);
            if (d < 0)
                d += SL_URBAN_TWO_PI;
            if (d <= v->az_span) {
                bx0 = sl_urban_min(bx0, ex + r * cos(ang)), bx1 = sl_urban_max(bx1, ex + r * cos(ang));
                by0 = sl_urban_min(by0, ey + r * sin(ang)), by1 = sl_urban_max(by1, ey + r * sin(ang));
            }
        }
    }
    double m = u->cell;
    *i0 = (int32_t)sl_urban_max(-1.0, sl_urban_min((double)u->nx, floor((bx0 - m - u->min_x) / u->cell)));
    *i1 = (int32_t)sl_urban_max(-1.0, sl_urban_min((double)u->nx, floor((bx1 + m - u->min_x) / u->cell)));
    *j0 = (int32_t)sl_urban_max(-1.0, sl_urban_min((double)u->ny, floor((by0 - m - u->min_y) / u->cell)));
    *j1 = (int32_t)sl_urban_max(-1.0, sl_urban_min((double)u->ny, floor((by1 + m - u->min_y) / u->cell)));
}

/* One frame; the visible objects are written to out (unsorted). */
static uint32_t cullmap_frame(cullmap_state *s, const sl_view *view, sl_urban_view *v, uint32_t *out,
                              sl_cull_stats *stats, double *t_select, double *t_traverse)
{
    sl_urban_scene *u = &s->us;
    if (++s->frame == 0) {
        memset(s->obj_stamp, 0, (size_t)(u->object_count ? u->object_count : 1) * sizeof(uint32_t));
        memset(s->edge_stamp, 0, (size_t)(u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
        memset(s->fp_excluded, 0, (size_t)(u->fp_count ? u->fp_count : 1) * sizeof(uint32_t));
        memset(s->part, 0, (size_t)(u->ncells ? u->ncells : 1) * sizeof(sl_cullmap_part));
        memset(s->modes.frame, 0, (size_t)(u->edge_count ? u->edge_count : 1) * sizeof(uint32_t));
        memset(s->cpart, 0, ((size_t)s->bnx * s->bny + (s->bnx * s->bny == 0)) * sizeof(sl_cullmap_part));
        s->frame = 1;
    }
    s->map.stamp = s->cmap.stamp = s->frame;
    s->edges_used = s->edges_hidden = 0;
    s->drawn_count = 0;
    sl_urban_view_make(u, view, v);
    double t0 = sl_now();
    /* stale values outside the spans are never read: in_spans guards every read */
    s->have_spans = sl_urban_frustum_spans(u, v, &s->j0, &s->j1, s->x0, s->x1);
    if (!s->have_spans) {
        uint32_t n = 0;
        sl_urban_add_outside(u, v, s->obj_stamp, s->frame, out, &n);
        *t_select = *t_traverse = 0;
        return n;
    }
    if (!v->perspective) {
        uint64_t cells = 0, tested = 0;
        uint32_t n = sl_urban_frustum_only(u, v, s->obj_stamp, s->frame, s->x0, s->x1, out, &cells, &tested);
        sl_urban_add_outside(u, v, s->obj_stamp, s->frame, out, &n);
        stats->nodes_visited = cells;
        stats->objects_tested = tested;
        *t_select = 0;
        *t_traverse = sl_cull_ms(t0, sl_now());
        /* the map shows nothing hidden */
        sl_cullmap_clip clip = {s->j0, s->j1, 0, u->nx - 1, s->x0, s->x1};
        clear_fine_counts(s, &clip);
        sl_cullmap_clear(&s->map, &clip);
        return n;
    }
    int32_t ci0 = INT32_MAX, ci1 = -1;
    for (uint32_t j = s->j0; j <= s->j1; j++)
        if (s->x0[j - s->j0] <= s->x1[j - s->j0]) {
            ci0 = SL_MIN(ci0, s->x0[j - s->j0]);
            ci1 = SL_MAX(ci1, s->x1[j - s->j0]);
        }
    sl_cullmap_clip clip = {s->j0, s->j1, (uint32_t)ci0, (uint32_t)ci1, s->x0, s->x1};
    /* the coarse spans: the blocks of the fine ones */
    s->cj0 = s->j0 >> 3;
    s->cj1 = s->j1 >> 3;
    for (uint32_t cj = s->cj0; cj <= s->cj1; cj++) {
        int32_t a = INT32_MAX, b = -1;
        for (uint32_t j = SL_MAX(cj << 3, s->j0); j <= SL_MIN((cj << 3) + 7, s->j1); j++)
            if (s->x0[j - s->j0] <= s->x1[j - s->j0]) {
                a = SL_MIN(a, s->x0[j - s->j0] >> 3);
                b = SL_MAX(b, s->x1[j - s->j0] >> 3);
            }
        s->cx0[cj - s->cj0] = a == INT32_MAX ? 1 : a;
        s->cx1[cj - s->cj0] = a == INT32_MAX ? 0 : b;
    }
    sl_cullmap_clip cclip = {s->cj0, s->cj1, (uint32_t)ci0 >> 3, (uint32_t)ci1 >> 3, s->cx0, s->cx1};
    for (uint32_t bj = s->cj0 >> 3; bj <= s->cj1 >> 3; bj++)
        memset(s->cunsat + (size_t)bj * s->cbnx + (cclip.i0 >> 3), 0,
               (size_t)((cclip.i1 >> 3) - (cclip.i0 >> 3) + 1) * sizeof(uint16_t));
    for (uint32_t cj = s->cj0; cj <= s->cj1; cj++)
        memset(s->crbits + (size_t)cj * s->cwords, 0, s->cwords * sizeof(uint64_t));
    for (uint32_t bj = s->cj0 >> 3; bj <= s->cj1 >> 3; bj++) {
        memset(s->cbbits + (size_t)bj * s->cwords, 0, s->cwords * sizeof(uint64_t));
        memset(s->cbcount + (size_t)bj * s->bnx, 0, s->bnx);
    }
    sl_cullmap_clear(&s->cmap, &cclip);
    sl_urban_exclude(u, v, s->fp_excluded, s->frame);
    double rx = sl_urban_max(fabs(u->min_x + ci0 * u->cell - v->eye[0]),
                             fabs(u->min_x + (ci1 + 1.0) * u->cell - v->eye[0]));
    double ry = sl_urban_max(fabs(u->min_y + s->j0 * u->cell - v->eye[1]),
                             fabs(u->min_y + (s->j1 + 1.0) * u->cell - v->eye[1]));
    s->reach = sqrt(rx * rx + ry * ry);

    /* occluders: square rings around the eye's cell, nearest first, within the sector's box */
    uint64_t px = 0;
    int32_t bi0, bi1, bj0, bj1;
    sector_box(s, v, s->cfg.radius, &bi0, &bi1, &bj0, &bj1);
    int32_t ex = (int32_t)sl_urban_max(-1.0, sl_urban_min((double)u->nx, floor((v->eye[0] - u->min_x) / u->cell)));
    int32_t ey = (int32_t)sl_urban_max(-1.0, sl_urban_min((double)u->ny, floor((v->eye[1] - u->min_y) / u->cell)));
    int32_t rmax = SL_MAX(SL_MAX(abs(bi0 - ex), abs(bi1 - ex)), SL_MAX(abs(bj0 - ey), abs(bj1 - ey)));
    bi0 = SL_MAX(bi0, 0), bj0 = SL_MAX(bj0, 0);
    bi1 = SL_MIN(bi1, (int32_t)u->nx - 1), bj1 = SL_MIN(bj1, (int32_t)u->ny - 1);
    const double hw = 0.5 * u->cell + u->margin;
    /* per row of the box, the columns that may be inside the azimuth range (a cell wider on each
     * side than the exact test, which each cell still gets) */
    for (int32_t j = bj0; j <= bj1; j++) {
        double lo = bi0, hi = bi1;
        if (!v->full_az) {
            double cy = u->min_y + (j + 0.5) * u->cell;
            for (int q = 0; q < 2; q++) {
                const double *h = v->cone[q];
                /* h0 * cx + rest >= 0 with cx = min_x + (i + 0.5) cell */
                double rest = h[1] * cy + h[2] + hw * (fabs(h[0]) + fabs(h[1])) + 1e-6;
                if (h[0] > 0)
                    lo = sl_urban_max(lo, (-rest / h[0] - u->min_x) / u->cell - 1.5);
                else if (h[0] < 0)
                    hi = sl_urban_min(hi, (-rest / h[0] - u->min_x) / u->cell + 0.5);
                else if (rest < 0)
                    hi = -1;
            }
        }
        s->ring_i0[j - bj0] = lo > hi ? 1 : (int32_t)floor(lo);
        s->ring_i1[j - bj0] = lo > hi ? 0 : (int32_t)ceil(hi);
    }
    for (int32_t r = 0; r <= rmax && bi0 <= bi1 && bj0 <= bj1; r++) {
        /* the ring's rows, each with its cells in the box and the azimuth range */
        for (int32_t j = SL_MAX(ey - r, bj0); j <= SL_MIN(ey + r, bj1); j++) {
            bool edge_row = j == ey - r || j == ey + r;
            int32_t step = edge_row ? 1 : 2 * r;
            int32_t ia = SL_MAX(ex - r, s->ring_i0[j - bj0]), ib = SL_MIN(ex + r, s->ring_i1[j - bj0]);
            for (int32_t i = edge_row ? ia : ex - r; i <= ib; i += step ? step : 1) {
                if (i < ia)
                    continue;
                uint32_t c = (uint32_t)j * u->nx + (uint32_t)i;
                if (u->cell_edge_start[c] == u->cell_edge_start[c + 1])
                    continue;
                if (!v->full_az) {
                    double cx = u->min_x + (i + 0.5) * u->cell, cy = u->min_y + (j + 0.5) * u->cell;
                    bool outside = false;
                    for (int q = 0; q < 2 && !outside; q++) {
                        const double *h = v->cone[q];
                        outside = h[0] * cx + h[1] * cy + h[2] < -hw * (fabs(h[0]) + fabs(h[1])) - 1e-6;
                    }
                    if (outside)
                        continue;
                }
                px += draw_cell(s, v, c, &cclip);
            }
        }
    }
    /* the fine pass, once the coarse map is complete: the fine map starts from the coarse values
     * (so its cells already hidden count as saturated), the blocks the coarse map hides whole are
     * skipped (the map's block_z), and so is an edge the map already hides */
    seed_fine(s, &clip);
    for (uint32_t k = 0; k < s->drawn_count; k++) {
        uint32_t e = s->drawn[k] & 0x7FFFFFFFu;
        if (k > 0 && edge_hidden(s, e, false))
            continue;
        if (!thin(s, v, e, s->map.cell))
            px += draw_edge(s, &s->map, v, e, (s->drawn[k] >> 31) ? -1 : 1, &clip);
    }
    double t1 = sl_now();
    *t_select = sl_cull_ms(t0, t1);

    /* traversal: the two-level test over the cells of the frustum (blocks the coarse map hides
     * whole are skipped) */
    const struct sl_grid_t *g = u->grid;
    uint32_t n = 0;
    uint64_t cells = 0, tested = 0;
    for (uint32_t j = s->j0; j <= s->j1; j++) {
        int32_t a = s->x0[j - s->j0], b = s->x1[j - s->j0];
        const float *czrow = s->cz + (size_t)(j >> 3) * s->bnx, *ctrow = s->ctop + (size_t)(j >> 3) * s->bnx;
        for (int32_t i = a; i <= b; i++) {
            uint32_t bi = (uint32_t)i >> 3;
            if (czrow[bi] >= ctrow[bi]) { /* the whole block is hidden */
                i = (int32_t)((bi + 1) << 3) - 1;
                continue;
            }
            uint32_t c = j * u->nx + (uint32_t)i;
            cells++;
            float zc = s->z[c] > czrow[bi] ? s->z[c] : czrow[bi];
            if (!(g->max_z[c] > zc))
                continue;
            const uint32_t *ids = g->ids + g->start[c];
            for (uint32_t k = 0; k < g->count[c]; k++) {
                uint32_t o = ids[k];
                if (s->obj_stamp[o] == s->frame || !(u->boxes[o].max.z > zc))
                    continue;
                s->obj_stamp[o] = s->frame;
                tested++;
                if (sl_urban_box_in_frustum(v, &u->boxes[o]))
                    out[n++] = o;
            }
        }
    }
    sl_urban_add_outside(u, v, s->obj_stamp, s->frame, out, &n);
    *t_traverse = sl_cull_ms(t1, sl_now());
    stats->nodes_visited = cells;
    stats->objects_tested = tested;
    stats->occlusion_tests = cells + s->edges_used + s->edges_hidden;
    stats->pixels_rasterized = px;
    stats->pixel_queries = cells;
    stats->queries = s->edges_hidden;
    return n;
}

static sl_status cullmap_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                              sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    (void)err;
    cullmap_state *s = state;
    sl_urban_view v;
    double ts, tt;
    uint32_t n = cullmap_frame(s, view, &v, out, stats, &ts, &tt);
    double t0 = sl_now();
    sl_cull_sort_ids(out, n, s->sort_scratch);
    sl_cull_phase(stats, "shadows", ts);
    sl_cull_phase(stats, "traverse", tt);
    sl_cull_phase(stats, "sort", sl_cull_ms(t0, sl_now()));
    *count = n;
    return SL_OK;
}

const sl_cull_method sl_cull_method_cullmap = {
    .name = "cullmap",
    .suits = "cities with building footprints (2.5D), eyes near the ground",
    .summary = "2.5D occluder shadows rasterized top-down into a cull map, then a scan of the frustum's grid cells "
               "(Wonka 2001 ch. 4, occluder shadows)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(cullmap_config),
    .configure = cullmap_configure,
    .create = cullmap_create,
    .cull = cullmap_cull,
    .scene_changed = cullmap_scene_changed,
    .destroy = cullmap_destroy,
    .applicable = sl_urban_applicable,
};

/* ===== the cull map as an image ==================================================================== */

static void put(uint8_t *img, uint32_t w, uint32_t h, int32_t x, int32_t y, uint32_t rgb)
{
    if (x < 0 || y < 0 || (uint32_t)x >= w || (uint32_t)y >= h)
        return;
    uint8_t *p = img + 3 * ((size_t)y * w + (uint32_t)x);
    p[0] = (uint8_t)(rgb >> 16), p[1] = (uint8_t)(rgb >> 8), p[2] = (uint8_t)rgb;
}

/* A line from world (ax, ay) to (bx, by); image y grows downward from the grid's top (max y). */
static void line(uint8_t *img, uint32_t w, uint32_t h, const sl_urban_scene *u, double scale, double ax, double ay,
                 double bx, double by, uint32_t rgb)
{
    double x0 = (ax - u->min_x) * scale, y0 = h - (ay - u->min_y) * scale;
    double x1 = (bx - u->min_x) * scale, y1 = h - (by - u->min_y) * scale;
    int steps = (int)sl_urban_min(1e5, ceil(sl_urban_max(fabs(x1 - x0), fabs(y1 - y0))) + 1);
    for (int k = 0; k <= steps; k++) {
        double t = (double)k / steps;
        put(img, w, h, (int32_t)floor(x0 + t * (x1 - x0)), (int32_t)floor(y0 + t * (y1 - y0)), rgb);
    }
}

sl_status sl_cullmap_render_png(sl_scene scene, const sl_camera *cam, const char *options, const char *path,
                                sl_error *err)
{
    if (!scene || !cam || !path)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_cullmap_render_png: scene, camera and path are required");
    sl_view view;
    sl_status st = sl_view_from_camera(cam, &view, err);
    if (st != SL_OK)
        return st;
    return sl_cullmap_render_png_view(scene, &view, options, path, err);
}

sl_status sl_cullmap_render_png_view(sl_scene scene, const sl_view *view_in, const char *options, const char *path,
                                     sl_error *err)
{
    if (!scene || !view_in || !path)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_cullmap_render_png: scene, view and path are required");
    sl_status st = sl_view_validate(view_in, err);
    if (st != SL_OK)
        return st;
    /* an infinite far plane: bounded by the scene's box, as sl_culler_cull_view does */
    sl_view bounded;
    const sl_view *vp;
    if ((st = sl_scene_finite_view(scene, view_in, &bounded, &vp, err)) != SL_OK)
        return st;
    const sl_view view = *vp;
    const sl_allocator *a = sl_default_allocator();
    sl_opts *opts = sl_alloc(a, sizeof *opts);
    if (!opts)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cullmap: out of memory");
    cullmap_config cfg;
    memset(&cfg, 0, sizeof cfg);
    sl_cull_guarantee g = SL_CONSERVATIVE;
    st = sl_opts_parse(opts, "cullmap", options, err);
    if (st == SL_OK)
        st = cullmap_configure(opts, &cfg, &g, err);
    if (st == SL_OK)
        st = sl_opts_check_unused(opts, err);
    sl_free(a, opts, sizeof *opts);
    if (st != SL_OK)
        return st;
    void *state = NULL;
    if ((st = cullmap_create(scene, &cfg, a, &state, err)) != SL_OK)
        return st;
    cullmap_state *s = state;
    const sl_urban_scene *u = &s->us;
    uint32_t no = u->object_count ? u->object_count : 1;
    uint32_t *ids = sl_alloc(a, (size_t)no * sizeof(uint32_t));
    uint8_t *visible = sl_calloc(a, no, 1);
    /* a few pixels per cell, about a thousand pixels across */
    uint32_t scale_px = SL_MAX(1u, 1024u / SL_MAX(u->nx, u->ny));
    uint32_t w = u->nx * scale_px, h = u->ny * scale_px;
    uint8_t *img = (size_t)w * h <= (1u << 26) ? sl_alloc(a, (size_t)w * h * 3) : NULL;
    if (!ids || !visible || !img) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "cullmap: out of memory for a %ux%u image", w, h);
        goto done;
    }
    sl_cull_stats stats;
    memset(&stats, 0, sizeof stats);
    sl_urban_view v;
    double ts, tt;
    uint32_t n = cullmap_frame(s, &view, &v, ids, &stats, &ts, &tt);
    for (uint32_t k = 0; k < n; k++)
        visible[ids[k]] = 1;
    /* the highest shadow value in view, for the colour ramp */
    float zmax = 1.0f;
    for (uint32_t c = 0; c < u->ncells; c++)
        if (s->have_spans && in_spans(s, c) && isfinite(cell_value(s, c, false)))
            zmax = sl_urban_maxf(zmax, cell_value(s, c, false));
    const struct sl_grid_t *gr = u->grid;
    for (uint32_t j = 0; j < u->ny; j++)
        for (uint32_t i = 0; i < u->nx; i++) {
            uint32_t c = j * u->nx + i, rgb;
            float top = gr->max_z[c];
            uint32_t grey = top == -INFINITY ? 24 : (uint32_t)SL_CLAMP(40 + 4 * top, 40, 110);
            if (!s->have_spans || !in_spans(s, c))
                rgb = grey * 0x010101u; /* outside the frustum: the city's heights in grey */
            else if (!(cell_value(s, c, false) > -INFINITY))
                rgb = 0xF0F0E0u; /* in view, nothing hidden */
            else
                rgb = sl_ramp_color(SL_CLAMP(cell_value(s, c, false) / zmax, 0.0f, 1.0f)); /* the shadow's height */
            for (uint32_t dy = 0; dy < scale_px; dy++)
                for (uint32_t dx = 0; dx < scale_px; dx++)
                    put(img, w, h, (int32_t)(i * scale_px + dx), (int32_t)(h - 1 - (j * scale_px + dy)), rgb);
        }
    const double sc = scale_px / u->cell;
    for (uint32_t e = 0; e < u->edge_count; e++) {
        const sl_urban_edge *ed = &u->edges[e];
        uint32_t obj = u->fps[ed->fp].object;
        uint32_t rgb = obj < u->object_count && visible[obj] ? 0x10C040u : 0x202020u;
        line(img, w, h, u, sc, ed->ax, ed->ay, ed->bx, ed->by, rgb);
    }
    /* the frustum's plan and the eye */
    for (int k = 0; k < v.npoly; k++) {
        const double *p = v.poly[k], *q = v.poly[(k + 1) % v.npoly];
        line(img, w, h, u, sc, p[0], p[1], q[0], q[1], 0x3060FFu);
    }
    int32_t ex = (int32_t)floor((v.eye[0] - u->min_x) * sc), ey = (int32_t)floor(h - (v.eye[1] - u->min_y) * sc);
    for (int32_t dy = -2; dy <= 2; dy++)
        for (int32_t dx = -2; dx <= 2; dx++)
            put(img, w, h, ex + dx, ey + dy, 0xFF2020u);
    st = sl_png_write(path, w, h, 3, img, 0, err);
done:
    sl_free(a, img, (size_t)w * h * 3);
    sl_free(a, visible, no);
    sl_free(a, ids, (size_t)no * sizeof(uint32_t));
    cullmap_destroy(s);
    return st;
}

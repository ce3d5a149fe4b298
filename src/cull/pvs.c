/* pvs: precomputed from-region visibility at run time — find the view cell holding the eye, then
 * frustum-cull that cell's baked visible set (P. Wonka, PhD thesis, TU Wien 2001, section 5.2.4
 * and the walkthrough of section 5.7: "visible objects of the current view cell ... view-frustum
 * culled"). The set comes from a .slpvs file (include/sightline/pvs.h, `sightline pvs build`).
 *
 * Conservative when the file was baked by a conservative method for this scene: every object
 * visible from anywhere in the cell is in the set, and the frustum test only drops boxes wholly
 * outside the frustum. Two cases fall back to plain view-frustum culling of every object, so the
 * guarantee holds everywhere: an eye in no cell (inside a building, above the eye range, off the
 * streets), and dynamic objects (cars), whose baked positions mean nothing once they move
 * (option dynamic=frustum). With motion regions in the file (format 1.2, docs/motion.md), a
 * dynamic object in the frustum is dropped when a node of the region hierarchy holding its current
 * box is hidden from every cell the near-plane region meets (dynamic=regions; dynamic=auto, the
 * default, takes regions when the file has them and frustum otherwise). An eye outside the domain (solid or void space of a map,
 * docs/oracle.md) never reaches this method: the culler interface (culler.c) gives it the frustum
 * set of vfc, flagged in sl_cull_stats.out_of_domain.
 *
 * Near-plane holes: an eye a few cm from a wall sees, through the near plane's cut, what lies behind
 * it, which its own cell need not see. The candidates are the union of the sets of every cell the
 * box of the near-plane region (eye to near plane) meets, or every object when that box leaves the
 * cells (solid or void leaves, buildings, outside the eye range): docs/pvs.md, "Near-plane holes".
 *
 * Steady state allocates nothing: the decoded set of the current cell is kept, and re-decoded only
 * when the cells met change (one zstd block per cell, cached by the PVS handle). */
#include "culler_internal.h"

#include "sightline/accel.h"
#include "sightline/pvs.h"
#include "scene/scene_internal.h"

#include <math.h>

#define PATH_MAX_CHARS SL_OPTS_MAX_CHARS

typedef struct pvs_config {
    char file[PATH_MAX_CHARS + 1];
    uint32_t dynamic;           /* 0: frustum, 1: pvs, 2: regions, 3: auto (regions when the file has them) */
    bool aggressive;            /* accept a file baked by an aggressive method */
} pvs_config;

typedef struct pvs_state {
    sl_allocator alloc;
    sl_scene scene;
    pvs_config cfg;
    sl_pvs pvs;
    sl_viewcells cells;
    uint32_t object_count;
    uint32_t cell;              /* cell whose set is in `set`, or SL_NONE */
    uint32_t *set;              /* object_count entries */
    uint32_t set_count;
    uint32_t *dyn;              /* ascending ids of dynamic objects */
    uint32_t dyn_count;
    uint32_t *scratch;          /* object_count entries */
    uint32_t *tmp;              /* object_count entries */
    uint32_t cell_count;
    uint32_t *near_cells;       /* cell_count entries: the cells the near-plane region meets */
    uint32_t *set_cells;        /* cell_count entries: the cells whose union is in `set` */
    uint32_t set_cell_count;    /* 0: `set` holds nothing */
    uint8_t *mark;              /* object_count entries, zero between calls */
    bool regions;               /* dynamic objects by the motion regions */
    uint8_t *rrow;              /* the OR of the region rows of set_cells (made with the union) */
    size_t rrow_size;
} pvs_state;

static const char g_help[] =
    "file=PATH (required): the .slpvs baked for this scene by `sightline pvs build` (no commas or spaces)\n"
    "dynamic=auto|frustum|regions|pvs (default auto): dynamic objects (cars) by frustum only, by frustum and the file's "
    "motion regions (auto: when the file has them, else frustum), or from the baked set too (aggressive)\n"
    "aggressive=BOOL (default false): accept a file baked by an aggressive method (gvs); the culler is then aggressive\n";

static sl_status pvs_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    pvs_config *c = config;
    const char *file;
    static const char *const dyn_names[] = {"frustum", "pvs", "regions", "auto"};
    sl_status st = sl_opts_string(o, "file", &file, err);
    if (st == SL_OK)
        st = sl_opts_enum(o, "dynamic", dyn_names, 4, 3, &c->dynamic, err);
    if (st == SL_OK)
        st = sl_opts_bool(o, "aggressive", false, &c->aggressive, err);
    if (st != SL_OK)
        return st;
    if (!file) {
        /* unknown keys are the more useful message when there are some */
        if ((st = sl_opts_check_unused(o, err)) != SL_OK)
            return st;
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "pvs: option file=PATH is required (bake a PVS with `sightline pvs build SCENE -o FILE.slpvs`)");
    }
    if (strlen(file) > PATH_MAX_CHARS)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pvs: file name is too long");
    snprintf(c->file, sizeof c->file, "%s", file);
    /* baked sets of moving objects go stale: trusting them gives up the guarantee */
    if (c->dynamic == 1 || c->aggressive)
        *g = SL_AGGRESSIVE;
    return SL_OK;
}

static void pvs_destroy(void *state)
{
    pvs_state *s = state;
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    size_t n = (size_t)s->object_count + 1;
    sl_pvs_destroy(s->pvs);
    sl_free(a, s->set, n * sizeof(uint32_t));
    sl_free(a, s->dyn, n * sizeof(uint32_t));
    sl_free(a, s->scratch, n * sizeof(uint32_t));
    sl_free(a, s->tmp, n * sizeof(uint32_t));
    size_t cn = (size_t)s->cell_count + 1;
    sl_free(a, s->near_cells, cn * sizeof(uint32_t));
    sl_free(a, s->set_cells, cn * sizeof(uint32_t));
    sl_free(a, s->mark, n);
    sl_free(a, s->rrow, s->rrow_size);
    sl_free(a, s, sizeof *s);
}

static sl_status pvs_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state, sl_error *err)
{
    pvs_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory");
    s->alloc = *alloc;
    s->scene = scene;
    s->cfg = *(const pvs_config *)config;
    s->object_count = sl_scene_object_count(scene);
    s->cell = SL_NONE;
    sl_status st = sl_pvs_load(s->cfg.file, alloc, &s->pvs, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "pvs");
        pvs_destroy(s);
        return st;
    }
    if ((st = sl_pvs_check_scene(s->pvs, scene, err)) != SL_OK) {
        sl_error_prefix(err, "pvs");
        pvs_destroy(s);
        return st;
    }
    /* the culler's guarantee was fixed by its options: a file from an aggressive bake must be
     * asked for explicitly */
    const char *g = sl_pvs_meta(s->pvs, "guarantee");
    if (!s->cfg.aggressive && (!g || strcmp(g, "conservative") != 0)) {
        const char *m = sl_pvs_meta(s->pvs, "method");
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                     "pvs: %s was baked by %s method %s: pass aggressive=true to use it (the culler is then aggressive)",
                     s->cfg.file, g ? "the aggressive" : "an unknown", m ? m : "?");
        pvs_destroy(s);
        return st;
    }
    s->cells = sl_pvs_cells(s->pvs);
    const uint32_t nreg = sl_pvs_region_count(s->pvs);
    if (s->cfg.dynamic == 2 && nreg == 0) {
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                     "pvs: dynamic=regions, but %s has no motion regions (bake it from a scene whose dynamic objects "
                     "have motion records, without --no-regions; or use dynamic=frustum)",
                     s->cfg.file);
        pvs_destroy(s);
        return st;
    }
    if (s->cfg.dynamic == 3)
        s->cfg.dynamic = nreg ? 2 : 0;
    s->regions = s->cfg.dynamic == 2;
    if (s->regions) {
        s->rrow_size = ((size_t)nreg + 7) / 8;
        if (!(s->rrow = sl_calloc(alloc, s->rrow_size, 1))) {
            pvs_destroy(s);
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory");
        }
    }
    size_t n = (size_t)s->object_count + 1;
    s->set = sl_alloc(alloc, n * sizeof(uint32_t));
    s->dyn = sl_alloc(alloc, n * sizeof(uint32_t));
    s->scratch = sl_alloc(alloc, n * sizeof(uint32_t));
    s->tmp = sl_alloc(alloc, n * sizeof(uint32_t));
    s->cell_count = sl_viewcells_count(s->cells);
    size_t cn = (size_t)s->cell_count + 1;
    s->near_cells = sl_alloc(alloc, cn * sizeof(uint32_t));
    s->set_cells = sl_alloc(alloc, cn * sizeof(uint32_t));
    s->mark = sl_calloc(alloc, n, 1);
    if (!s->set || !s->dyn || !s->scratch || !s->tmp || !s->near_cells || !s->set_cells || !s->mark) {
        pvs_destroy(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory for %u objects", s->object_count);
    }
    const sl_object_rec *objs = sl_scene_objects(scene);
    for (uint32_t i = 0; i < s->object_count; i++)
        if (s->cfg.dynamic != 1 && (objs[i].flags & SL_OBJECT_DYNAMIC))
            s->dyn[s->dyn_count++] = i;
    *state = s;
    return SL_OK;
}

/* Frustum-test candidates (ascending) into out (ascending); skip dynamic ones when they are
 * handled separately. Returns the count. */
static uint32_t frustum_filter(const pvs_state *s, const sl_frustum *fr, const uint32_t *cand, uint32_t n, uint32_t *out,
                               bool skip_dynamic, uint64_t *tested)
{
    const sl_aabb *bounds = sl_scene_object_bounds_array(s->scene);
    const sl_object_rec *objs = sl_scene_objects(s->scene);
    /* the shared classifier with the plane slack of every culler (core/margins.h; this used the
     * public sl_frustum_test_aabb, which has none, so a box touching a plane within rounding could
     * be dropped) */
    float slack[6];
    sl_frustum_slacks(fr->planes, slack);
    uint32_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t id = cand[i];
        if (skip_dynamic && (objs[id].flags & SL_OBJECT_DYNAMIC))
            continue;
        (*tested)++;
        if (!sl_aabb_is_empty(&bounds[id]) && sl_frustum_classify_box(fr->planes, slack, &bounds[id], 0x3fu, false, NULL) >= 0)
            out[k++] = id;
    }
    return k;
}

/* The box of the near-plane region: the part of the frustum between the eye (the eye plane for
 * an orthographic camera) and the near plane, i.e. the near rectangle and its copy moved back by
 * the near distance; widened by a margin for float rounding. */
static sl_aabb near_box(const sl_view *view, const sl_frustum *fr)
{
    sl_vec3 f = view->forward;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double nearv = view->near_plane;
    for (int k = 0; k < 4; k++) {
        const sl_vec3 *c = &fr->corners[k];
        double p[2][3] = {{c->x, c->y, c->z}, {c->x - nearv * f.x, c->y - nearv * f.y, c->z - nearv * f.z}};
        for (int j = 0; j < 2; j++)
            for (int a = 0; a < 3; a++) {
                lo[a] = fmin(lo[a], p[j][a]);
                hi[a] = fmax(hi[a], p[j][a]);
            }
    }
    double e[3] = {view->eye.x, view->eye.y, view->eye.z};
    sl_aabb b;
    float *bl = &b.min.x, *bh = &b.max.x;
    for (int a = 0; a < 3; a++) {
        if (view->projection == SL_PERSPECTIVE) {
            lo[a] = fmin(lo[a], e[a]);
            hi[a] = fmax(hi[a], e[a]);
        }
        double m = 1e-4 + 1e-6 * (fabs(lo[a]) + fabs(hi[a]));
        bl[a] = (float)(lo[a] - m);
        bh[a] = (float)(hi[a] + m);
    }
    return b;
}

/* Make `set` the union of the sets of cells[0..n) (ascending); nothing to do when it already is. */
static sl_status load_union(pvs_state *s, const uint32_t *cells, uint32_t n, sl_error *err)
{
    if (n == s->set_cell_count && memcmp(cells, s->set_cells, n * sizeof *cells) == 0)
        return SL_OK;
    s->set_cell_count = 0;
    sl_status st;
    if (n == 1) {
        if ((st = sl_pvs_cell_set(s->pvs, cells[0], s->set, s->object_count, &s->set_count, err)) != SL_OK)
            return st;
    } else {
        /* mark every member, then collect them in id order and clear the marks */
        uint32_t total = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t k;
            if ((st = sl_pvs_cell_set(s->pvs, cells[i], s->tmp, s->object_count, &k, err)) != SL_OK) {
                memset(s->mark, 0, s->object_count);
                return st;
            }
            for (uint32_t j = 0; j < k; j++) {
                total += !s->mark[s->tmp[j]];
                s->mark[s->tmp[j]] = 1;
            }
        }
        uint32_t m = 0;
        for (uint32_t id = 0; id < s->object_count && m < total; id++)
            if (s->mark[id]) {
                s->mark[id] = 0;
                s->set[m++] = id;
            }
        s->set_count = m;
    }
    memcpy(s->set_cells, cells, n * sizeof *cells);
    s->set_cell_count = n;
    if (s->regions)
        for (uint32_t c = 0; c < n; c++) {
            const uint8_t *row = sl_pvs_region_row(s->pvs, cells[c]);
            if (c == 0)
                memcpy(s->rrow, row, s->rrow_size);
            else
                for (size_t b = 0; b < s->rrow_size; b++)
                    s->rrow[b] |= row[b];
        }
    return SL_OK;
}

static sl_status pvs_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    pvs_state *s = state;
    double t0 = sl_now();
    sl_frustum fr = view->frustum;
    uint32_t cell = sl_viewcells_locate(s->cells, s->scene, view->eye);
    stats->nodes_visited = 1;
    /* What the near plane cuts open is seen from the near-plane region, not from the eye alone:
     * take the union of the sets of every cell that region's box meets; where the box reaches
     * beyond the cells (solid or void leaves, buildings, outside the eye range), no baked set holds
     * what a sight line from there shows, and every object is a candidate (docs/pvs.md). */
    bool all = cell == SL_NONE;
    if (!all) {
        sl_aabb nb = near_box(view, &fr);
        bool covered;
        uint32_t nc = sl_viewcells_overlap(s->cells, s->scene, &nb, s->near_cells, s->cell_count, &covered);
        if (!covered || nc == 0) {
            all = true;
        } else {
            sl_status st = load_union(s, s->near_cells, nc, err);
            if (st != SL_OK)
                return st;
        }
    }
    s->cell = all ? SL_NONE : cell;
    double t1 = sl_now();
    bool skip_dyn = s->cfg.dynamic != 1;
    uint32_t n;
    if (all) {
        /* outside every cell: every object is a candidate (ids are ascending by construction) */
        for (uint32_t i = 0; i < s->object_count; i++)
            s->scratch[i] = i;
        n = frustum_filter(s, &fr, s->scratch, s->object_count, s->tmp, skip_dyn, &stats->objects_tested);
    } else {
        n = frustum_filter(s, &fr, s->set, s->set_count, s->tmp, skip_dyn, &stats->objects_tested);
    }
    uint32_t nd = skip_dyn ? frustum_filter(s, &fr, s->dyn, s->dyn_count, s->scratch, false, &stats->objects_tested) : 0;
    if (s->regions && !all) {
        /* the dynamic objects in the frustum whose box a hidden node holds, from every cell met
         * (their rows' union is made with the set's, only when the cells change: load_union) */
        const uint32_t nc = s->set_cell_count;
        const sl_aabb *bounds = sl_scene_object_bounds_array(s->scene);
        uint32_t kept = 0;
        for (uint32_t q = 0; q < nd; q++)
            if (nc == 0 || sl_pvs_region_box_visible(s->pvs, s->rrow, &bounds[s->scratch[q]]))
                s->scratch[kept++] = s->scratch[q];
        nd = kept;
    }
    /* merge the two ascending lists (disjoint: the set's dynamic objects were skipped) */
    uint32_t i = 0, j = 0, k = 0;
    while (i < n || j < nd) {
        if (j >= nd || (i < n && s->tmp[i] < s->scratch[j]))
            out[k++] = s->tmp[i++];
        else
            out[k++] = s->scratch[j++];
    }
    *count = k;
    sl_cull_phase(stats, "lookup", sl_cull_ms(t0, t1));
    sl_cull_phase(stats, "frustum", sl_cull_ms(t1, sl_now()));
    return SL_OK;
}

const sl_cull_method sl_cull_method_pvs = {
    .name = "pvs",
    .suits = "any scene with a PVS baked for where the eye goes (sightline pvs build)",
    .summary = "precomputed visibility: the baked set of the eye's view cell, frustum-culled (Wonka 2001, ch. 5)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(pvs_config),
    .configure = pvs_configure,
    .create = pvs_create,
    .cull = pvs_cull,
    .scene_changed = NULL,
    .destroy = pvs_destroy,
};

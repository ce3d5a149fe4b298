/* Motion regions in the PVS bake (P. Wonka, PhD thesis, TU Wien 2001, section 8.5, after Durand
 * et al. 2000 and Sudarsky and Gotsman 1996: "build a bounding-volume hierarchy over the regions
 * where dynamic objects can move and test those volumes during preprocessing; at run time, draw a
 * dynamic object if its containing volume is in the current PVS").
 *
 * The leaves are the distinct regions of the scene's motion records (sl_object_motion.region).
 * The hierarchy is binary, split at the median of the leaves' centres along the longest axis of
 * those centres, and laid out breadth first, so a node's two children are consecutive and come
 * after it (the .slpvs rules, pvs.h). Each node's box is the union of its leaves' boxes.
 *
 * Per cell every node is tested against the static occluders with the probe of the adjustable
 * method (sl_adj_probe_boxes: its levels of eps-disks covering the cell, conservative for 2.5D
 * scenes), all in one pass: a node is marked when the probe cannot hide its box from the whole
 * cell and its parent is marked (a child of a hidden node lies in the parent's box, hidden from
 * the whole cell). Testing top down, a frontier at a time, gave the same marks but took 2.6 times
 * as long on the small city (105 s against 41 s for 14843 cells and 555 nodes): a pass of the
 * probe costs more than the boxes it could skip. The occluders are the footprints of the
 * objects that do not move (a footprint of a DYNAMIC object is left out: it may be elsewhere),
 * and only those the probe may use for the cell: a footprint above the cell's lowest eye hides
 * nothing, and a node reaching below a used footprint's base is tested through a larger
 * stand-in (method_adjustable.c, lower_boxes; base_levels.c).
 * Whatever method baked the sets, the marks are conservative: an unmarked node's box is hidden
 * from every point of the cell, so a dynamic object whose current box lies inside it is too.
 * A scene without footprints marks every node (the objects are then drawn as by frustum alone).
 *
 * Deterministic: the leaves are sorted, the split is a total order, and each cell's marks depend
 * on that cell only. */
#include "motion_regions.h"
#include "pvs_internal.h"

#include "scene/scene_internal.h"

#include <omp.h>
#include <stdlib.h>

static int box_cmp(const sl_aabb *a, const sl_aabb *b)
{
    const float *x = &a->min.x, *y = &b->min.x;
    for (int k = 0; k < 6; k++)
        if (x[k] != y[k])
            return x[k] < y[k] ? -1 : 1;
    return 0;
}

static int box_qcmp(const void *a, const void *b) { return box_cmp(a, b); }

typedef struct split_key {
    double c;                   /* centre on the split axis */
    uint32_t i;                 /* the leaf (ties: the sorted order) */
} split_key;

static int key_cmp(const void *a, const void *b)
{
    const split_key *x = a, *y = b;
    if (x->c != y->c)
        return x->c < y->c ? -1 : 1;
    return x->i < y->i ? -1 : x->i > y->i;
}

static double centre(const sl_aabb *b, int axis) { return 0.5 * ((double)(&b->min.x)[axis] + (&b->max.x)[axis]); }

/* The hierarchy over the distinct regions (none when no object has a record). */
static sl_status build_tree(sl_scene scene, const sl_allocator *a, sl_pvs_region **out, uint32_t *count,
                            sl_error *err)
{
    *out = NULL;
    *count = 0;
    const uint32_t no = sl_scene_object_count(scene);
    uint32_t nl = 0;
    sl_object_motion m;
    for (uint32_t o = 0; o < no; o++)
        nl += sl_scene_object_motion(scene, o, &m);
    if (nl == 0)
        return SL_OK;
    sl_aabb *leaf = sl_alloc(a, (size_t)nl * sizeof *leaf);
    if (!leaf)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "motion regions: out of memory for %u regions", nl);
    uint32_t k = 0;
    for (uint32_t o = 0; o < no && k < nl; o++) {
        if (sl_scene_object_motion(scene, o, &m))
            leaf[k++] = m.region;
    }
    qsort(leaf, nl, sizeof *leaf, box_qcmp);
    uint32_t nd = 0;
    for (uint32_t i = 0; i < nl; i++)
        if (nd == 0 || box_cmp(&leaf[i], &leaf[nd - 1]) != 0)
            leaf[nd++] = leaf[i];
    sl_status st = SL_OK;
    if (nd > (SL_PVS_MAX_REGIONS + 1) / 2) {
        st = sl_fail(err, SL_ERROR_LIMIT, "motion regions: %u distinct regions, at most %u", nd,
                     (SL_PVS_MAX_REGIONS + 1) / 2);
        sl_free(a, leaf, (size_t)nl * sizeof *leaf);
        return st;
    }
    const uint32_t nn = 2 * nd - 1;
    sl_pvs_region *n = sl_calloc(a, nn, sizeof *n);
    uint32_t(*range)[2] = sl_alloc(a, (size_t)nn * sizeof *range); /* per node: its leaves [lo, hi) */
    split_key *key = sl_alloc(a, (size_t)nd * sizeof *key);
    sl_aabb *tmp = sl_alloc(a, (size_t)nd * sizeof *tmp);
    if (!n || !range || !key || !tmp) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "motion regions: out of memory for %u nodes", nn);
        goto done;
    }
    uint32_t used = 1;
    range[0][0] = 0, range[0][1] = nd;
    n[0].parent = SL_NONE;
    for (uint32_t i = 0; i < used; i++) { /* breadth first: `used` grows as nodes are split */
        const uint32_t lo = range[i][0], hi = range[i][1];
        sl_aabb b = leaf[lo];
        double cmin[3], cmax[3];
        for (int ax = 0; ax < 3; ax++)
            cmin[ax] = cmax[ax] = centre(&leaf[lo], ax);
        for (uint32_t j = lo + 1; j < hi; j++) {
            sl_aabb_merge(&b, &leaf[j]);
            for (int ax = 0; ax < 3; ax++) {
                cmin[ax] = fmin(cmin[ax], centre(&leaf[j], ax));
                cmax[ax] = fmax(cmax[ax], centre(&leaf[j], ax));
            }
        }
        n[i].box = b;
        if (hi - lo == 1)
            continue;
        int axis = 0;
        for (int ax = 1; ax < 3; ax++)
            if (cmax[ax] - cmin[ax] > cmax[axis] - cmin[axis])
                axis = ax;
        for (uint32_t j = lo; j < hi; j++)
            key[j - lo] = (split_key){centre(&leaf[j], axis), j};
        qsort(key, hi - lo, sizeof *key, key_cmp);
        for (uint32_t j = lo; j < hi; j++)
            tmp[j - lo] = leaf[key[j - lo].i];
        memcpy(leaf + lo, tmp, (size_t)(hi - lo) * sizeof *tmp);
        const uint32_t mid = lo + (hi - lo) / 2;
        n[i].first_child = used;
        n[i].child_count = 2;
        range[used][0] = lo, range[used][1] = mid;
        range[used + 1][0] = mid, range[used + 1][1] = hi;
        n[used].parent = n[used + 1].parent = i;
        used += 2;
    }
    if (used != nn)
        st = sl_fail(err, SL_ERROR_INTERNAL, "motion regions: %u nodes for %u leaves", used, nd);
done:
    sl_free(a, leaf, (size_t)nl * sizeof *leaf);
    sl_free(a, range, (size_t)nn * sizeof *range);
    sl_free(a, key, (size_t)nd * sizeof *key);
    sl_free(a, tmp, (size_t)nd * sizeof *tmp);
    if (st == SL_OK) {
        *out = n;
        *count = nn;
    } else {
        sl_free(a, n, (size_t)nn * sizeof *n);
    }
    return st;
}

/* One cell's row: every node tested at once, then marked when it and all its ancestors were
 * found visible (breadth-first order: a parent's mark is final before its children's). */
static sl_status mark_cell(void *w, uint32_t cell, const sl_pvs_region *n, uint32_t nn, uint32_t *front,
                           uint8_t *seen, uint8_t *row, sl_error *err)
{
    for (uint32_t i = 0; i < nn; i++)
        front[i] = i, seen[i] = 0;
    sl_status st = sl_adj_probe_boxes(w, cell, front, nn, seen, err);
    if (st != SL_OK)
        return st;
    for (uint32_t k = 0; k < nn; k++)
        if (seen[k] && (k == 0 || (row[n[k].parent >> 3] >> (n[k].parent & 7) & 1)))
            row[k >> 3] |= (uint8_t)(1u << (k & 7));
    return SL_OK;
}

/* Does old hold exactly these nodes? */
static bool same_tree(sl_pvs old, const sl_pvs_region *n, uint32_t count)
{
    if (!old || sl_pvs_region_count(old) != count)
        return false;
    const sl_pvs_region *o = sl_pvs_region_nodes(old);
    for (uint32_t i = 0; i < count; i++)
        if (memcmp(&o[i].box, &n[i].box, sizeof n[i].box) || o[i].first_child != n[i].first_child ||
            o[i].child_count != n[i].child_count || o[i].parent != n[i].parent)
            return false;
    return true;
}

sl_status sl_motion_regions_bake(sl_scene scene, sl_viewcells cells, const char *probe_options, uint32_t threads,
                                 const sl_allocator *a, sl_motion_regions *out, sl_error *err)
{
    uint32_t copied;
    return sl_motion_regions_update(scene, cells, probe_options, threads, NULL, NULL, a, out, &copied, err);
}

sl_status sl_motion_regions_update(sl_scene scene, sl_viewcells cells, const char *probe_options, uint32_t threads,
                                   sl_pvs old, const uint8_t *keep, const sl_allocator *a, sl_motion_regions *out,
                                   uint32_t *copied, sl_error *err)
{
    memset(out, 0, sizeof *out);
    *copied = 0;
    /* the probe needs prism or box cells: a bake of BSP cluster cells has no regions (its moving
     * objects are drawn as by frustum alone) */
    const sl_viewcell *vc = sl_viewcells_data(cells);
    for (uint32_t c = 0; c < sl_viewcells_count(cells); c++)
        if (vc[c].shape != SL_CELL_PRISM && vc[c].shape != SL_CELL_BOX)
            return SL_OK;
    sl_status st = build_tree(scene, a, &out->nodes, &out->count, err);
    if (st != SL_OK || out->count == 0)
        return st;
    const uint32_t nn = out->count, nc = sl_viewcells_count(cells);
    const size_t rb = ((size_t)nn + 7) / 8;
    /* what the file can hold, before the marking time is spent */
    if (nn > SL_PVS_MAX_REGIONS || (uint64_t)nc * rb > SL_PVS_MAX_REGION_MARK_BYTES) {
        st = sl_fail(err, SL_ERROR_LIMIT,
                     "motion regions: %u cells of %u region nodes exceed what a .slpvs holds (%u nodes, %u bytes of "
                     "marks); bake with --no-regions (no_regions), or fewer distinct regions",
                     nc, nn, SL_PVS_MAX_REGIONS, SL_PVS_MAX_REGION_MARK_BYTES);
        sl_motion_regions_free(a, out);
        return st;
    }
    out->rows_size = (size_t)nc * rb + 1;
    out->rows = sl_calloc(a, out->rows_size, 1);
    if (!keep || !same_tree(old, out->nodes, nn) || sl_viewcells_count(sl_pvs_cells(old)) != nc)
        keep = NULL;
    if (keep && out->rows)
        for (uint32_t c = 0; c < nc; c++)
            if (keep[c]) {
                memcpy(out->rows + (size_t)c * rb, sl_pvs_region_row(old, c), rb);
                (*copied)++;
            }
    const uint32_t nf = sl_scene_footprint_count(scene);
    uint8_t *use = sl_alloc(a, (size_t)nf + 1);
    sl_aabb *boxes = sl_alloc(a, (size_t)nn * sizeof *boxes);
    if (!out->rows || !use || !boxes) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "motion regions: out of memory for %u cells of %u regions", nc, nn);
        goto done;
    }
    for (uint32_t f = 0; f < nf; f++) {
        uint32_t o = sl_scene_footprint(scene, f).object;
        use[f] = o == SL_NONE || o >= sl_scene_object_count(scene) ||
                 !(sl_scene_object(scene, o).flags & SL_OBJECT_DYNAMIC);
    }
    for (uint32_t i = 0; i < nn; i++)
        boxes[i] = out->nodes[i].box;
    void *probe = NULL;
    if ((st = sl_adj_probe_create(scene, cells, probe_options, use, boxes, nn, a, &probe, err)) != SL_OK)
        goto done;
    int nt = threads ? (int)threads : omp_get_max_threads();
    nt = SL_MAX(1, SL_MIN(nt, (int)sl_thread_limit()));
    volatile int stop = 0;
    sl_status fs = SL_OK;
    sl_error ferr;
    memset(&ferr, 0, sizeof ferr);
#pragma omp parallel num_threads(nt)
    {
        void *w = NULL;
        sl_error terr;
        memset(&terr, 0, sizeof terr);
        uint32_t *front = sl_alloc(a, (size_t)nn * sizeof *front);
        uint8_t *seen = sl_calloc(a, nn, 1);
        sl_status ts = front && seen ? sl_adj_probe_worker_create(probe, &w, &terr)
                                             : sl_fail(&terr, SL_ERROR_OUT_OF_MEMORY, "motion regions: out of memory");
#pragma omp for schedule(dynamic, 4)
        for (uint32_t cell = 0; cell < nc; cell++) {
            if (stop || ts != SL_OK || (keep && keep[cell]))
                continue;
            ts = mark_cell(w, cell, out->nodes, nn, front, seen, out->rows + (size_t)cell * rb, &terr);
        }
        if (ts != SL_OK) {
#pragma omp critical(sl_motion_regions)
            if (!stop) {
                stop = 1;
                fs = ts;
                ferr = terr;
            }
        }
        if (w)
            sl_adj_probe_worker_destroy(w);
        sl_free(a, front, (size_t)nn * sizeof *front);
        sl_free(a, seen, nn);
    }
    sl_adj_probe_destroy(probe);
    if (stop) {
        st = fs;
        if (err)
            *err = ferr;
    }
done:
    sl_free(a, use, (size_t)nf + 1);
    sl_free(a, boxes, (size_t)nn * sizeof *boxes);
    if (st != SL_OK)
        sl_motion_regions_free(a, out);
    return st;
}

void sl_motion_regions_free(const sl_allocator *a, sl_motion_regions *r)
{
    sl_free(a, r->nodes, (size_t)r->count * sizeof *r->nodes);
    sl_free(a, r->rows, r->rows_size);
    memset(r, 0, sizeof *r);
}

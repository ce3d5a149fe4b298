/* plp and cplp: Prioritized-Layered Projection and its conservative completion, after Klosowski &
 * Silva, "The Prioritized-Layered Projection Algorithm for Visible Set Estimation" (IEEE TVCG
 * 2000, sections 3-4) and "Efficient Conservative Visibility Culling Using the Prioritized-
 * Layered Projection Algorithm" (IEEE TVCG 2001, section 3.3), as summarised in the SIGGRAPH 2000
 * course "Visibility, problems, techniques and applications".
 *
 * Preprocessing: an octree over the scene (a node splits while the triangles of the objects
 * centred in it exceed `leaf_tris`, by default the scene's triangles / 2048 and at least 256,
 * down to 1/64 of the root's side); its leaves, empty ones
 * included, tile space and are the cells, with their face neighbours. Every object is listed in
 * every cell one of its triangles' boxes meets, with the number of its triangles there (|c|, the
 * cell's primitives); moving (SL_OBJECT_DYNAMIC) objects by their current box, refreshed by
 * scene_changed.
 *
 * plp (aggressive): from the eye's cell, a front of cells ordered by solidity. Projecting a cell
 * reports its objects and renders their occluder proxies; each neighbour B of the projected cell A
 * inside the view pyramid gets rho_B = |A|/rho_max + (v.n_AB) rho_A (v the view direction, n_AB
 * the normal of the shared face, the least value kept), doubled when B is not in star-shaped
 * position (the eye on B's side of the shared face), and the least solid cell is projected next,
 * until the reported objects' triangles reach `budget`.
 * cplp (conservative): after the budget, every cell leaving the front is tested against the
 * rasterizer (its box at its nearest depth); visible cells are projected (their objects each
 * tested first) and their neighbours join the front, until the front is empty. Every ray
 * from the eye to a visible point crosses a chain of face-adjacent closed cells, each containing
 * a point of the ray in front of that visible point, so each of them tests visible (the
 * rasterizer holds only proxies, which never hide what the oracle sees) and gets projected: no
 * visible object is missed. The front is seeded with the eye's cell, or, when the eye is outside
 * the octree or the camera is orthographic (rays start anywhere on the near rectangle), with the
 * cells on the octree's boundary and those meeting the near rectangle. */
#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/select.h"
#include "cull/occlusion/view.h"

#include <math.h>
#include <stdlib.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#define PLP_SSE 1
#else
#define PLP_SSE 0
#endif

#define PLP_MAX_DEPTH 12

typedef struct plp_config {
    sl_occ_common c;
    bool conservative;
    uint32_t leaf_tris;
} plp_config;

typedef struct oct_node {
    sl_aabb box;
    int32_t child;              /* first of 8 children, or -1 for a leaf */
    uint32_t cell;              /* leaf: its cell */
} oct_node;

typedef struct plp_cell {
    sl_aabb box;
    uint32_t nb_first, nb_count;  /* neighbours in nb[] / nb_dir[] */
    uint32_t obj_first, obj_count;/* static members in members[] */
    uint32_t tris;                /* static triangles (+ dynamic at the last refresh) */
    uint8_t boundary;             /* touches the octree's boundary */
} plp_cell;

typedef struct member {
    uint32_t object, tris;
} member;

/* The front is a binary min-heap of 64-bit keys: the solidity's float bits (non-negative, so they
 * order like the floats) above the push counter (FIFO among equal solidities); the pushed cell is
 * heap_cell[counter]. One integer compare per step instead of a float compare and a tie branch. */
typedef uint64_t heap_key;

typedef struct plp_state {
    sl_allocator alloc;
    sl_scene scene;
    plp_config cfg;
    sl_occ_set *occ;
    sl_occ_raster r;
    oct_node *nodes;
    uint32_t node_count;
    plp_cell *cells;
    uint32_t cell_count;
    uint32_t *nb;
    uint8_t *nb_dir;              /* axis*2 + (1 if the neighbour is on the + side) */
    uint32_t nb_total;
    member *members;
    uint32_t member_count;
    /* dynamic objects: members by cell (CSR), rebuilt by scene_changed */
    uint32_t *dyn_first;          /* cell_count + 1 */
    member *dyn;
    uint32_t dyn_count, dyn_cap;
    uint32_t *dyn_objects;
    uint32_t dyn_object_count;
    uint32_t *outside;            /* moving objects whose box leaves the octree's root */
    uint32_t outside_count;
    float rho_max;
    /* per frame */
    uint8_t *cstate;              /* 0 untouched, 1 queued, 2 projected, 3 hidden */
    float *rho;
    heap_key *heap;
    uint32_t *heap_cell;          /* per push (the key's low half): its cell */
    uint32_t heap_n, heap_cap, order;
    uint32_t *ostamp, frame_id;
    uint32_t *hstamp;             /* per object: frame_id once it tested hidden or outside this frame */
    uint32_t *seeds;              /* scratch of cell_count */
    uint32_t object_count;
    uint32_t *sort_scratch;
    uint64_t cells_projected, cell_tests, object_tests;
} plp_state;

static const char g_help_plp[] =
    "budget=0..100000000 (default 100000): triangles reported before the front stops\n"
    "leaf_tris=0|16..10000000 (default 0): triangles above which an octree node splits (0: automatic, the scene's "
    "triangles / 2048, at least 256)\n" SL_OCC_HELP_RASTER
    "min_quality=NUMBER (default 0.0005): least Coorg-Teller quality (sr) of a reported object rendered as an occluder\n"
    "inset=0.01..10 (default 0.1): metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n" SL_OCC_HELP_DEBUG;

static const char g_help_cplp[] =
    "budget=0..100000000 (default 5000): triangles of the plain PLP phase before the conservative completion\n"
    "leaf_tris=0|16..10000000 (default 0): triangles above which an octree node splits (0: automatic, the scene's "
    "triangles / 2048, at least 256)\n" SL_OCC_HELP_RES SL_OCC_HELP_RASTER
    "min_quality=NUMBER (default 0.0005): least Coorg-Teller quality (sr) of a reported object rendered as an occluder\n"
    "inset=0.01..10 (default 0.1): metres a footprint prism is shrunk by inside its building\n"
    "all_objects=BOOL (default false): every object's own mesh may occlude, not only SL_OBJECT_OCCLUDER ones\n" SL_OCC_HELP_DEBUG;

static sl_status configure(sl_opts *o, plp_config *c, bool conservative, sl_cull_guarantee *g, sl_error *err)
{
    sl_status st;
    c->conservative = conservative;
    /* cplp takes res=any|culling (plp is aggressive either way: it keeps today's rendering) */
    uint32_t res = conservative ? SL_OCC_OPT_RES : 0;
    if ((st = sl_opts_u32(o, "budget", conservative ? 5000 : 100000, 0, 100000000, &c->c.budget, err)) != SL_OK ||
        (st = sl_opts_u32(o, "leaf_tris", 0, 0, 10000000, &c->leaf_tris, err)) != SL_OK ||
        (st = sl_occ_configure_common(o, SL_OCC_OPT_RASTER | SL_OCC_OPT_DEBUG | res, 0, 0, &c->c, err)) != SL_OK ||
        (st = sl_opts_float(o, "min_quality", 0.0005f, 0.0f, 100.0f, &c->c.min_quality, err)) != SL_OK)
        return st;
    if (c->leaf_tris && c->leaf_tris < 16)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option leaf_tris=%u: 0 (automatic) or 16..10000000",
                       o->method, c->leaf_tris);
    if (conservative)
        *g = sl_occ_res_guarantee(&c->c);
    return SL_OK;
}

static sl_status plp_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure(o, config, false, g, err);
}

static sl_status cplp_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    return configure(o, config, true, g, err);
}

static const char *name_of(const plp_state *s) { return s->cfg.conservative ? "cplp" : "plp"; }

static void plp_destroy(void *state)
{
    plp_state *s = state;
    if (!s)
        return;
    const sl_allocator *a = &s->alloc;
    sl_occ_raster_free(&s->r);
    sl_occ_set_destroy(s->occ);
    sl_free(a, s->nodes, (size_t)s->node_count * sizeof(oct_node));
    sl_free(a, s->cells, (size_t)s->cell_count * sizeof(plp_cell));
    sl_free(a, s->nb, (size_t)s->nb_total * sizeof(uint32_t));
    sl_free(a, s->nb_dir, s->nb_total);
    sl_free(a, s->members, (size_t)s->member_count * sizeof(member));
    sl_free(a, s->dyn_first, ((size_t)s->cell_count + 1) * sizeof(uint32_t));
    sl_free(a, s->dyn, (size_t)s->dyn_cap * sizeof(member));
    sl_free(a, s->dyn_objects, (size_t)(s->dyn_object_count ? s->dyn_object_count : 1) * sizeof(uint32_t));
    sl_free(a, s->outside, (size_t)(s->dyn_object_count ? s->dyn_object_count : 1) * sizeof(uint32_t));
    sl_free(a, s->cstate, s->cell_count);
    sl_free(a, s->rho, (size_t)s->cell_count * sizeof(float));
    sl_free(a, s->heap, (size_t)s->heap_cap * sizeof(heap_key));
    sl_free(a, s->heap_cell, (size_t)s->heap_cap * sizeof(uint32_t));
    sl_free(a, s->ostamp, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    sl_free(a, s->hstamp, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    sl_free(a, s->seeds, (size_t)s->cell_count * sizeof(uint32_t));
    sl_free(a, s->sort_scratch, (size_t)(s->object_count ? s->object_count : 1) * sizeof(uint32_t));
    sl_free(a, s, sizeof *s);
}

/* ---- the octree ---- */

typedef struct build {
    const sl_allocator *a;
    sl_array nodes;             /* oct_node */
    uint32_t *obj;              /* object ids, partitioned in place per node */
    const sl_aabb *bounds;
    const uint32_t *tris;       /* triangles per object */
    float min_side;
    uint32_t leaf_tris;
    uint32_t cells;
} build;

static sl_vec3 centre_of(const sl_aabb *b)
{
    return (sl_vec3){0.5f * (b->min.x + b->max.x), 0.5f * (b->min.y + b->max.y), 0.5f * (b->min.z + b->max.z)};
}

/* Build node `ni` over objects obj[first, first+count) (those whose box centre is inside). */
static bool build_node(build *b, uint32_t ni, uint32_t first, uint32_t count, int depth)
{
    oct_node *n = &SL_AT(b->nodes, oct_node, ni);
    uint64_t tris = 0;
    for (uint32_t i = 0; i < count; i++)
        tris += b->tris[b->obj[first + i]];
    sl_aabb box = n->box;
    float side = sl_occ_maxf(box.max.x - box.min.x, sl_occ_maxf(box.max.y - box.min.y, box.max.z - box.min.z));
    if (tris <= b->leaf_tris || depth >= PLP_MAX_DEPTH || side * 0.5f < b->min_side) {
        n->child = -1;
        n->cell = b->cells++;
        return true;
    }
    sl_vec3 m = centre_of(&box);
    uint32_t c0 = (uint32_t)b->nodes.count;
    if (!sl_array_push(b->a, &b->nodes, sizeof(oct_node), NULL, 8))
        return false;
    n = &SL_AT(b->nodes, oct_node, ni); /* the array may have moved */
    n->child = (int32_t)c0;
    n->cell = SL_NONE;
    /* partition the objects by octant of their centre (a counting pass per octant) */
    uint32_t start[9] = {0}, cnt[8] = {0};
    for (uint32_t i = 0; i < count; i++) {
        sl_vec3 c = centre_of(&b->bounds[b->obj[first + i]]);
        cnt[(c.x >= m.x ? 1 : 0) | (c.y >= m.y ? 2 : 0) | (c.z >= m.z ? 4 : 0)]++;
    }
    for (int k = 0; k < 8; k++)
        start[k + 1] = start[k] + cnt[k];
    /* in-place cycle sort into octant ranges */
    uint32_t next[8];
    for (int k = 0; k < 8; k++)
        next[k] = start[k];
    for (int k = 0; k < 8; k++)
        while (next[k] < start[k + 1]) {
            uint32_t id = b->obj[first + next[k]];
            sl_vec3 c = centre_of(&b->bounds[id]);
            int o = (c.x >= m.x ? 1 : 0) | (c.y >= m.y ? 2 : 0) | (c.z >= m.z ? 4 : 0);
            if (o == k) {
                next[k]++;
                continue;
            }
            uint32_t t = b->obj[first + next[o]];
            b->obj[first + next[o]] = id;
            next[o]++;
            b->obj[first + next[k]] = t;
        }
    for (int k = 0; k < 8; k++) {
        oct_node *ch = &SL_AT(b->nodes, oct_node, c0 + (uint32_t)k);
        ch->box.min = (sl_vec3){(k & 1) ? m.x : box.min.x, (k & 2) ? m.y : box.min.y, (k & 4) ? m.z : box.min.z};
        ch->box.max = (sl_vec3){(k & 1) ? box.max.x : m.x, (k & 2) ? box.max.y : m.y, (k & 4) ? box.max.z : m.z};
        if (!build_node(b, c0 + (uint32_t)k, first + start[k], cnt[k], depth + 1))
            return false;
    }
    return true;
}

/* Closed-box overlap. */
static inline bool overlap(const sl_aabb *a, const sl_aabb *b)
{
    return a->min.x <= b->max.x && b->min.x <= a->max.x && a->min.y <= b->max.y && b->min.y <= a->max.y &&
           a->min.z <= b->max.z && b->min.z <= a->max.z;
}

/* Call fn for every leaf cell whose closed box meets q. */
typedef void (*leaf_fn)(void *user, uint32_t cell);
static void each_leaf(const plp_state *s, const sl_aabb *q, leaf_fn fn, void *user)
{
    uint32_t stack[8 * PLP_MAX_DEPTH + 8], sp = 0;
    if (!s->node_count || !overlap(&s->nodes[0].box, q))
        return;
    stack[sp++] = 0;
    while (sp) {
        const oct_node *n = &s->nodes[stack[--sp]];
        if (n->child < 0) {
            fn(user, n->cell);
            continue;
        }
        for (uint32_t k = 0; k < 8; k++)
            if (overlap(&s->nodes[(uint32_t)n->child + k].box, q))
                stack[sp++] = (uint32_t)n->child + k;
    }
}

/* Leaf containing point p (closed boxes, the first found), or SL_NONE outside the root. */
static uint32_t find_leaf(const plp_state *s, sl_vec3 p)
{
    if (!s->node_count)
        return SL_NONE;
    const oct_node *n = &s->nodes[0];
    sl_aabb b = n->box;
    if (!(p.x >= b.min.x && p.x <= b.max.x && p.y >= b.min.y && p.y <= b.max.y && p.z >= b.min.z && p.z <= b.max.z))
        return SL_NONE;
    while (n->child >= 0) {
        sl_vec3 m = centre_of(&n->box);
        n = &s->nodes[(uint32_t)n->child + (uint32_t)((p.x >= m.x ? 1 : 0) | (p.y >= m.y ? 2 : 0) | (p.z >= m.z ? 4 : 0))];
    }
    return n->cell;
}

/* ---- cell contents ---- */

typedef struct member_ctx {
    plp_state *s;
    sl_array *pairs;            /* member, with .object = cell during collection (then sorted) */
    uint32_t object;
    uint32_t *stamp;            /* per cell: object + 1 last seen */
    uint32_t *pos;              /* per cell: index of its pair for the current object */
    uint32_t tris_add;
    bool oom;
} member_ctx;

typedef struct cell_member {
    uint32_t cell, object, tris;
} cell_member;

static void add_member(void *user, uint32_t cell)
{
    member_ctx *m = user;
    if (m->oom)
        return;
    if (m->stamp[cell] == m->object + 1) {
        SL_AT(*m->pairs, cell_member, m->pos[cell]).tris += m->tris_add;
        return;
    }
    m->stamp[cell] = m->object + 1;
    m->pos[cell] = (uint32_t)m->pairs->count;
    cell_member cm = {cell, m->object, m->tris_add};
    if (!sl_array_push(&m->s->alloc, m->pairs, sizeof cm, &cm, 1))
        m->oom = true;
}

/* List object `o` in the cells its triangles' boxes meet (its box for dynamic objects). */
static void collect_object(member_ctx *m, uint32_t o, bool by_box)
{
    plp_state *s = m->s;
    const struct sl_scene_t *sc = s->scene;
    const sl_object_rec *rec = &sl_scene_objects(sc)[o];
    const sl_mesh_rec *mr = &sl_scene_meshes(sc)[rec->mesh];
    sl_aabb ob = sl_scene_object_bounds_array(s->scene)[o];
    m->object = o;
    if (mr->triangle_count == 0)
        return;
    uint32_t single = find_leaf(s, ob.min);
    bool one = single != SL_NONE && single == find_leaf(s, ob.max);
    if (one) {
        /* the whole box in one leaf (the leaf holding both corners contains the box) */
        const sl_aabb *cb = &s->cells[single].box;
        one = ob.min.x >= cb->min.x && ob.max.x <= cb->max.x && ob.min.y >= cb->min.y && ob.max.y <= cb->max.y &&
              ob.min.z >= cb->min.z && ob.max.z <= cb->max.z;
    }
    if (by_box || one) {
        /* a moving object's triangles are counted in full in every cell its box meets */
        m->tris_add = mr->triangle_count;
        if (one)
            add_member(m, single);
        else
            each_leaf(s, &ob, add_member, m);
        return;
    }
    sl_affine id = sl_affine_identity();
    const sl_affine *xf = rec->transform == SL_NONE ? &id : &sl_scene_transforms(sc)[rec->transform];
    const float *pos = sl_scene_positions(sc) + 3 * mr->first_vertex;
    const uint32_t *idx = sl_scene_indices(sc) + mr->first_index;
    m->tris_add = 1;
    for (uint32_t t = 0; t < mr->triangle_count && !m->oom; t++) {
        sl_aabb tb = sl_aabb_empty();
        for (int c = 0; c < 3; c++) {
            const float *p = pos + 3 * (size_t)idx[3 * t + c];
            sl_aabb_grow(&tb, sl_affine_point(xf, (sl_vec3){p[0], p[1], p[2]}));
        }
        /* grow by the rounding of the transform */
        float g = SL_MARGIN_XFORM_REL_F * (fabsf(tb.min.x) + fabsf(tb.min.y) + fabsf(tb.min.z) + fabsf(tb.max.x) + fabsf(tb.max.y) +
                           fabsf(tb.max.z) + 1.0f);
        tb.min.x -= g, tb.min.y -= g, tb.min.z -= g, tb.max.x += g, tb.max.y += g, tb.max.z += g;
        each_leaf(s, &tb, add_member, m);
    }
}

static int cmp_cell_member(const void *a, const void *b)
{
    const cell_member *x = a, *y = b;
    if (x->cell != y->cell)
        return x->cell < y->cell ? -1 : 1;
    return (x->object > y->object) - (x->object < y->object);
}

/* Fill members (static or dynamic) from collected pairs: sorted by cell, then CSR. */
static bool pairs_to_csr(plp_state *s, sl_array *pairs, member **out, uint32_t *out_count, uint32_t *first,
                         bool to_cells)
{
    size_t n = pairs->count;
    cell_member *p = pairs->data;
    if (n)
        qsort(p, n, sizeof *p, cmp_cell_member);
    member *m = sl_alloc(&s->alloc, (n ? n : 1) * sizeof(member));
    if (!m)
        return false;
    uint32_t c = 0;
    for (size_t i = 0; i < n; i++) {
        m[i] = (member){p[i].object, p[i].tris};
        while (c <= p[i].cell) {
            if (to_cells) {
                s->cells[c].obj_first = (uint32_t)i;
                s->cells[c].obj_count = 0;
            } else {
                first[c] = (uint32_t)i;
            }
            c++;
        }
        if (to_cells)
            s->cells[p[i].cell].obj_count++;
    }
    for (; c <= s->cell_count; c++) {
        if (to_cells && c < s->cell_count) {
            s->cells[c].obj_first = (uint32_t)n;
            s->cells[c].obj_count = 0;
        } else if (!to_cells) {
            first[c] = (uint32_t)n;
        }
    }
    *out = m;
    *out_count = (uint32_t)n;
    return true;
}

/* (Re)list the moving objects by their current boxes and refresh rho_max. */
static sl_status refresh_dynamic(plp_state *s, sl_error *err)
{
    sl_array pairs = {0};
    uint32_t *stamp = sl_calloc(&s->alloc, s->cell_count, sizeof(uint32_t));
    uint32_t *pos = sl_alloc(&s->alloc, (size_t)s->cell_count * sizeof(uint32_t));
    sl_status st = SL_OK;
    if (!stamp || !pos) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", name_of(s));
        goto done;
    }
    member_ctx m = {s, &pairs, 0, stamp, pos, 0, false};
    const sl_aabb *root = &s->nodes[0].box, *bounds = sl_scene_object_bounds_array(s->scene);
    s->outside_count = 0;
    for (uint32_t i = 0; i < s->dyn_object_count && !m.oom; i++) {
        uint32_t o = s->dyn_objects[i];
        const sl_aabb *b = &bounds[o];
        /* the cells tile the root only: an object reaching beyond it is tested on its own */
        if (!(b->min.x >= root->min.x && b->max.x <= root->max.x && b->min.y >= root->min.y &&
              b->max.y <= root->max.y && b->min.z >= root->min.z && b->max.z <= root->max.z))
            s->outside[s->outside_count++] = o;
        collect_object(&m, o, true);
    }
    if (m.oom) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for cell lists", name_of(s));
        goto done;
    }
    sl_free(&s->alloc, s->dyn, (size_t)s->dyn_cap * sizeof(member));
    s->dyn = NULL;
    s->dyn_cap = 0;
    uint32_t cnt;
    if (!pairs_to_csr(s, &pairs, &s->dyn, &cnt, s->dyn_first, false)) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for cell lists", name_of(s));
        goto done;
    }
    s->dyn_count = cnt;
    s->dyn_cap = cnt ? cnt : 1;
    s->rho_max = 1;
    for (uint32_t c = 0; c < s->cell_count; c++) {
        uint32_t t = 0;
        for (uint32_t i = s->cells[c].obj_first; i < s->cells[c].obj_first + s->cells[c].obj_count; i++)
            t += s->members[i].tris;
        for (uint32_t i = s->dyn_first[c]; i < s->dyn_first[c + 1]; i++)
            t += s->dyn[i].tris;
        s->cells[c].tris = t;
        s->rho_max = sl_occ_maxf(s->rho_max, (float)t);
    }
done:
    sl_array_free(&s->alloc, &pairs, sizeof(cell_member));
    sl_free(&s->alloc, stamp, (size_t)s->cell_count * sizeof(uint32_t));
    sl_free(&s->alloc, pos, (size_t)s->cell_count * sizeof(uint32_t));
    return st;
}

/* Face neighbours: leaves whose closed boxes share a face portion of positive area. */
typedef struct nb_ctx {
    plp_state *s;
    uint32_t self;
    int axis, sign;
    sl_array *list;             /* uint32 cell, then uint8 dir packed as (cell << 3 | dir) in uint64 */
    bool oom;
} nb_ctx;

static void add_nb(void *user, uint32_t cell)
{
    nb_ctx *n = user;
    if (cell == n->self || n->oom)
        return;
    const sl_aabb *a = &n->s->cells[n->self].box, *b = &n->s->cells[cell].box;
    const float amin[3] = {a->min.x, a->min.y, a->min.z}, amax[3] = {a->max.x, a->max.y, a->max.z};
    const float bmin[3] = {b->min.x, b->min.y, b->min.z}, bmax[3] = {b->max.x, b->max.y, b->max.z};
    /* touching on the face plane, overlapping with positive area on the two other axes */
    if (n->sign > 0 ? bmin[n->axis] != amax[n->axis] : bmax[n->axis] != amin[n->axis])
        return;
    for (int k = 0; k < 3; k++)
        if (k != n->axis && !(amin[k] < bmax[k] && bmin[k] < amax[k]))
            return;
    uint64_t e = ((uint64_t)cell << 3) | (uint64_t)(n->axis * 2 + (n->sign > 0 ? 1 : 0));
    if (!sl_array_push(&n->s->alloc, n->list, sizeof e, &e, 1))
        n->oom = true;
}

static sl_status build_cells(plp_state *s, sl_error *err)
{
    const struct sl_scene_t *sc = s->scene;
    uint32_t n = s->object_count;
    sl_aabb root = sl_scene_bounds(s->scene);
    if (sl_aabb_is_empty(&root))
        root = (sl_aabb){{-1, -1, -1}, {1, 1, 1}};
    /* a cube around the scene, grown a little so that nothing lies on its boundary */
    sl_vec3 c = centre_of(&root);
    float half = 0.5f * sl_occ_maxf(root.max.x - root.min.x, sl_occ_maxf(root.max.y - root.min.y, root.max.z - root.min.z));
    half = half * 1.01f + 1.0f;
    root = (sl_aabb){{c.x - half, c.y - half, c.z - half}, {c.x + half, c.y + half, c.z + half}};
    build b = {&s->alloc, {0}, NULL, sl_scene_object_bounds_array(s->scene), NULL, 2 * half / 64.0f, s->cfg.leaf_tris, 0};
    uint32_t *tris = sl_alloc(&s->alloc, (size_t)(n ? n : 1) * sizeof(uint32_t));
    b.obj = sl_alloc(&s->alloc, (size_t)(n ? n : 1) * sizeof(uint32_t));
    sl_status st = SL_OK;
    if (!tris || !b.obj || !sl_array_push(&s->alloc, &b.nodes, sizeof(oct_node), NULL, 1)) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the octree", name_of(s));
        goto done;
    }
    const sl_object_rec *objects = sl_scene_objects(sc);
    const sl_mesh_rec *meshes = sl_scene_meshes(sc);
    uint32_t nd = 0;
    for (uint32_t i = 0; i < n; i++) {
        tris[i] = meshes[objects[i].mesh].triangle_count;
        b.obj[i] = i;
        nd += (objects[i].flags & SL_OBJECT_DYNAMIC) != 0;
    }
    b.tris = tris;
    if (b.leaf_tris == 0) {
        uint64_t total = 0;
        for (uint32_t i = 0; i < n; i++)
            total += tris[i];
        b.leaf_tris = (uint32_t)SL_MAX(256, total / 2048);
    }
    SL_AT(b.nodes, oct_node, 0).box = root;
    if (!build_node(&b, 0, 0, n, 0)) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the octree", name_of(s));
        goto done;
    }
    s->node_count = (uint32_t)b.nodes.count;
    s->nodes = b.nodes.data;
    b.nodes.data = NULL;
    s->nodes = sl_realloc(&s->alloc, s->nodes, b.nodes.cap * sizeof(oct_node), (size_t)s->node_count * sizeof(oct_node));
    s->cell_count = b.cells;
    s->cells = sl_calloc(&s->alloc, s->cell_count, sizeof(plp_cell));
    if (!s->nodes || !s->cells) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for %u cells", name_of(s), b.cells);
        goto done;
    }
    for (uint32_t i = 0; i < s->node_count; i++)
        if (s->nodes[i].child < 0) {
            plp_cell *cl = &s->cells[s->nodes[i].cell];
            cl->box = s->nodes[i].box;
            cl->boundary = cl->box.min.x == root.min.x || cl->box.min.y == root.min.y || cl->box.min.z == root.min.z ||
                           cl->box.max.x == root.max.x || cl->box.max.y == root.max.y || cl->box.max.z == root.max.z;
        }
    /* neighbours */
    sl_array list = {0};
    sl_array firsts = {0};
    for (uint32_t ci = 0; ci < s->cell_count; ci++) {
        uint32_t f = (uint32_t)list.count;
        if (!sl_array_push(&s->alloc, &firsts, sizeof f, &f, 1)) {
            st = SL_ERROR_OUT_OF_MEMORY;
            break;
        }
        const sl_aabb *a = &s->cells[ci].box;
        for (int axis = 0; axis < 3 && st == SL_OK; axis++)
            for (int sign = -1; sign <= 1; sign += 2) {
                sl_aabb q = *a;
                float *qmin = &q.min.x, *qmax = &q.max.x;
                float v = sign > 0 ? (&a->max.x)[axis] : (&a->min.x)[axis];
                qmin[axis] = qmax[axis] = v;
                nb_ctx nc = {s, ci, axis, sign, &list, false};
                each_leaf(s, &q, add_nb, &nc);
                if (nc.oom)
                    st = SL_ERROR_OUT_OF_MEMORY;
            }
    }
    if (st == SL_OK) {
        s->nb_total = (uint32_t)list.count;
        s->nb = sl_alloc(&s->alloc, (size_t)(s->nb_total ? s->nb_total : 1) * sizeof(uint32_t));
        s->nb_dir = sl_alloc(&s->alloc, s->nb_total ? s->nb_total : 1);
        if (!s->nb || !s->nb_dir)
            st = SL_ERROR_OUT_OF_MEMORY;
    }
    if (st == SL_OK) {
        s->nb_total = s->nb_total ? s->nb_total : 1;
        const uint64_t *e = list.data;
        for (size_t i = 0; i < list.count; i++) {
            s->nb[i] = (uint32_t)(e[i] >> 3);
            s->nb_dir[i] = (uint8_t)(e[i] & 7);
        }
        for (uint32_t ci = 0; ci < s->cell_count; ci++) {
            uint32_t f = SL_AT(firsts, uint32_t, ci);
            uint32_t l = ci + 1 < s->cell_count ? SL_AT(firsts, uint32_t, ci + 1) : (uint32_t)list.count;
            s->cells[ci].nb_first = f;
            s->cells[ci].nb_count = l - f;
        }
    }
    sl_array_free(&s->alloc, &list, sizeof(uint64_t));
    sl_array_free(&s->alloc, &firsts, sizeof(uint32_t));
    if (st != SL_OK) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for cell neighbours", name_of(s));
        goto done;
    }
    /* static members */
    {
        sl_array pairs = {0};
        uint32_t *stamp = sl_calloc(&s->alloc, s->cell_count, sizeof(uint32_t));
        uint32_t *pos = sl_alloc(&s->alloc, (size_t)s->cell_count * sizeof(uint32_t));
        member_ctx m = {s, &pairs, 0, stamp, pos, 0, !stamp || !pos};
        for (uint32_t o = 0; o < n && !m.oom; o++)
            if (!(objects[o].flags & SL_OBJECT_DYNAMIC))
                collect_object(&m, o, false);
        bool ok = !m.oom && pairs_to_csr(s, &pairs, &s->members, &s->member_count, NULL, true);
        sl_array_free(&s->alloc, &pairs, sizeof(cell_member));
        sl_free(&s->alloc, stamp, (size_t)s->cell_count * sizeof(uint32_t));
        sl_free(&s->alloc, pos, (size_t)s->cell_count * sizeof(uint32_t));
        if (!ok) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for cell lists", name_of(s));
            goto done;
        }
        s->member_count = s->member_count ? s->member_count : 1; /* the allocation size */
    }
    s->dyn_object_count = nd;
    s->dyn_objects = sl_alloc(&s->alloc, (size_t)(nd ? nd : 1) * sizeof(uint32_t));
    s->outside = sl_alloc(&s->alloc, (size_t)(nd ? nd : 1) * sizeof(uint32_t));
    s->dyn_first = sl_alloc(&s->alloc, ((size_t)s->cell_count + 1) * sizeof(uint32_t));
    if (!s->dyn_objects || !s->outside || !s->dyn_first) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", name_of(s));
        goto done;
    }
    nd = 0;
    for (uint32_t o = 0; o < n; o++)
        if (objects[o].flags & SL_OBJECT_DYNAMIC)
            s->dyn_objects[nd++] = o;
    st = refresh_dynamic(s, err);
done:
    sl_array_free(&s->alloc, &b.nodes, sizeof(oct_node));
    sl_free(&s->alloc, tris, (size_t)(n ? n : 1) * sizeof(uint32_t));
    sl_free(&s->alloc, b.obj, (size_t)(n ? n : 1) * sizeof(uint32_t));
    return st;
}

static sl_status plp_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state, sl_error *err)
{
    plp_state *s = sl_calloc(alloc, 1, sizeof *s);
    const plp_config *cfg = config;
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", cfg->conservative ? "cplp" : "plp");
    s->alloc = *alloc;
    s->scene = scene;
    s->cfg = *cfg;
    s->object_count = sl_scene_object_count(scene);
    sl_occ_options oo = {s->cfg.c.inset, s->cfg.c.all_objects, s->cfg.c.res_any, 0, false}; /* res=any draws faces */
    sl_status st = sl_occ_set_create(scene, &oo, alloc, &s->occ, err);
    if (st == SL_OK)
        st = sl_occ_raster_init(&s->r, &s->cfg.c, s->occ, alloc, err);
    if (st != SL_OK)
        sl_error_prefix(err, "%s", name_of(s));
    if (st == SL_OK)
        st = build_cells(s, err);
    if (st == SL_OK) {
        size_t nc = s->cell_count ? s->cell_count : 1, no = s->object_count ? s->object_count : 1;
        s->cstate = sl_alloc(alloc, nc);
        s->rho = sl_alloc(alloc, nc * sizeof(float));
        s->heap_cap = s->nb_total + 2 * s->cell_count + 1;
        s->heap = sl_alloc(alloc, (size_t)s->heap_cap * sizeof(heap_key));
        s->heap_cell = sl_alloc(alloc, (size_t)s->heap_cap * sizeof(uint32_t));
        s->ostamp = sl_calloc(alloc, no, sizeof(uint32_t));
        s->hstamp = sl_calloc(alloc, no, sizeof(uint32_t));
        s->seeds = sl_alloc(alloc, nc * sizeof(uint32_t));
        s->sort_scratch = sl_alloc(alloc, no * sizeof(uint32_t));
        if (!s->cstate || !s->rho || !s->heap || !s->heap_cell || !s->ostamp || !s->hstamp || !s->seeds ||
            !s->sort_scratch)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", name_of(s));
    }
    if (st != SL_OK) {
        plp_destroy(s);
        return st;
    }
    *state = s;
    return SL_OK;
}

static sl_status plp_scene_changed(void *state, sl_error *err)
{
    plp_state *s = state;
    sl_occ_set_scene_changed(s->occ);
    return refresh_dynamic(s, err);
}

/* ---- per frame ---- */

/* Solidities are finite and >= 0 (+0.0f folds a -0.0f into +0). */
static void heap_push(plp_state *s, float rho, uint32_t cell)
{
    if (s->order == s->heap_cap)
        return; /* cannot happen: every push is a seed, or follows a first visit or a strict decrease
                   through one of the nb_total neighbour links of a cell projected once */
    union {
        float f;
        uint32_t u;
    } bits = {rho + 0.0f};
    s->heap_cell[s->order] = cell;
    heap_key x = (heap_key)bits.u << 32 | s->order++;
    uint32_t i = s->heap_n++;
    while (i > 0 && x < s->heap[(i - 1) / 2]) {
        s->heap[i] = s->heap[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    s->heap[i] = x;
}

/* Pop the least key: its cell, and its solidity in *rho. */
static uint32_t heap_pop(plp_state *s, float *rho)
{
    heap_key *h = s->heap, top = h[0], x = h[--s->heap_n];
    uint32_t i = 0, n = s->heap_n;
    for (;;) {
        uint32_t l = 2 * i + 1;
        if (l >= n)
            break;
        l += (l + 1 < n && h[l + 1] < h[l]) ? 1u : 0u; /* the lesser child, without a branch */
        if (x <= h[l])
            break;
        h[i] = h[l];
        i = l;
    }
    h[i] = x;
    union {
        uint32_t u;
        float f;
    } bits = {(uint32_t)(top >> 32)};
    *rho = bits.f;
    return s->heap_cell[(uint32_t)top];
}

/* ---- box tests, four corners or planes per SSE register ----
 * The completion phase projects thousands of cell and object boxes per frame, which made the
 * scalar sl_occ_frustum_classify and sl_occ_project_box the largest costs of a cplp frame. These
 * are the same computations with the corners (or planes) in SSE lanes, every lane doing the
 * scalar code's float operations in its order, so the answers, rectangles and depths are the same
 * bits (checked on every call of the test suite and a 300-frame walk while this was written;
 * were a build to fuse multiply-adds in one and not the other, both would stay conservative: the
 * rectangle's 1/64-pixel growth and the depth's 2^-20 nudge cover far more than a rounding).
 * The frustum planes are the shared classifier's SSE lanes (core/frustum_classify.h,
 * sl_frustum_lanes_reject, tested bit-identical to sl_frustum_classify_box). Without SSE2 the
 * scalar functions are called. */
typedef struct fast_view {
#if PLP_SSE
    __m128 col[4];              /* the world-to-clip matrix's columns */
    __m128 hw, hh;
#endif
    sl_frustum_lanes planes[2]; /* the frustum planes: all six | all but the near plane (0x2f) */
} fast_view;

static void fast_view_init(fast_view *fv, const sl_occ_view *v)
{
#if PLP_SSE
    for (int c = 0; c < 4; c++)
        fv->col[c] = _mm_loadu_ps(v->vp.m + 4 * c);
    fv->hw = _mm_set1_ps(0.5f * (float)v->width);
    fv->hh = _mm_set1_ps(0.5f * (float)v->height);
#endif
    sl_frustum_lanes_init(&fv->planes[0], v->fr.planes, v->slack, 0x3fu);
    sl_frustum_lanes_init(&fv->planes[1], v->fr.planes, v->slack, 0x2fu);
}

#if PLP_SSE
static inline __m128 bcast_ps(__m128 v, int i)
{
    switch (i) {
    case 0: return _mm_shuffle_ps(v, v, 0x00);
    case 1: return _mm_shuffle_ps(v, v, 0x55);
    case 2: return _mm_shuffle_ps(v, v, 0xaa);
    default: return _mm_shuffle_ps(v, v, 0xff);
    }
}
static inline float hmin_ps(__m128 v)
{
    v = _mm_min_ps(v, _mm_shuffle_ps(v, v, 0x4e));
    return _mm_cvtss_f32(_mm_min_ps(v, _mm_shuffle_ps(v, v, 0xb1)));
}
static inline float hmax_ps(__m128 v)
{
    v = _mm_max_ps(v, _mm_shuffle_ps(v, v, 0x4e));
    return _mm_cvtss_f32(_mm_max_ps(v, _mm_shuffle_ps(v, v, 0xb1)));
}
#endif

/* sl_occ_frustum_classify(v, b, all ? 0x3f : 0x2f) >= 0, by the shared classifier's SSE lanes. */
static bool fast_in_planes(const fast_view *fv, const sl_aabb *b, bool all)
{
    return !sl_frustum_lanes_reject(&fv->planes[all ? 0 : 1], b);
}

#if PLP_SSE
/* floor of x clamped to [-2, n + 2] (exact there: truncation corrected below zero). */
static inline int32_t floor_clamped(float x, int32_t n)
{
    x = x < -2.0f ? -2.0f : (x > (float)n + 2.0f ? (float)n + 2.0f : x);
    int32_t t = (int32_t)x;
    return (float)t > x ? t - 1 : t;
}
static inline int32_t clamp_i(int32_t x, int32_t n) { return x < 0 ? 0 : (x > n ? n : x); }
#endif

/* sl_occ_project_box(v, b, r), with r filled only for SL_OCC_RECT. */
static int fast_project_box(const fast_view *fv, const sl_occ_view *v, const sl_aabb *b, sl_occ_rect *r)
{
#if PLP_SSE
    /* clip = base + (k&1) ex + (k&2) ey + (k&4) ez for corner k: lanes 0-3 hold k = 0-3, lanes 4-7 k = 4-7 */
    const __m128 zero = _mm_setzero_ps();
    __m128 base = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(fv->col[0], _mm_set1_ps(b->min.x)),
                                                   _mm_mul_ps(fv->col[1], _mm_set1_ps(b->min.y))),
                                        _mm_mul_ps(fv->col[2], _mm_set1_ps(b->min.z))),
                             fv->col[3]);
    __m128 ex = _mm_mul_ps(fv->col[0], _mm_set1_ps(b->max.x - b->min.x));
    __m128 ey = _mm_mul_ps(fv->col[1], _mm_set1_ps(b->max.y - b->min.y));
    __m128 ez = _mm_mul_ps(fv->col[2], _mm_set1_ps(b->max.z - b->min.z));
    const __m128 kx = _mm_castsi128_ps(_mm_setr_epi32(0, -1, 0, -1));
    const __m128 ky = _mm_castsi128_ps(_mm_setr_epi32(0, 0, -1, -1));
    __m128 c[4][2]; /* component, corner half */
    for (int i = 0; i < 4; i++) {
        __m128 t = _mm_add_ps(_mm_add_ps(bcast_ps(base, i), _mm_and_ps(kx, bcast_ps(ex, i))),
                              _mm_and_ps(ky, bcast_ps(ey, i)));
        c[i][0] = _mm_add_ps(t, zero);
        c[i][1] = _mm_add_ps(t, bcast_ps(ez, i));
    }
    const __m128 sign = _mm_set1_ps(-0.0f);
    __m128 bad = zero, near = zero, o[6];
    for (int h = 0; h < 2; h++) {
        __m128 x = c[0][h], y = c[1][h], z = c[2][h], w = c[3][h], nw = _mm_xor_ps(w, sign);
        __m128 fin = _mm_add_ps(_mm_add_ps(_mm_sub_ps(x, x), _mm_sub_ps(y, y)),
                                _mm_add_ps(_mm_sub_ps(z, z), _mm_sub_ps(w, w))); /* NaN where one is not finite */
        bad = _mm_or_ps(bad, _mm_cmpunord_ps(fin, fin));
        __m128 zn = _mm_cmplt_ps(z, nw);
        near = _mm_or_ps(near, _mm_or_ps(zn, _mm_cmplt_ps(w, _mm_set1_ps(1e-5f))));
        __m128 oc[6] = {_mm_cmplt_ps(x, nw), _mm_cmpgt_ps(x, w), _mm_cmplt_ps(y, nw),
                        _mm_cmpgt_ps(y, w), zn, _mm_cmpgt_ps(z, w)};
        for (int p = 0; p < 6; p++)
            o[p] = h ? _mm_and_ps(o[p], oc[p]) : oc[p];
    }
    if (_mm_movemask_ps(bad))
        return SL_OCC_NEAR;
    for (int p = 0; p < 6; p++)
        if (_mm_movemask_ps(o[p]) == 15)
            return SL_OCC_OUT;
    if (_mm_movemask_ps(near))
        return SL_OCC_NEAR;
    __m128 sx[2], sy[2], d[2];
    for (int h = 0; h < 2; h++) {
        __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), c[3][h]);
        sx[h] = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(c[0][h], inv), fv->hw), fv->hw);
        sy[h] = _mm_sub_ps(fv->hh, _mm_mul_ps(_mm_mul_ps(c[1][h], inv), fv->hh));
        d[h] = v->ortho ? _mm_mul_ps(_mm_set1_ps(0.5f), _mm_sub_ps(_mm_set1_ps(1.0f), _mm_mul_ps(c[2][h], inv))) : inv;
    }
    /* no lane is NaN (finite coordinates, w >= 1e-5), so the order of the reductions is immaterial */
    float minx = hmin_ps(_mm_min_ps(sx[0], sx[1])), maxx = hmax_ps(_mm_max_ps(sx[0], sx[1]));
    float miny = hmin_ps(_mm_min_ps(sy[0], sy[1])), maxy = hmax_ps(_mm_max_ps(sy[0], sy[1]));
    float dn = hmax_ps(_mm_max_ps(d[0], d[1]));
    if (!isfinite(minx) || !isfinite(maxx) || !isfinite(miny) || !isfinite(maxy) || !isfinite(dn))
        return SL_OCC_NEAR;
    /* the pixels touched, grown by 1/64 pixel, clamped to the screen (as sl_occ_project_box) */
    const float eps = SL_MARGIN_RECT_PX;
    int32_t w = (int32_t)v->width, hgt = (int32_t)v->height;
    r->x0 = clamp_i(floor_clamped(minx - eps, w), w);
    r->x1 = clamp_i(floor_clamped(maxx + eps, w) + 1, w);
    r->y0 = clamp_i(floor_clamped(miny - eps, hgt), hgt);
    r->y1 = clamp_i(floor_clamped(maxy + eps, hgt) + 1, hgt);
    if (r->x0 >= r->x1 || r->y0 >= r->y1)
        return SL_OCC_OUT;
    r->dnear = dn + fabsf(dn) * SL_MARGIN_REL_F;
    return SL_OCC_RECT;
#else
    (void)fv;
    return sl_occ_project_box(v, b, r);
#endif
}

typedef struct frame {
    plp_state *s;
    const sl_occ_view *v;
    uint32_t *out, k;
    uint64_t tris;
    bool test_objects;          /* the conservative phase tests each object first */
    fast_view fv;
} frame;

/* Is a box in the view pyramid? Perspective: side and far planes only (the cells between the eye
 * and the near plane carry rays too); orthographic: all six. */
static bool in_view(const frame *f, const sl_aabb *b)
{
    return fast_in_planes(&f->fv, b, f->v->ortho);
}

/* Does the rasterizer show any part of box b? (visible, crossing the near plane, or unknown) */
static bool box_visible(frame *f, const sl_aabb *b)
{
    sl_occ_rect r;
    int k = fast_project_box(&f->fv, f->v, b, &r);
    if (k == SL_OCC_NEAR)
        return true;
    if (k == SL_OCC_OUT)
        return false;
    return sl_occ_raster_test(&f->s->r, r.x0, r.y0, r.x1, r.y1, r.dnear) == SL_RASTER_VISIBLE;
}

static void report(frame *f, uint32_t o)
{
    plp_state *s = f->s;
    if (s->ostamp[o] == s->frame_id || s->hstamp[o] == s->frame_id)
        return;
    const sl_aabb *ob = &sl_scene_object_bounds_array(s->scene)[o];
    if (!fast_in_planes(&f->fv, ob, true)) {
        s->hstamp[o] = s->frame_id; /* outside the view: never drawn, whichever cell lists it again */
        return;
    }
    if (f->test_objects) {
        s->object_tests++;
        if (!box_visible(f, ob)) {
            s->hstamp[o] = s->frame_id; /* hidden now: hidden for good (the buffer's occluders stay valid) */
            return;
        }
    }
    s->ostamp[o] = s->frame_id;
    f->out[f->k++] = o;
    f->tris += sl_scene_meshes(s->scene)[sl_scene_objects(s->scene)[o].mesh].triangle_count;
    uint32_t p = s->occ->object_proxy[o];
    if (p != SL_NONE && sl_occ_usable(s->occ, p, f->v) && sl_occ_quality(s->occ, p, f->v) >= s->cfg.c.min_quality)
        sl_occ_raster_render(&s->r, s->occ, f->v, &p, 1);
}

static void project(frame *f, uint32_t c)
{
    plp_state *s = f->s;
    s->cstate[c] = 2;
    s->cells_projected++;
    const plp_cell *cl = &s->cells[c];
    for (uint32_t i = cl->obj_first; i < cl->obj_first + cl->obj_count; i++)
        report(f, s->members[i].object);
    for (uint32_t i = s->dyn_first[c]; i < s->dyn_first[c + 1]; i++)
        report(f, s->dyn[i].object);
}

/* Solidity of the neighbour reached from projected cell a through face direction dir. */
static float solidity(const plp_state *s, const sl_occ_view *v, uint32_t a, uint8_t dir)
{
    int axis = dir >> 1;
    float sign = (dir & 1) ? 1.0f : -1.0f;
    const float fw[3] = {v->fwd.x, v->fwd.y, v->fwd.z};
    float vdotn = fw[axis] * sign;
    float rho = (float)s->cells[a].tris / s->rho_max + vdotn * s->rho[a];
    if (rho < 0)
        rho = 0;
    /* star-shaped: the eye on a's side of the shared face (or the view moving through it) */
    const sl_aabb *ab = &s->cells[a].box;
    float face = (dir & 1) ? (&ab->max.x)[axis] : (&ab->min.x)[axis];
    float e = (&v->eye.x)[axis];
    bool star = v->ortho ? vdotn > 0 : ((dir & 1) ? e <= face : e >= face);
    return star ? rho : 2.0f * rho + 0.5f;
}

/* Expand the neighbours of projected cell c into the front, by solidity. (The conservative phase
 * tests a cell when it leaves the front, against the buffer as it is then, rather than when it
 * enters: the same cells are dropped, each tested once, with more occluders rendered.) */
static void expand(frame *f, uint32_t c)
{
    plp_state *s = f->s;
    const plp_cell *cl = &s->cells[c];
    for (uint32_t i = cl->nb_first; i < cl->nb_first + cl->nb_count; i++) {
        uint32_t b = s->nb[i];
        uint8_t st = s->cstate[b];
        if (st >= 2)
            continue;
        if (st == 0 && !in_view(f, &s->cells[b].box)) {
            s->cstate[b] = 3;
            continue;
        }
        float rho = solidity(s, f->v, c, s->nb_dir[i]);
        if (st == 0 || rho < s->rho[b]) {
            s->rho[b] = rho;
            s->cstate[b] = 1;
            heap_push(s, rho, b);
        }
    }
}

/* Seed cells: the eye's cell, or the boundary and near-rectangle cells (see the file comment). */
static uint32_t seed(plp_state *s, const frame *f)
{
    const sl_occ_view *v = f->v;
    uint32_t n = 0;
    uint32_t eye = v->ortho ? SL_NONE : find_leaf(s, v->eye);
    if (eye != SL_NONE) {
        s->seeds[n++] = eye;
        return n;
    }
    for (uint32_t c = 0; c < s->cell_count; c++)
        if (s->cells[c].boundary && in_view(f, &s->cells[c].box))
            s->seeds[n++] = c;
    if (v->ortho) {
        /* the near rectangle: the cells its box meets */
        sl_aabb q = sl_aabb_empty();
        for (int i = 0; i < 4; i++)
            sl_aabb_grow(&q, v->fr.corners[i]);
        for (uint32_t c = 0; c < s->cell_count; c++)
            if (!s->cells[c].boundary && overlap(&s->cells[c].box, &q))
                s->seeds[n++] = c;
    }
    return n;
}

static sl_status plp_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                          sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    plp_state *s = state;
    double t0 = sl_now();
    sl_occ_view v;
    sl_occ_view_init(&v, view);
    sl_status st = sl_occ_raster_begin(&s->r, &v, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", name_of(s));
        return st;
    }
    if (++s->frame_id == 0) {
        memset(s->ostamp, 0, (size_t)s->object_count * sizeof(uint32_t));
        memset(s->hstamp, 0, (size_t)s->object_count * sizeof(uint32_t));
        s->frame_id = 1;
    }
    memset(s->cstate, 0, s->cell_count);
    s->heap_n = 0;
    s->order = 0;
    s->cells_projected = s->cell_tests = s->object_tests = 0;
    frame f = {.s = s, .v = &v, .out = out};
    fast_view_init(&f.fv, &v);
    uint32_t ns = seed(s, &f);
    for (uint32_t i = 0; i < ns; i++) {
        uint32_t c = s->seeds[i];
        if (s->cstate[c] == 0) {
            s->rho[c] = 0;
            s->cstate[c] = 1;
            heap_push(s, 0, c);
        }
    }
    /* 1. PLP: the least solid cell first, until the budget */
    while (s->heap_n && f.tris < s->cfg.c.budget) {
        float rho;
        uint32_t c = heap_pop(s, &rho);
        if (s->cstate[c] != 1 || rho != s->rho[c])
            continue; /* projected already, or a stale entry */
        project(&f, c);
        expand(&f, c);
    }
    double t1 = sl_now();
    /* 2. cPLP: test the remaining front; project what is visible until the front is empty */
    if (s->cfg.conservative) {
        f.test_objects = true;
        while (s->heap_n) {
            float rho;
            uint32_t c = heap_pop(s, &rho);
            if (s->cstate[c] != 1 || rho != s->rho[c])
                continue;
            s->cell_tests++;
            if (!box_visible(&f, &s->cells[c].box)) {
                s->cstate[c] = 3;
                continue;
            }
            project(&f, c);
            expand(&f, c);
        }
    }
    /* moving objects beyond the octree: reported (plp) or tested (cplp) on their own */
    for (uint32_t i = 0; i < s->outside_count; i++)
        report(&f, s->outside[i]);
    double t2 = sl_now();
    sl_cull_sort_ids(out, f.k, s->sort_scratch);
    double t3 = sl_now();
    stats->nodes_visited = s->cells_projected;
    stats->objects_tested = s->object_tests;
    stats->occlusion_tests = s->cell_tests + s->object_tests;
    stats->queries = s->r.queries;
    stats->pixel_queries = s->r.pixel_queries;
    sl_cull_phase(stats, "plp", sl_cull_ms(t0, t1));
    if (s->cfg.conservative)
        sl_cull_phase(stats, "complete", sl_cull_ms(t1, t2));
    sl_cull_phase(stats, "sort", sl_cull_ms(t2, t3));
    *count = f.k;
    if ((st = sl_occ_raster_end(&s->r, NULL, err)) != SL_OK)
        sl_error_prefix(err, "%s", name_of(s));
    return st;
}

const sl_cull_method sl_cull_method_plp = {
    .name = "plp",
    .suits = "dense scenes where a time budget matters more than exactness (aggressive)",
    .summary = "prioritized-layered projection: octree cells projected by solidity from the eye until a "
               "triangle budget (aggressive; Klosowski & Silva 2000)",
    .options_help = g_help_plp,
    .guarantee = SL_AGGRESSIVE,
    .depth = SL_DEPTH_INV_W,
    .config_size = sizeof(plp_config),
    .configure = plp_configure,
    .create = plp_create,
    .cull = plp_cull,
    .scene_changed = plp_scene_changed,
    .destroy = plp_destroy,
};

const sl_cull_method sl_cull_method_cplp = {
    .name = "cplp",
    .suits = "dense scenes of many small occluders (octree cells by solidity)",
    .summary = "conservative PLP: after the budget, the front of octree cells is tested against the "
               "rasterizer until empty (Klosowski & Silva 2001)",
    .options_help = g_help_cplp,
    .guarantee = SL_CONSERVATIVE,
    .res_culling = true,
    .depth = SL_DEPTH_INV_W,
    .config_size = sizeof(plp_config),
    .configure = cplp_configure,
    .create = plp_create,
    .cull = plp_cull,
    .scene_changed = plp_scene_changed,
    .destroy = plp_destroy,
};

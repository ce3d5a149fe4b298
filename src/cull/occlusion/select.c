/* Occluder selection (Coorg & Teller, "Real-time occlusion culling for models with large
 * occluders", I3D 1997, section 3: the quality metric -A (N.V) / |D|^2): per-node area bounds and
 * the walk choosing the frame's best occluders (select.h). */
#include "select.h"

#include "walk.h"

#include <math.h>

float sl_occ_quality(const sl_occ_set *s, uint32_t proxy, const sl_occ_view *v)
{
    const sl_occ_proxy *p = &s->proxies[proxy];
    if (p->kind == SL_OCC_PRISM) {
        float q = 0;
        for (uint32_t i = 0; i < p->face_count; i++) {
            const sl_occ_face *f = &s->faces[p->face_first + i];
            float dx = f->centre.x - v->eye.x, dy = f->centre.y - v->eye.y, dz = f->centre.z - v->eye.z;
            float d2 = dx * dx + dy * dy + dz * dz;
            if (!(d2 > 1e-6f))
                continue;
            float ndv = (f->normal.x * dx + f->normal.y * dy + f->normal.z * dz) / sqrtf(d2);
            if (ndv < 0)
                q += -f->area * ndv / d2;
        }
        return q;
    }
    sl_aabb b = sl_occ_proxy_box(s, p);
    float dx = 0.5f * (b.min.x + b.max.x) - v->eye.x, dy = 0.5f * (b.min.y + b.max.y) - v->eye.y;
    float dz = 0.5f * (b.min.z + b.max.z) - v->eye.z;
    float r2 = 0.25f * ((b.max.x - b.min.x) * (b.max.x - b.min.x) + (b.max.y - b.min.y) * (b.max.y - b.min.y) +
                        (b.max.z - b.min.z) * (b.max.z - b.min.z));
    float d2 = sl_occ_maxf(dx * dx + dy * dy + dz * dz, sl_occ_maxf(r2, 1e-6f));
    return p->area / d2;
}

void sl_occ_node_areas(const sl_occ_set *s, const struct sl_bvh_t *bvh, float *node_area)
{
    for (uint32_t i = bvh->node_slots; i-- > 0;) {
        const sl_bvh_node *n = &bvh->nodes[i];
        float a = 0;
        if (i == 1 && bvh->node_slots > 1 && bvh->nodes[0].count == 0) {
            node_area[i] = 0; /* padding slot */
            continue;
        }
        if (n->count) {
            for (uint32_t j = n->first; j < n->first + n->count; j++) {
                uint32_t p = s->object_proxy[bvh->objects[j]];
                if (p != SL_NONE)
                    a = sl_occ_maxf(a, s->proxies[p].area);
            }
        } else {
            a = sl_occ_maxf(node_area[n->first], node_area[n->first + 1]);
        }
        node_area[i] = a;
    }
}

/* Min-heap by quality of the best candidates so far. */
static void heap_push(sl_occ_pick *h, uint32_t *n, uint32_t cap, sl_occ_pick x)
{
    if (*n == cap) {
        if (x.quality <= h[0].quality)
            return;
        /* replace the worst and sift down */
        uint32_t i = 0;
        for (;;) {
            uint32_t l = 2 * i + 1, r = l + 1, m = i;
            float mq = x.quality;
            if (l < *n && h[l].quality < mq)
                m = l, mq = h[l].quality;
            if (r < *n && h[r].quality < mq)
                m = r;
            if (m == i)
                break;
            h[i] = h[m];
            i = m;
        }
        h[i] = x;
        return;
    }
    uint32_t i = (*n)++;
    while (i > 0 && h[(i - 1) / 2].quality > x.quality) {
        h[i] = h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h[i] = x;
}

static void consider(const sl_occ_set *s, const sl_occ_view *v, uint32_t p, float min_quality, sl_occ_pick *heap,
                     uint32_t *hn, uint32_t cap)
{
    /* twice the half area over the squared distance to the box bounds every face's -A(N.V)/|D|^2
     * summed: skip the exact sum when that cannot beat the worst kept so far */
    sl_aabb b = sl_occ_proxy_box(s, &s->proxies[p]);
    const float e[3] = {v->eye.x, v->eye.y, v->eye.z};
    float d2 = sl_bvh_dist2(&b, e);
    if (d2 > 0) {
        float bound = 2.0f * s->proxies[p].area / d2;
        if (bound < min_quality || (*hn == cap && bound <= heap[0].quality))
            return;
    }
    if (!sl_occ_usable(s, p, v))
        return;
    float q = sl_occ_quality(s, p, v);
    if (q >= min_quality && q > 0)
        heap_push(heap, hn, cap, (sl_occ_pick){p, q});
}

/* The selection's walk: prunes nodes whose proxies cannot qualify, offers every proxy reached. */
typedef struct select_walk {
    const sl_occ_set *s;
    const sl_occ_view *v;
    const float *node_area;
    float min_quality;
    sl_occ_pick *heap;
    uint32_t hn, cap;
    float e[3];
} select_walk;

static bool select_skip(void *ctx, uint32_t slot, const sl_aabb *box)
{
    select_walk *w = ctx;
    if (slot == SL_NONE)
        return false; /* objects: consider() prunes them */
    if (!(w->node_area[slot] > 0))
        return true;
    /* no quality below this node can reach min_quality, or beat the worst kept once the heap is
     * full (the walk goes near to far, so it fills with good ones early) */
    float d2 = sl_bvh_dist2(box, w->e), bound = 2.0f * w->node_area[slot];
    return !(d2 <= 0 || (bound >= w->min_quality * d2 && !(w->hn == w->cap && bound <= w->heap[0].quality * d2)));
}

static void select_visit(void *ctx, uint32_t object, const sl_aabb *box)
{
    (void)box;
    select_walk *w = ctx;
    uint32_t p = w->s->object_proxy[object];
    if (p != SL_NONE)
        consider(w->s, w->v, p, w->min_quality, w->heap, &w->hn, w->cap);
}

uint32_t sl_occ_select(const sl_occ_set *s, const sl_occ_view *v, const struct sl_bvh_t *bvh, const float *node_area,
                       uint32_t max_count, uint32_t tri_budget, float min_quality, sl_occ_pick *heap,
                       sl_occ_pick *out, uint64_t *nodes_visited)
{
    if (max_count == 0 || s->proxy_count == 0)
        return 0;
    select_walk sw = {s, v, node_area, min_quality, heap, 0, max_count, {v->eye.x, v->eye.y, v->eye.z}};
    sl_occ_walk w = {select_skip, select_visit, &sw, NULL, 0};
    uint64_t visited = sl_occ_walk_bvh(bvh, v, &w, NULL);
    uint32_t hn = sw.hn;
    /* proxies that belong to no object are not in the tree */
    for (uint32_t p = 0; p < s->proxy_count; p++) {
        if (s->proxies[p].object != SL_NONE)
            continue;
        sl_aabb b = s->proxies[p].box;
        if (sl_occ_frustum_classify(v, &b, 0x3f) >= 0)
            consider(s, v, p, min_quality, heap, &hn, max_count);
    }
    if (nodes_visited)
        *nodes_visited += visited;
    /* heap sort: best first */
    uint32_t n = hn;
    while (n > 1) {
        sl_occ_pick top = heap[0], x = heap[n - 1];
        n--;
        uint32_t i = 0;
        for (;;) {
            uint32_t l = 2 * i + 1, r = l + 1, m = i;
            float mq = x.quality;
            if (l < n && heap[l].quality < mq)
                m = l, mq = heap[l].quality;
            if (r < n && heap[r].quality < mq)
                m = r;
            if (m == i)
                break;
            heap[i] = heap[m];
            i = m;
        }
        heap[i] = x;
        heap[n] = top;
    }
    /* heap[0..hn) is now in decreasing quality; keep what fits in the budget */
    uint32_t k = 0;
    uint64_t tris = 0;
    for (uint32_t i = 0; i < hn; i++) {
        uint32_t t = s->proxies[heap[i].proxy].triangles;
        if (tris + t > tri_budget)
            continue;
        tris += t;
        out[k++] = heap[i];
    }
    /* render order: nearest first. The rasterizer merges two depth layers per block and keeps the
     * nearer one when they differ a lot, so front-to-back submission keeps the most occlusion;
     * the distance rides in the quality field from here on (insertion sort: k is small) */
    for (uint32_t i = 0; i < k; i++) {
        sl_aabb b = sl_occ_proxy_box(s, &s->proxies[out[i].proxy]);
        out[i].quality = sl_bvh_dist2(&b, sw.e);
    }
    for (uint32_t i = 1; i < k; i++) {
        sl_occ_pick x = out[i];
        uint32_t j = i;
        for (; j > 0 && out[j - 1].quality > x.quality; j--)
            out[j] = out[j - 1];
        out[j] = x;
    }
    return k;
}

/* Splitting a triangle soup into spatially compact pieces: recursive quantile cuts of triangle
 * centroids along the longest axis (a kd-tree built top-down until every leaf is small enough).
 * See split.h for the contract. */
#include "split.h"

#include <stdlib.h>

/* Task stack depth: k halves at every level and k < 2^32, so at most 33 levels, each leaving one
 * pending right side behind. */
#define SPLIT_STACK 80

/* A range of the triangle order still to be cut into k pieces. */
typedef struct split_task {
    uint32_t begin, end;
    uint32_t k;
} split_task;

/* The key a triangle is ordered by along one axis; ties go to the lower triangle index so that
 * every triangle has a distinct key and the partition is fully determined by the input. */
static inline bool key_less(const float *cent, int axis, uint32_t a, uint32_t b)
{
    float ka = cent[3 * (size_t)a + axis], kb = cent[3 * (size_t)b + axis];
    return ka < kb || (ka == kb && a < b);
}

typedef struct sort_ctx {
    const float *cent;
    int axis;
} sort_ctx;

static int cmp_key(const void *pa, const void *pb, void *user)
{
    const sort_ctx *c = user;
    uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    return key_less(c->cent, c->axis, a, b) ? -1 : key_less(c->cent, c->axis, b, a) ? 1 : 0;
}

static inline void swap_u32(uint32_t *a, uint32_t *b)
{
    uint32_t t = *a;
    *a = *b;
    *b = t;
}

/* Reorder ord[0..n) so that ord[m] holds the element of rank m and everything before it is
 * smaller (quickselect with a median-of-three pivot). Falls back to a full sort when the
 * partitions stop shrinking, which bounds the worst case at O(n log n). */
static void select_rank(uint32_t *ord, uint32_t n, uint32_t m, const float *cent, int axis)
{
    uint32_t lo = 0, hi = n - 1;
    int budget = 64;
    while (lo < hi) {
        if (budget-- == 0) {
            sort_ctx c = {cent, axis};
            qsort_r(ord + lo, hi - lo + 1, sizeof *ord, cmp_key, &c);
            return;
        }
        uint32_t mid = lo + (hi - lo) / 2;
        /* order lo, mid, hi; the median lands in mid and serves as the pivot */
        if (key_less(cent, axis, ord[mid], ord[lo]))
            swap_u32(&ord[mid], &ord[lo]);
        if (key_less(cent, axis, ord[hi], ord[lo]))
            swap_u32(&ord[hi], &ord[lo]);
        if (key_less(cent, axis, ord[hi], ord[mid]))
            swap_u32(&ord[hi], &ord[mid]);
        uint32_t pivot = ord[mid];
        swap_u32(&ord[mid], &ord[hi]);
        uint32_t store = lo;
        for (uint32_t i = lo; i < hi; i++)
            if (key_less(cent, axis, ord[i], pivot))
                swap_u32(&ord[i], &ord[store++]);
        swap_u32(&ord[store], &ord[hi]);
        /* keys are distinct, so the pivot sits at its final rank */
        if (store == m)
            return;
        if (m < store)
            hi = store - 1;
        else
            lo = store + 1;
    }
}

void sl_split_free(const sl_allocator *a, sl_split_result *r)
{
    if (!r)
        return;
    sl_free(a, r->pieces, (size_t)r->piece_count * sizeof *r->pieces);
    sl_free(a, r->positions, (size_t)r->vertex_count * 3 * sizeof(float));
    sl_free(a, r->normals, (size_t)r->vertex_count * 3 * sizeof(float));
    sl_free(a, r->indices, (size_t)r->triangle_count * 3 * sizeof(uint32_t));
    sl_free(a, r->source_triangle, (size_t)r->triangle_count * sizeof(uint32_t));
    memset(r, 0, sizeof *r);
}

/* Cut the triangle order into leaves; leaf_of[t] receives the leaf of triangle t. Leaves are
 * numbered left to right along the cuts, so nearby leaves are nearby in space too. */
static uint32_t build_leaves(uint32_t *ord, uint32_t nt, uint32_t target, const float *cent, uint32_t *leaf_of,
                             split_task *stack)
{
    uint32_t leaves = 0, top = 0;
    /* n <= k * target holds for every task: the root by the choice of k, children because each
     * side gets floor or ceil of its proportional share */
    stack[top++] = (split_task){0, nt, (uint32_t)(((uint64_t)nt + target - 1) / target)};
    while (top) {
        split_task t = stack[--top];
        uint32_t n = t.end - t.begin;
        if (t.k <= 1 || n <= 1 || top + 2 > SPLIT_STACK) {
            for (uint32_t i = t.begin; i < t.end; i++)
                leaf_of[ord[i]] = leaves;
            leaves++;
            continue;
        }
        float lo[3] = {cent[3 * (size_t)ord[t.begin]], cent[3 * (size_t)ord[t.begin] + 1], cent[3 * (size_t)ord[t.begin] + 2]};
        float hi[3] = {lo[0], lo[1], lo[2]};
        for (uint32_t i = t.begin; i < t.end; i++)
            for (int c = 0; c < 3; c++) {
                float v = cent[3 * (size_t)ord[i] + c];
                lo[c] = v < lo[c] ? v : lo[c];
                hi[c] = v > hi[c] ? v : hi[c];
            }
        int axis = 0;
        for (int c = 1; c < 3; c++)
            if (hi[c] - lo[c] > hi[axis] - lo[axis])
                axis = c;
        uint32_t kl = t.k / 2;
        uint32_t m = (uint32_t)((uint64_t)n * kl / t.k); /* rank of the first triangle on the right */
        select_rank(ord + t.begin, n, m, cent, axis);
        /* right first so that the left side is taken (and numbered) first */
        stack[top++] = (split_task){t.begin + m, t.end, t.k - kl};
        stack[top++] = (split_task){t.begin, t.begin + m, kl};
    }
    return leaves;
}

sl_status sl_split_mesh(const float *pos, const float *nrm, uint32_t nv, const uint32_t *idx, uint32_t nt, uint32_t target,
                        const sl_allocator *a, sl_split_result *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_split_mesh: out is NULL");
    memset(out, 0, sizeof *out);
    if ((nv && !pos) || (nt && !idx) || target == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_split_mesh: NULL array or zero target");
    for (uint64_t i = 0; i < 3ull * nt; i++)
        if (idx[i] >= nv)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_split_mesh: triangle %llu: index %u out of range (%u vertices)",
                           (unsigned long long)(i / 3), idx[i], nv);
    for (uint32_t v = 0; v < nv; v++)
        if (!sl_finite3(pos + 3 * (size_t)v))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_split_mesh: vertex %u: position is not finite", v);
    if (nt == 0)
        return SL_OK;

    sl_status st = SL_OK;
    size_t nt3 = 3 * (size_t)nt;
    float *cent = sl_alloc(a, nt3 * sizeof(float));
    uint32_t *ord = sl_alloc(a, (size_t)nt * sizeof(uint32_t));
    uint32_t *leaf_of = sl_alloc(a, (size_t)nt * sizeof(uint32_t));
    uint32_t *remap = sl_alloc(a, (nv ? (size_t)nv : 1) * sizeof(uint32_t));
    uint32_t *stamp = sl_alloc(a, (nv ? (size_t)nv : 1) * sizeof(uint32_t));
    split_task *stack = sl_alloc(a, SPLIT_STACK * sizeof(split_task));
    uint32_t *leaf_start = NULL;
    uint32_t leaves = 0;
    if (!cent || !ord || !leaf_of || !remap || !stamp || !stack) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_split_mesh: out of memory (%u triangles)", nt);
        goto done;
    }
    for (uint32_t t = 0; t < nt; t++) {
        const uint32_t *tri = idx + 3 * (size_t)t;
        for (int c = 0; c < 3; c++)
            cent[3 * (size_t)t + c] = (pos[3 * (size_t)tri[0] + c] + pos[3 * (size_t)tri[1] + c] + pos[3 * (size_t)tri[2] + c]) / 3.0f;
        ord[t] = t;
    }
    leaves = build_leaves(ord, nt, target, cent, leaf_of, stack);

    /* stable bucket sort by leaf: each piece keeps its triangles in input order */
    leaf_start = sl_calloc(a, (size_t)leaves + 1, sizeof(uint32_t));
    out->pieces = sl_calloc(a, leaves, sizeof *out->pieces);
    if (!leaf_start || !out->pieces) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_split_mesh: out of memory (%u pieces)", leaves);
        goto done;
    }
    out->piece_count = leaves;
    for (uint32_t t = 0; t < nt; t++)
        leaf_start[leaf_of[t] + 1]++;
    for (uint32_t l = 0; l < leaves; l++)
        leaf_start[l + 1] += leaf_start[l];
    for (uint32_t t = 0; t < nt; t++)
        ord[leaf_start[leaf_of[t]]++] = t;
    /* leaf_start[l] now holds the end of leaf l; shift back to starts */
    for (uint32_t l = leaves; l > 0; l--)
        leaf_start[l] = leaf_start[l - 1];
    leaf_start[0] = 0;

    /* first pass: vertices per piece (a vertex shared by two pieces is counted in both);
     * stamp[v] == l marks vertex v as already seen in piece l */
    for (uint32_t v = 0; v < nv; v++)
        stamp[v] = UINT32_MAX;
    uint64_t total_vertices = 0;
    for (uint32_t l = 0; l < leaves; l++) {
        uint32_t count = 0;
        for (uint32_t i = leaf_start[l]; i < leaf_start[l + 1]; i++)
            for (int c = 0; c < 3; c++) {
                uint32_t v = idx[3 * (size_t)ord[i] + c];
                if (stamp[v] != l) {
                    stamp[v] = l;
                    count++;
                }
            }
        sl_split_piece *p = &out->pieces[l];
        p->first_triangle = leaf_start[l];
        p->triangle_count = leaf_start[l + 1] - leaf_start[l];
        p->first_vertex = (uint32_t)SL_MIN(total_vertices, UINT32_MAX);
        p->vertex_count = count;
        total_vertices += count;
    }
    if (total_vertices > UINT32_MAX) {
        st = sl_fail(err, SL_ERROR_LIMIT, "sl_split_mesh: %llu vertices after splitting, more than 2^32-1",
                     (unsigned long long)total_vertices);
        goto done;
    }
    out->vertex_count = (uint32_t)total_vertices;
    out->triangle_count = nt;
    size_t vbytes = (size_t)total_vertices * 3 * sizeof(float);
    out->positions = sl_alloc(a, vbytes ? vbytes : 1);
    out->normals = nrm ? sl_alloc(a, vbytes ? vbytes : 1) : NULL;
    out->indices = sl_alloc(a, nt3 * sizeof(uint32_t));
    out->source_triangle = sl_alloc(a, (size_t)nt * sizeof(uint32_t));
    if (!out->positions || (nrm && !out->normals) || !out->indices || !out->source_triangle) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_split_mesh: out of memory (%llu vertices)", (unsigned long long)total_vertices);
        goto done;
    }

    /* second pass: copy vertices in order of first use, rewrite indices to the piece */
    for (uint32_t v = 0; v < nv; v++)
        stamp[v] = UINT32_MAX;
    for (uint32_t l = 0; l < leaves; l++) {
        sl_split_piece *p = &out->pieces[l];
        uint32_t local = 0;
        sl_aabb box = sl_aabb_empty();
        float *dst_pos = out->positions + 3 * (size_t)p->first_vertex;
        float *dst_nrm = nrm ? out->normals + 3 * (size_t)p->first_vertex : NULL;
        for (uint32_t i = p->first_triangle; i < p->first_triangle + p->triangle_count; i++) {
            uint32_t t = ord[i];
            out->source_triangle[i] = t;
            for (int c = 0; c < 3; c++) {
                uint32_t v = idx[3 * (size_t)t + c];
                if (stamp[v] != l) {
                    stamp[v] = l;
                    remap[v] = local;
                    const float *src = pos + 3 * (size_t)v;
                    memcpy(dst_pos + 3 * (size_t)local, src, 3 * sizeof(float));
                    if (dst_nrm)
                        memcpy(dst_nrm + 3 * (size_t)local, nrm + 3 * (size_t)v, 3 * sizeof(float));
                    sl_aabb_grow(&box, (sl_vec3){src[0], src[1], src[2]});
                    local++;
                }
                out->indices[3 * (size_t)i + c] = remap[v];
            }
        }
        p->bounds = box;
    }

done:
    sl_free(a, cent, nt3 * sizeof(float));
    sl_free(a, ord, (size_t)nt * sizeof(uint32_t));
    sl_free(a, leaf_of, (size_t)nt * sizeof(uint32_t));
    sl_free(a, remap, (nv ? (size_t)nv : 1) * sizeof(uint32_t));
    sl_free(a, stamp, (nv ? (size_t)nv : 1) * sizeof(uint32_t));
    sl_free(a, stack, SPLIT_STACK * sizeof(split_task));
    sl_free(a, leaf_start, ((size_t)leaves + 1) * sizeof(uint32_t));
    if (st != SL_OK)
        sl_split_free(a, out);
    return st;
}

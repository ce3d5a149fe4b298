/* The region oracle: which objects are visible from anywhere in a view cell? Estimated by dense
 * sampling — every sample point renders a cube map with the exact point oracle (oracle.c) and the
 * union of the visible sets is the answer. It is a LOWER BOUND of the exact from-region set: what
 * is visible only from between the samples, or only through a gap thinner than a cube-map pixel,
 * is not found. Conservative PVS methods are held to it: every object it finds must be in their
 * set (docs/pvs.md, "Verification").
 *
 * Samples (deterministic functions of the options, the cell and the seed):
 *  - the cell's vertices, and points along every edge at most edge_spacing apart (for a prism the
 *    top edges are where the thesis samples: section 5.3 of Wonka's thesis);
 *  - face_samples random points on the boundary faces (area-weighted);
 *  - interior_samples random points inside.
 * Every point is pulled 1 mm towards the cell's centre, so that a point never sits exactly on a
 * wall that bounds the cell (a camera on a wall's plane sees along both of its sides), and lifted
 * to at least 0.1 m above the terrain. Each point renders with a near plane below half its
 * distance to the nearest triangle (sample_near), so that no wall is clipped away in front of
 * it; a point touching a surface is skipped. The points are then shuffled, so that the last 10% rendered
 * is a fair random subset: the number of objects it adds first is the convergence figure.
 *
 * CLUSTER cells (Quake III) sample the boxes of the cluster's leaves instead (corners, centres,
 * random points), keeping the points the map's BSP puts in a leaf of the cluster.
 *
 * The rules are the point oracle's (docs/oracle.md, "One set of rules"): a sample outside the
 * domain (a BSP leaf without a cluster) is skipped and counted, and a cell all of whose samples are
 * outside is itself outside the domain (its set is empty and flagged, nothing is judged there); on
 * a map, a pixel counts only when its sight line stays in open space (open_pixels below). */
#include "sightline/region.h"
#include "sightline/truth.h"

#include "open_space.h"
#include "pvs/viewcells_internal.h"
#include "scene/scene_internal.h"

#include <math.h>

#define DEFAULT_FACE 256u
#define DEFAULT_SPACING 1.0f
#define DEFAULT_FACE_SAMPLES 24u
#define DEFAULT_INTERIOR 24u
#define DEFAULT_MAX_SAMPLES 4096u
#define HARD_MAX_SAMPLES 65536u
#define INSET 1e-3f
#define GROUND_CLEARANCE 0.1f
#define OPEN_BIT 0x80000000u

struct sl_region_oracle_t {
    sl_allocator alloc;
    sl_scene scene;
    sl_region_oracle_options opt;
    sl_oracle oracle;
    uint32_t object_count;      /* entries of max_pixels and first (objects + 1) */
    uint32_t *max_pixels;       /* per object, during a query */
    uint32_t *first;            /* per object: first sample that saw it, SL_NONE */
    uint32_t *sample_pixels;    /* per object: pixels of the current sample in open space (BSP) */
    sl_array points;            /* sl_vec3 */
    sl_array visible;           /* uint32 */
    sl_array out_pixels;        /* uint32 */
    sl_array out_first;         /* uint32 */
};

sl_status sl_region_oracle_create(sl_scene scene, const sl_region_oracle_options *opt, const sl_allocator *alloc,
                                  sl_region_oracle *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_region_oracle_create: scene and out must not be NULL");
    *out = NULL;
    sl_region_oracle_options o;
    if (opt)
        o = *opt;
    else
        memset(&o, 0, sizeof o);
    if (!o.face_size)
        o.face_size = DEFAULT_FACE;
    if (o.edge_spacing == 0)
        o.edge_spacing = DEFAULT_SPACING;
    if (!o.max_samples)
        o.max_samples = DEFAULT_MAX_SAMPLES;
    if (o.near_plane == 0)
        o.near_plane = 0.05f;
    if (!o.threads)
        o.threads = 2;
    /* zero means "default" for the sample counts only when the whole struct was defaulted */
    if (!opt) {
        o.face_samples = DEFAULT_FACE_SAMPLES;
        o.interior_samples = DEFAULT_INTERIOR;
    }
    if (!isfinite(o.edge_spacing) || !(o.edge_spacing >= 0.001f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "region oracle: edge_spacing %g must be at least 0.001 m",
                       (double)o.edge_spacing);
    if (o.max_samples > HARD_MAX_SAMPLES)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "region oracle: max_samples %u is above %u", o.max_samples,
                       HARD_MAX_SAMPLES);
    if (!isfinite(o.near_plane) || !(o.near_plane > 0) || !isfinite(o.far_plane) || o.far_plane < 0 ||
        (o.far_plane > 0 && !(o.far_plane > o.near_plane)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "region oracle: near %g and far %g must satisfy 0 < near < far",
                       (double)o.near_plane, (double)o.far_plane);
    if (o.far_plane == 0) {
        sl_aabb b = sl_scene_bounds(scene);
        double d = sl_aabb_is_empty(&b) ? 1.0
                                        : hypot(hypot((double)b.max.x - b.min.x, (double)b.max.y - b.min.y),
                                                (double)b.max.z - b.min.z);
        o.far_plane = (float)fmax(2.0 * d, 10.0 * o.near_plane);
    }
    alloc = sl_alloc_or_default(alloc);
    struct sl_region_oracle_t *r = sl_calloc(alloc, 1, sizeof *r);
    if (!r)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "region oracle: out of memory");
    r->alloc = *alloc;
    r->scene = scene;
    r->opt = o;
    sl_oracle_options po = sl_oracle_default_options();
    po.threads = o.threads;
    po.see_through_solid = true; /* the open-space rule is applied below, from each sample itself */
    sl_status st = sl_oracle_create(scene, &po, alloc, &r->oracle, err);
    if (st != SL_OK) {
        sl_free(alloc, r, sizeof *r);
        return st;
    }
    *out = r;
    return SL_OK;
}

void sl_region_oracle_destroy(sl_region_oracle r)
{
    if (!r)
        return;
    const sl_allocator *a = &r->alloc;
    sl_oracle_destroy(r->oracle);
    sl_free(a, r->max_pixels, (size_t)r->object_count * sizeof(uint32_t));
    sl_free(a, r->first, (size_t)r->object_count * sizeof(uint32_t));
    sl_free(a, r->sample_pixels, (size_t)r->object_count * sizeof(uint32_t));
    sl_array_free(a, &r->points, sizeof(sl_vec3));
    sl_array_free(a, &r->visible, sizeof(uint32_t));
    sl_array_free(a, &r->out_pixels, sizeof(uint32_t));
    sl_array_free(a, &r->out_first, sizeof(uint32_t));
    sl_free(a, r, sizeof *r);
}

/* ---- sample points ---- */

typedef struct sampler {
    struct sl_region_oracle_t *r;
    sl_rng rng;
    sl_vec3 centre;
    bool oom;
} sampler;

static void put(sampler *s, sl_vec3 p)
{
    /* pull towards the centre by INSET (never past it), keep clear of the terrain */
    double dx = (double)s->centre.x - p.x, dy = (double)s->centre.y - p.y, dz = (double)s->centre.z - p.z;
    double d = sqrt(dx * dx + dy * dy + dz * dz);
    if (d > 0) {
        double k = fmin(1.0, INSET / d);
        p.x = (float)(p.x + k * dx);
        p.y = (float)(p.y + k * dy);
        p.z = (float)(p.z + k * dz);
    }
    float g = sl_scene_ground_height(s->r->scene, p.x, p.y) + GROUND_CLEARANCE;
    sl_terrain_view tv;
    if (sl_scene_terrain(s->r->scene, &tv) && p.z < g)
        p.z = g;
    if (!sl_array_push(&s->r->alloc, &s->r->points, sizeof p, &p, 1))
        s->oom = true;
}

static sl_vec3 lerp3(sl_vec3 a, sl_vec3 b, float t)
{
    return (sl_vec3){a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)};
}

static float dist3(sl_vec3 a, sl_vec3 b)
{
    return (float)sqrt(((double)b.x - a.x) * ((double)b.x - a.x) + ((double)b.y - a.y) * ((double)b.y - a.y) +
                       ((double)b.z - a.z) * ((double)b.z - a.z));
}

/* Points strictly inside segment ab, at most `spacing` apart. */
static void edge_points(sampler *s, sl_vec3 a, sl_vec3 b, float spacing)
{
    float len = dist3(a, b);
    uint32_t n = (uint32_t)fminf(ceilf(len / spacing), 1e6f);
    for (uint32_t i = 1; i < n; i++)
        put(s, lerp3(a, b, (float)i / (float)n));
}

/* A uniform point in triangle abc. */
static sl_vec3 in_triangle(sl_rng *g, sl_vec3 a, sl_vec3 b, sl_vec3 c)
{
    float u = sl_rng_float(g), v = sl_rng_float(g);
    if (u + v > 1) {
        u = 1 - u;
        v = 1 - v;
    }
    return (sl_vec3){a.x + u * (b.x - a.x) + v * (c.x - a.x), a.y + u * (b.y - a.y) + v * (c.y - a.y),
                     a.z + u * (b.z - a.z) + v * (c.z - a.z)};
}

/* A convex polyhedron given as vertices, edges and quad/triangle faces. */
typedef struct poly {
    sl_vec3 v[8];
    int nv;
    int e[12][2];
    int ne;
    int f[6][4]; /* f[k][3] < 0: a triangle */
    int nf;
} poly;

static void prism_poly(const sl_viewcell *c, poly *p)
{
    static const int edges[9][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}};
    static const int faces[5][4] = {{0, 1, 2, -1}, {3, 4, 5, -1}, {0, 1, 4, 3}, {1, 2, 5, 4}, {2, 0, 3, 5}};
    memset(p, 0, sizeof *p);
    for (int k = 0; k < 3; k++) {
        p->v[k] = (sl_vec3){c->tri[k].x, c->tri[k].y, c->z_min};
        p->v[k + 3] = (sl_vec3){c->tri[k].x, c->tri[k].y, c->z_max};
    }
    p->nv = 6;
    memcpy(p->e, edges, sizeof edges);
    p->ne = 9;
    memcpy(p->f, faces, sizeof faces);
    p->nf = 5;
}

static void box_poly(const sl_aabb *b, poly *p)
{
    static const int edges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                     {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    static const int faces[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    memset(p, 0, sizeof *p);
    for (int i = 0; i < 8; i++)
        p->v[i] = (sl_vec3){(i & 1) ? b->max.x : b->min.x, (i & 2) ? b->max.y : b->min.y,
                            (i & 4) ? b->max.z : b->min.z};
    p->nv = 8;
    memcpy(p->e, edges, sizeof edges);
    p->ne = 12;
    memcpy(p->f, faces, sizeof faces);
    p->nf = 6;
}

static double tri_area(sl_vec3 a, sl_vec3 b, sl_vec3 c)
{
    double e1[3] = {(double)b.x - a.x, (double)b.y - a.y, (double)b.z - a.z};
    double e2[3] = {(double)c.x - a.x, (double)c.y - a.y, (double)c.z - a.z};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

/* Sample a convex polyhedron: vertices, edges, faces, interior. */
static void sample_poly(sampler *s, const poly *p, bool prism)
{
    const sl_region_oracle_options *o = &s->r->opt;
    double total_edge = 0;
    for (int k = 0; k < p->ne; k++)
        total_edge += dist3(p->v[p->e[k][0]], p->v[p->e[k][1]]);
    uint32_t fixed = (uint32_t)p->nv + o->face_samples + o->interior_samples;
    float spacing = o->edge_spacing;
    if (o->max_samples > fixed) {
        /* widen the spacing so that the edge points fit the cap */
        double room = (double)(o->max_samples - fixed);
        if (total_edge / spacing > room)
            spacing = (float)(total_edge / fmax(room, 1.0)) * 1.0001f;
    } else {
        spacing = (float)fmax(total_edge, 1.0);
    }
    for (int k = 0; k < p->nv; k++)
        put(s, p->v[k]);
    for (int k = 0; k < p->ne; k++)
        edge_points(s, p->v[p->e[k][0]], p->v[p->e[k][1]], spacing);
    /* faces split into triangles, chosen by area */
    sl_vec3 tris[12][3];
    double area[12], sum = 0;
    int nt = 0;
    for (int f = 0; f < p->nf; f++) {
        const int *q = p->f[f];
        tris[nt][0] = p->v[q[0]], tris[nt][1] = p->v[q[1]], tris[nt][2] = p->v[q[2]];
        area[nt] = tri_area(tris[nt][0], tris[nt][1], tris[nt][2]);
        sum += area[nt++];
        if (q[3] >= 0) {
            tris[nt][0] = p->v[q[0]], tris[nt][1] = p->v[q[2]], tris[nt][2] = p->v[q[3]];
            area[nt] = tri_area(tris[nt][0], tris[nt][1], tris[nt][2]);
            sum += area[nt++];
        }
    }
    for (uint32_t i = 0; i < o->face_samples && sum > 0; i++) {
        double pick = sl_rng_double(&s->rng) * sum;
        int t = 0;
        while (t < nt - 1 && pick >= area[t]) {
            pick -= area[t];
            t++;
        }
        put(s, in_triangle(&s->rng, tris[t][0], tris[t][1], tris[t][2]));
    }
    for (uint32_t i = 0; i < o->interior_samples; i++) {
        sl_vec3 q;
        if (prism) {
            q = in_triangle(&s->rng, p->v[0], p->v[1], p->v[2]);
            q.z = p->v[0].z + sl_rng_float(&s->rng) * (p->v[3].z - p->v[0].z);
        } else {
            q = (sl_vec3){p->v[0].x + sl_rng_float(&s->rng) * (p->v[7].x - p->v[0].x),
                          p->v[0].y + sl_rng_float(&s->rng) * (p->v[7].y - p->v[0].y),
                          p->v[0].z + sl_rng_float(&s->rng) * (p->v[7].z - p->v[0].z)};
        }
        put(s, q);
    }
}

/* Put p when the map's BSP puts it in `cluster`. */
static void put_in_cluster(sampler *s, sl_viewcells cells, uint32_t cell, sl_vec3 p)
{
    if (sl_viewcell_contains(cells, s->r->scene, cell, p))
        put(s, p);
}

static void sample_cluster(sampler *s, sl_viewcells cells, uint32_t cell)
{
    const sl_viewcell *c = &sl_viewcells_data(cells)[cell];
    const sl_region_oracle_options *o = &s->r->opt;
    sl_bsp_view bsp;
    if (!sl_scene_bsp(s->r->scene, &bsp))
        return;
    double vol_sum = 0;
    for (uint32_t l = 0; l < bsp.leaf_count; l++)
        if (bsp.leaves[l].cluster == c->cluster) {
            const sl_aabb *b = &bsp.leaves[l].bounds;
            vol_sum += fmax(1e-6, ((double)b->max.x - b->min.x) * ((double)b->max.y - b->min.y) *
                                      ((double)b->max.z - b->min.z));
        }
    uint32_t budget = o->face_samples + o->interior_samples;
    for (uint32_t l = 0; l < bsp.leaf_count && !s->oom; l++) {
        if (bsp.leaves[l].cluster != c->cluster)
            continue;
        const sl_aabb *b = &bsp.leaves[l].bounds;
        /* corners pulled 1% inwards, and the centre */
        sl_vec3 ctr = {0.5f * (b->min.x + b->max.x), 0.5f * (b->min.y + b->max.y), 0.5f * (b->min.z + b->max.z)};
        put_in_cluster(s, cells, cell, ctr);
        for (int i = 0; i < 8; i++) {
            sl_vec3 v = {(i & 1) ? b->max.x : b->min.x, (i & 2) ? b->max.y : b->min.y, (i & 4) ? b->max.z : b->min.z};
            put_in_cluster(s, cells, cell, lerp3(v, ctr, 0.01f));
        }
        double vol = fmax(1e-6, ((double)b->max.x - b->min.x) * ((double)b->max.y - b->min.y) *
                                    ((double)b->max.z - b->min.z));
        uint32_t n = (uint32_t)ceil(budget * vol / vol_sum);
        /* random tries; points outside the cluster (solid, other leaves) are dropped */
        for (uint32_t i = 0; i < 4 * n; i++) {
            sl_vec3 q = {b->min.x + sl_rng_float(&s->rng) * (b->max.x - b->min.x),
                         b->min.y + sl_rng_float(&s->rng) * (b->max.y - b->min.y),
                         b->min.z + sl_rng_float(&s->rng) * (b->max.z - b->min.z)};
            put_in_cluster(s, cells, cell, q);
        }
    }
}

sl_status sl_region_oracle_points(sl_region_oracle r, sl_viewcells cells, uint32_t cell, const sl_vec3 **points,
                                  uint32_t *count, sl_error *err)
{
    if (!r || !cells || !points || !count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_region_oracle_points: arguments must not be NULL");
    *points = NULL;
    *count = 0;
    if (cell >= sl_viewcells_count(cells))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "region oracle: cell %u does not exist (%u cells)", cell,
                       sl_viewcells_count(cells));
    const sl_viewcell *c = &sl_viewcells_data(cells)[cell];
    sampler s;
    memset(&s, 0, sizeof s);
    s.r = r;
    sl_rng_seed(&s.rng, r->opt.seed, 0x9e3779b97f4a7c15ull ^ cell);
    r->points.count = 0;
    poly p;
    if (c->shape == SL_CELL_PRISM) {
        prism_poly(c, &p);
        s.centre = (sl_vec3){(c->tri[0].x + c->tri[1].x + c->tri[2].x) / 3, (c->tri[0].y + c->tri[1].y + c->tri[2].y) / 3,
                             0.5f * (c->z_min + c->z_max)};
        sample_poly(&s, &p, true);
    } else if (c->shape == SL_CELL_BOX) {
        box_poly(&c->bounds, &p);
        s.centre = (sl_vec3){0.5f * (c->bounds.min.x + c->bounds.max.x), 0.5f * (c->bounds.min.y + c->bounds.max.y),
                             0.5f * (c->bounds.min.z + c->bounds.max.z)};
        sample_poly(&s, &p, false);
    } else {
        /* leaf samples are already inside: no pull */
        s.centre = (sl_vec3){NAN, NAN, NAN};
        sample_cluster(&s, cells, cell);
    }
    if (s.oom)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "region oracle: out of memory for the sample points");
    /* Fisher-Yates: a random interleaving, so that every tenth of the order is a fair subset */
    sl_vec3 *pts = r->points.data;
    uint32_t n = (uint32_t)r->points.count;
    for (uint32_t i = n; i > 1; i--) {
        uint32_t j = sl_rng_below(&s.rng, i);
        sl_vec3 t = pts[i - 1];
        pts[i - 1] = pts[j];
        pts[j] = t;
    }
    if (n > r->opt.max_samples)
        n = r->opt.max_samples;
    *points = pts;
    *count = n;
    return SL_OK;
}

/* ---- the near plane of each sample ---- */

/* Squared distance from p to triangle abc (the closest-point regions of Ericson, "Real-Time
 * Collision Detection", 5.1.5), in double. */
static double tri_dist2(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k], ac[k] = c[k] - a[k];
        ap[k] = p[k] - a[k], bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
    }
#define DOT3(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT3(ab, ap), d2 = DOT3(ac, ap), d3 = DOT3(ab, bp), d4 = DOT3(ac, bp);
    double d5 = DOT3(ab, cp), d6 = DOT3(ac, cp);
#undef DOT3
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    double u, v; /* q = a + u ab + v ac */
    if (d1 <= 0 && d2 <= 0)
        u = 0, v = 0;
    else if (d3 >= 0 && d4 <= d3)
        u = 1, v = 0;
    else if (d6 >= 0 && d5 <= d6)
        u = 0, v = 1;
    else if (vc <= 0 && d1 >= 0 && d3 <= 0)
        u = d1 / (d1 - d3), v = 0;
    else if (vb <= 0 && d2 >= 0 && d6 <= 0)
        u = 0, v = d2 / (d2 - d6);
    else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        u = 1 - w, v = w;
    } else {
        double den = va + vb + vc;
        if (!(den > 0)) /* a degenerate triangle covers no pixel: it hides nothing when clipped */
            return INFINITY;
        u = vb / den, v = vc / den;
    }
    double d2sum = 0;
    for (int k = 0; k < 3; k++) {
        q[k] = p[k] - (a[k] + u * ab[k] + v * ac[k]);
        d2sum += q[k] * q[k];
    }
    return d2sum;
}

/* Distance from p to the nearest triangle of the scene, or `limit` when none is nearer. Objects
 * are rejected by their world boxes first, triangles by their own boxes. */
static double clearance(const struct sl_region_oracle_t *r, sl_vec3 p, double limit)
{
    const struct sl_scene_t *s = r->scene;
    const sl_aabb *boxes = sl_scene_object_bounds_array(r->scene);
    const sl_object_rec *objs = sl_scene_objects(s);
    const sl_mesh_rec *meshes = sl_scene_meshes(s);
    const sl_affine *xfs = sl_scene_transforms(s);
    const float *pos = sl_scene_positions(s);
    const uint32_t *idx = sl_scene_indices(s);
    const double pp[3] = {p.x, p.y, p.z};
    double best2 = limit * limit;
    uint32_t no = sl_scene_object_count(r->scene);
    for (uint32_t o = 0; o < no; o++) {
        const sl_aabb *b = &boxes[o];
        double bd2 = 0;
        for (int k = 0; k < 3; k++) {
            double lo = (&b->min.x)[k], hi = (&b->max.x)[k];
            double e = pp[k] < lo ? lo - pp[k] : pp[k] > hi ? pp[k] - hi : 0;
            bd2 += e * e;
        }
        if (!(bd2 < best2))
            continue;
        const sl_mesh_rec *m = &meshes[objs[o].mesh];
        const sl_affine *xf = objs[o].transform == SL_NONE ? NULL : &xfs[objs[o].transform];
        const float *mp = pos + 3 * m->first_vertex;
        const uint32_t *mi = idx + m->first_index;
        for (uint32_t t = 0; t < m->triangle_count; t++) {
            double v[3][3];
            for (int j = 0; j < 3; j++) {
                sl_vec3 w = {mp[3 * (size_t)mi[3 * t + j]], mp[3 * (size_t)mi[3 * t + j] + 1],
                             mp[3 * (size_t)mi[3 * t + j] + 2]};
                if (xf)
                    w = sl_affine_point(xf, w);
                v[j][0] = w.x, v[j][1] = w.y, v[j][2] = w.z;
            }
            double td2 = 0; /* the triangle's box first */
            for (int k = 0; k < 3; k++) {
                double lo = fmin(v[0][k], fmin(v[1][k], v[2][k])), hi = fmax(v[0][k], fmax(v[1][k], v[2][k]));
                double e = pp[k] < lo ? lo - pp[k] : pp[k] > hi ? pp[k] - hi : 0;
                td2 += e * e;
            }
            if (td2 < best2)
                best2 = fmin(best2, tri_dist2(pp, v[0], v[1], v[2]));
        }
    }
    return sqrt(best2);
}

/* The near plane for an eye at p, or 0 when p cannot be rendered soundly. A cube face clips away
 * everything nearer than its near plane, up to near*sqrt(3) from the eye at the face's corners:
 * an eye closer than that to a wall would look through it and see what lies behind (Quake III
 * walls are single brushes between rooms: this made the maps' own PVS look non-conservative).
 * So the near plane is half the distance to the nearest triangle when that is below the
 * configured one. It has a floor that keeps the projection's depth order sound: the cube's view
 * matrix is single precision, and its translation rounds by about an ulp of the eye's
 * coordinates, which must stay small against the near distance. An eye nearer a surface than
 * two floors (60 micrometres at 100 m from the origin; a point on a face) is skipped: dropping a
 * sample keeps the oracle a lower bound, looking through the face would not. */
static float sample_near(const struct sl_region_oracle_t *r, sl_vec3 p)
{
    float big = fmaxf(fabsf(p.x), fmaxf(fabsf(p.y), fabsf(p.z)));
    float floor_near = fmaxf(1e-6f, 4.0f * (nextafterf(big, INFINITY) - big));
    float want = r->opt.near_plane;
    if (floor_near >= want)
        return want; /* coordinates so large that nothing finer is sound: the configured plane */
    double d = clearance(r, p, (double)want * 2.0);
    float n = (float)fmin((double)want, 0.5 * d);
    return n >= floor_near ? n : 0.0f;
}

/* ---- Quake III maps: sight lines through the map's solid space ---- */

/* Per object of the last cube map: its pixels when at least one of them is seen through the map's
 * open space, else 0, into r->sample_pixels (entries of objects not in the frame stay 0).
 *
 * Why: the oracle draws the map's drawn faces, but Quake III's opaque volumes are its brushes, and
 * many brush faces are never drawn: "caulk" on the sides a player is not meant to see (wall tops
 * far above the floor, faces behind patches, the outside of the hull). From a sample point high
 * in a cluster, a sight line can slip past a drawn face into such a brush and out of its undrawn
 * far side, and the oracle would report what lies beyond — while the map's own PVS, computed
 * against the brushes, rightly hides it (ctf_compromise: a wall top caulked at 15 m seen from
 * 32 m). A pixel therefore counts only when the segment from the eye to just before its surface
 * (backed off 2 mm, or 0.01%) crosses no leaf without a cluster. Surfaces of the structural
 * brushes lie on leaf boundaries, detail brushes and patches inside open leaves; both are
 * reached through open space. Once a pixel of an object is found open, its other pixels are
 * counted without tracing: the set is exact, the pixel count an upper bound (it is informative).
 * The cube faces' axes are read from the view matrices (exact signed unit rows), the depth from
 * the reversed depth buffer. */
static sl_status open_pixels(struct sl_region_oracle_t *r, const sl_bsp_view *bsp, sl_vec3 eye, float n,
                             const sl_oracle_frame *f, sl_error *err)
{
    for (uint32_t i = 0; i < f->visible_count; i++)
        r->sample_pixels[f->visible[i]] = 0;
    const double fr = r->opt.far_plane, nr = n;
    const double a = (fr + nr) / (nr - fr), b = 2.0 * fr * nr / (nr - fr);
    const double e[3] = {eye.x, eye.y, eye.z};
    for (uint32_t face = 0; face < 6; face++) {
        sl_oracle_view v;
        sl_status st = sl_oracle_get_view(r->oracle, face, &v, err);
        if (st != SL_OK)
            return st;
        const float *m = v.view_proj.m; /* column-major: rows 0, 1 and 3 are right, up, forward */
        const double rt[3] = {m[0], m[4], m[8]}, up[3] = {m[1], m[5], m[9]}, fw[3] = {m[3], m[7], m[11]};
        for (uint32_t y = 0; y < v.height; y++)
            for (uint32_t x = 0; x < v.width; x++) {
                size_t i = (size_t)y * v.width + x;
                uint32_t id = v.ids[i];
                if (id == SL_NONE || id >= r->object_count)
                    continue;
                uint32_t *cnt = &r->sample_pixels[id];
                (*cnt)++; /* low 31 bits: pixels; the top bit: one of them is open */
                if (*cnt & OPEN_BIT)
                    continue;
                /* d = (1 + a + b / z) / 2 with z < 0 the eye-space depth */
                double den = 2.0 * v.depth[i] - 1.0 - a;
                double t = den > 0 ? -b / den : fr;
                double u = 2.0 * (x + 0.5) / v.width - 1.0, w = 1.0 - 2.0 * (y + 0.5) / v.height;
                double dir[3], len2 = 0;
                for (int k = 0; k < 3; k++) {
                    dir[k] = t * (fw[k] + u * rt[k] + w * up[k]);
                    len2 += dir[k] * dir[k];
                }
                double keep = 1.0 - fmax(1e-4, 2e-3 / fmax(sqrt(len2), 1e-9)), end[3];
                if (keep <= 0) { /* the surface is within 2 mm: nothing lies between */
                    *cnt |= OPEN_BIT;
                    continue;
                }
                for (int k = 0; k < 3; k++)
                    end[k] = e[k] + keep * dir[k];
                if (sl_bsp_sight_line_open(bsp, e, end, false))
                    *cnt |= OPEN_BIT;
            }
    }
    for (uint32_t i = 0; i < f->visible_count; i++) {
        uint32_t *cnt = &r->sample_pixels[f->visible[i]];
        *cnt = (*cnt & OPEN_BIT) ? *cnt & ~OPEN_BIT : 0;
    }
    return SL_OK;
}

/* Render every point and gather the union. */
static sl_status render_points(struct sl_region_oracle_t *r, const sl_vec3 *pts, uint32_t n, sl_region_visibility *out,
                               sl_error *err)
{
    double t0 = sl_now();
    memset(out, 0, sizeof *out);
    uint32_t no = sl_scene_object_count(r->scene);
    if (r->object_count < (size_t)no + 1) {
        /* object_count holds the entries allocated (objects + 1, so never 0) */
        sl_free(&r->alloc, r->max_pixels, (size_t)r->object_count * sizeof(uint32_t));
        sl_free(&r->alloc, r->first, (size_t)r->object_count * sizeof(uint32_t));
        sl_free(&r->alloc, r->sample_pixels, (size_t)r->object_count * sizeof(uint32_t));
        r->object_count = 0;
        r->max_pixels = sl_alloc(&r->alloc, ((size_t)no + 1) * sizeof(uint32_t));
        r->first = sl_alloc(&r->alloc, ((size_t)no + 1) * sizeof(uint32_t));
        r->sample_pixels = sl_calloc(&r->alloc, (size_t)no + 1, sizeof(uint32_t));
        if (!r->max_pixels || !r->first || !r->sample_pixels) {
            sl_free(&r->alloc, r->max_pixels, ((size_t)no + 1) * sizeof(uint32_t));
            sl_free(&r->alloc, r->first, ((size_t)no + 1) * sizeof(uint32_t));
            sl_free(&r->alloc, r->sample_pixels, ((size_t)no + 1) * sizeof(uint32_t));
            r->max_pixels = r->first = r->sample_pixels = NULL;
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "region oracle: out of memory for %u objects", no);
        }
        r->object_count = no + 1;
    }
    for (uint32_t i = 0; i < no; i++) {
        r->max_pixels[i] = 0;
        r->first[i] = SL_NONE;
    }
    r->visible.count = 0;
    uint32_t rendered = 0; /* samples rendered: points touching a surface are skipped */
    uint32_t outside = 0;  /* samples outside the domain (docs/oracle.md): skipped */
    for (uint32_t k = 0; k < n; k++) {
        if (!sl_oracle_in_domain(r->scene, pts[k], NULL)) {
            outside++;
            continue;
        }
        float near_plane = sample_near(r, pts[k]);
        if (near_plane == 0)
            continue;
        sl_oracle_frame f;
        sl_status st = sl_oracle_render_cube(r->oracle, pts[k], r->opt.face_size, near_plane, r->opt.far_plane, &f, err);
        if (st != SL_OK) {
            sl_error_prefix(err, "region oracle, sample %u of %u at (%g, %g, %g)", k, n, (double)pts[k].x,
                            (double)pts[k].y, (double)pts[k].z);
            return st;
        }
        const uint32_t *px = f.pixels;
        sl_bsp_view bsp;
        if (sl_scene_bsp(r->scene, &bsp) && bsp.node_count > 0) {
            st = open_pixels(r, &bsp, pts[k], near_plane, &f, err);
            if (st != SL_OK)
                return st;
            px = r->sample_pixels;
        }
        for (uint32_t i = 0; i < f.visible_count; i++) {
            uint32_t id = f.visible[i], pixels = px == f.pixels ? px[i] : px[id];
            if (pixels == 0)
                continue;
            if (r->first[id] == SL_NONE) {
                r->first[id] = rendered;
                if (!sl_array_push(&r->alloc, &r->visible, sizeof id, &id, 1))
                    return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "region oracle: out of memory");
            }
            r->max_pixels[id] = SL_MAX(r->max_pixels[id], pixels);
        }
        rendered++;
    }
    n = rendered;
    /* ascending ids: mark and sweep over the object range (the set is small, the range bounded) */
    size_t nv = r->visible.count;
    r->visible.count = 0;
    r->out_pixels.count = 0;
    r->out_first.count = 0;
    if (!sl_array_reserve(&r->alloc, &r->out_pixels, sizeof(uint32_t), nv) ||
        !sl_array_reserve(&r->alloc, &r->out_first, sizeof(uint32_t), nv))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "region oracle: out of memory");
    uint32_t tail = n - n / 10; /* samples k >= tail form the last tenth */
    uint32_t added = 0;
    for (uint32_t id = 0; id < no; id++) {
        if (r->first[id] == SL_NONE)
            continue;
        SL_AT(r->visible, uint32_t, r->visible.count++) = id;
        SL_AT(r->out_pixels, uint32_t, r->out_pixels.count++) = r->max_pixels[id];
        SL_AT(r->out_first, uint32_t, r->out_first.count++) = r->first[id];
        if (n >= 10 && r->first[id] >= tail)
            added++;
    }
    out->sample_count = n;
    out->samples_out_of_domain = outside;
    out->out_of_domain = outside > 0 && rendered == 0;
    out->visible_count = (uint32_t)r->visible.count;
    out->visible = r->visible.data;
    out->max_pixels = r->out_pixels.data;
    out->first_sample = r->out_first.data;
    out->added_last_tenth = added;
    out->ms = (sl_now() - t0) * 1000.0;
    return SL_OK;
}

sl_status sl_region_oracle_cell(sl_region_oracle r, sl_viewcells cells, uint32_t cell, sl_region_visibility *out,
                                sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_region_oracle_cell: out must not be NULL");
    memset(out, 0, sizeof *out);
    const sl_vec3 *pts;
    uint32_t n;
    sl_status st = sl_region_oracle_points(r, cells, cell, &pts, &n, err);
    if (st != SL_OK)
        return st;
    if (n == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "region oracle: cell %u yields no sample point", cell);
    return render_points(r, pts, n, out, err);
}

sl_status sl_region_oracle_points_visible(sl_region_oracle r, const sl_vec3 *points, uint32_t count,
                                          sl_region_visibility *out, sl_error *err)
{
    if (!r || !out || (count && !points))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_region_oracle_points_visible: arguments must not be NULL");
    memset(out, 0, sizeof *out);
    for (uint32_t i = 0; i < count; i++)
        if (!sl_finite3(&points[i].x))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "region oracle: point %u is not finite", i);
    return render_points(r, points, count, out, err);
}

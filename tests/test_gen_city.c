/* Tests of the procedural city generator (src/scene/gen_city*.c): presets and option validation,
 * determinism, and the invariants every visibility method relies on: footprints valid and linked
 * to their buildings, nothing outside the extent, no building reaching into the free street space,
 * a connected and walkable street graph, dynamic cars, buildings standing on the terrain. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "sightline/gen.h"
#include "sightline/region.h"
#include "sightline/slscene.h"
#include "scene/scene_internal.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static sl_scene gen(const sl_city_options *o)
{
    sl_scene s = NULL;
    sl_error err;
    sl_status st = sl_gen_city(o, NULL, &s, &err);
    if (st != SL_OK)
        fail_msg("sl_gen_city failed: %s", err.message);
    assert_non_null(s);
    return s;
}

/* ---- geometry helpers (independent of the generator's own) ---- */

static double orient(const float *a, const float *b, const float *p)
{
    return ((double)b[0] - a[0]) * ((double)p[1] - a[1]) - ((double)b[1] - a[1]) * ((double)p[0] - a[0]);
}

static double seg_dist(const float *a, const float *b, const float *p)
{
    double dx = (double)b[0] - a[0], dy = (double)b[1] - a[1], l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? (((double)p[0] - a[0]) * dx + ((double)p[1] - a[1]) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double ex = a[0] + t * dx - p[0], ey = a[1] + t * dy - p[1];
    return sqrt(ex * ex + ey * ey);
}

static double boundary_dist(const float *xy, uint32_t n, const float *p)
{
    double d = INFINITY;
    for (uint32_t i = 0; i < n; i++)
        d = fmin(d, seg_dist(xy + 2 * i, xy + 2 * ((i + 1) % n), p));
    return d;
}

static bool crossing_inside(const float *xy, uint32_t n, const float *p)
{
    bool in = false;
    for (uint32_t i = 0, j = n - 1; i < n; j = i++) {
        double xi = xy[2 * i], yi = xy[2 * i + 1], xj = xy[2 * j], yj = xy[2 * j + 1];
        if ((yi > p[1]) != (yj > p[1]) && p[0] < (xj - xi) * (p[1] - yi) / (yj - yi) + xi)
            in = !in;
    }
    return in;
}

/* Inside by more than tol. */
static bool strictly_inside(const float *xy, uint32_t n, const float *p, double tol)
{
    return crossing_inside(xy, n, p) && boundary_dist(xy, n, p) > tol;
}

static bool on_or_inside(const float *xy, uint32_t n, const float *p, double tol)
{
    return crossing_inside(xy, n, p) || boundary_dist(xy, n, p) <= tol;
}

/* Segments cross with both pairs of endpoints clearly (> tol) on opposite sides. */
static bool proper_cross(const float *a, const float *b, const float *c, const float *d, double tol)
{
    double lab = hypot((double)b[0] - a[0], (double)b[1] - a[1]), lcd = hypot((double)d[0] - c[0], (double)d[1] - c[1]);
    if (!(lab > 0) || !(lcd > 0))
        return false;
    double o1 = orient(a, b, c) / lab, o2 = orient(a, b, d) / lab, o3 = orient(c, d, a) / lcd, o4 = orient(c, d, b) / lcd;
    return ((o1 > tol && o2 < -tol) || (o1 < -tol && o2 > tol)) && ((o3 > tol && o4 < -tol) || (o3 < -tol && o4 > tol));
}

static void poly_box(const float *xy, uint32_t n, float box[4])
{
    box[0] = box[1] = INFINITY, box[2] = box[3] = -INFINITY;
    for (uint32_t i = 0; i < n; i++) {
        box[0] = fminf(box[0], xy[2 * i]), box[2] = fmaxf(box[2], xy[2 * i]);
        box[1] = fminf(box[1], xy[2 * i + 1]), box[3] = fmaxf(box[3], xy[2 * i + 1]);
    }
}

static bool boxes_overlap(const float a[4], const float b[4], float tol)
{
    return a[0] < b[2] - tol && b[0] < a[2] - tol && a[1] < b[3] - tol && b[1] < a[3] - tol;
}

/* Interiors of two polygons overlap by more than tol. */
static bool polygons_overlap(const float *a, uint32_t na, const float *b, uint32_t nb, double tol)
{
    for (uint32_t i = 0; i < na; i++)
        if (strictly_inside(b, nb, a + 2 * i, tol))
            return true;
    for (uint32_t i = 0; i < nb; i++)
        if (strictly_inside(a, na, b + 2 * i, tol))
            return true;
    for (uint32_t i = 0; i < na; i++)
        for (uint32_t j = 0; j < nb; j++)
            if (proper_cross(a + 2 * i, a + 2 * ((i + 1) % na), b + 2 * j, b + 2 * ((j + 1) % nb), tol))
                return true;
    return false;
}

/* ---- hashing a whole scene (its arrays, byte for byte) ---- */

static uint64_t hash_array(uint64_t h, const sl_array *a, size_t elem)
{
    return sl_hash64(a->data, a->count * elem, h ^ a->count);
}

static uint64_t scene_hash(sl_scene s)
{
    uint64_t h = 0x5eed;
    h = hash_array(h, &s->meshes, sizeof(sl_mesh_rec));
    h = hash_array(h, &s->positions, sizeof(float));
    h = hash_array(h, &s->normals, sizeof(float));
    h = hash_array(h, &s->indices, sizeof(uint32_t));
    h = hash_array(h, &s->objects, sizeof(sl_object_rec));
    h = hash_array(h, &s->bounds, sizeof(sl_aabb));
    h = hash_array(h, &s->transforms, sizeof(sl_affine));
    h = hash_array(h, &s->footprints, sizeof(sl_footprint_rec));
    h = hash_array(h, &s->footprint_xy, sizeof(float));
    h = hash_array(h, &s->terrain_heights, sizeof(float));
    h = hash_array(h, &s->street_polys, sizeof(sl_polygon_rec));
    h = hash_array(h, &s->street_xy, sizeof(float));
    h = hash_array(h, &s->street_nodes, sizeof(sl_street_node));
    h = hash_array(h, &s->street_edges, sizeof(sl_street_edge));
    for (uint32_t i = 0; i < sl_scene_meta_count(s); i++) {
        const char *k, *v;
        sl_scene_meta_at(s, i, &k, &v);
        h = sl_hash64(k, strlen(k), h);
        h = sl_hash64(v, strlen(v), h);
    }
    return h;
}

/* Hash through the public views only: every mesh and object, field by field. */
static uint64_t views_hash(sl_scene s)
{
    uint64_t h = 0;
    for (uint32_t m = 0; m < sl_scene_mesh_count(s); m++) {
        sl_mesh_view v = sl_scene_mesh(s, m);
        h = sl_hash64(v.positions, 3 * sizeof(float) * v.vertex_count, h);
        h = sl_hash64(v.normals, 3 * sizeof(float) * v.vertex_count, h);
        h = sl_hash64(v.indices, 3 * sizeof(uint32_t) * v.triangle_count, h);
    }
    for (uint32_t o = 0; o < sl_scene_object_count(s); o++) {
        sl_object_view v = sl_scene_object(s, o);
        uint32_t f[4] = {v.mesh, v.color, v.kind, v.flags};
        h = sl_hash64(f, sizeof f, h);
        h = sl_hash64(v.transform.m, sizeof v.transform.m, h);
        h = sl_hash64(&v.bounds, sizeof v.bounds, h);
    }
    return h;
}

/* ---- invariants shared by every generated city ---- */

typedef struct city_check {
    double max_seconds;  /* 0: not checked */
    bool expect_connected;
} city_check;

static void check_footprints(sl_scene s)
{
    uint32_t nobj = sl_scene_object_count(s), nfp = sl_scene_footprint_count(s);
    uint32_t *seen = calloc(nobj, sizeof(uint32_t));
    assert_non_null(seen);
    uint32_t buildings = 0;
    for (uint32_t o = 0; o < nobj; o++) {
        sl_object_view v = sl_scene_object(s, o);
        if (v.kind == SL_KIND_BUILDING) {
            buildings++;
            assert_true(v.flags & SL_OBJECT_OCCLUDER);
            assert_false(v.flags & SL_OBJECT_DYNAMIC);
        }
    }
    assert_int_equal(nfp, buildings);
    for (uint32_t f = 0; f < nfp; f++) {
        sl_footprint_view fp = sl_scene_footprint(s, f);
        assert_true(fp.vertex_count >= 3);
        assert_true(fp.roof_z > fp.base_z);
        assert_true(fp.object < nobj);
        sl_object_view v = sl_scene_object(s, fp.object);
        assert_int_equal(v.kind, SL_KIND_BUILDING);
        seen[fp.object]++;
        /* CCW, and inside the building's bounds: the occluder lies within the building */
        double area = 0;
        for (uint32_t i = 0; i < fp.vertex_count; i++) {
            const float *a = fp.xy + 2 * i, *b = fp.xy + 2 * ((i + 1) % fp.vertex_count);
            area += (double)a[0] * b[1] - (double)b[0] * a[1];
            assert_true(a[0] >= v.bounds.min.x - 1e-3f && a[0] <= v.bounds.max.x + 1e-3f);
            assert_true(a[1] >= v.bounds.min.y - 1e-3f && a[1] <= v.bounds.max.y + 1e-3f);
        }
        assert_true(area > 0);
        assert_true(fabsf(v.bounds.min.z - fp.base_z) < 1e-3f);
        assert_true(fp.roof_z <= v.bounds.max.z + 1e-3f);
    }
    for (uint32_t o = 0; o < nobj; o++)
        if (sl_scene_object(s, o).kind == SL_KIND_BUILDING)
            assert_int_equal(seen[o], 1);
    free(seen);
}

static void check_extent(sl_scene s, const sl_city_options *o)
{
    float hx = 0.5f * o->extent_x + 1e-3f, hy = 0.5f * o->extent_y + 1e-3f;
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        sl_aabb b = sl_scene_object_bounds(s, i);
        if (b.min.x < -hx || b.max.x > hx || b.min.y < -hy || b.max.y > hy)
            fail_msg("object %u (%s) reaches outside the extent: x %g..%g y %g..%g", i,
                     sl_object_kind_name(sl_scene_object(s, i).kind), b.min.x, b.max.x, b.min.y, b.max.y);
    }
    for (uint32_t i = 0; i < sl_scene_street_polygon_count(s); i++) {
        sl_polygon_view p = sl_scene_street_polygon(s, i);
        for (uint32_t k = 0; k < p.vertex_count; k++)
            assert_true(fabsf(p.xy[2 * k]) <= hx && fabsf(p.xy[2 * k + 1]) <= hy);
    }
}

/* No footprint and no vertex of a building's mesh lies in the free street space. */
static void check_clear_of_streets(sl_scene s)
{
    uint32_t np = sl_scene_street_polygon_count(s);
    float(*pbox)[4] = malloc(sizeof(float[4]) * (np ? np : 1));
    assert_non_null(pbox);
    for (uint32_t i = 0; i < np; i++) {
        sl_polygon_view p = sl_scene_street_polygon(s, i);
        poly_box(p.xy, p.vertex_count, pbox[i]);
    }
    for (uint32_t f = 0; f < sl_scene_footprint_count(s); f++) {
        sl_footprint_view fp = sl_scene_footprint(s, f);
        float fbox[4];
        poly_box(fp.xy, fp.vertex_count, fbox);
        for (uint32_t i = 0; i < np; i++) {
            if (!boxes_overlap(fbox, pbox[i], 0.01f))
                continue;
            sl_polygon_view p = sl_scene_street_polygon(s, i);
            if (polygons_overlap(fp.xy, fp.vertex_count, p.xy, p.vertex_count, 0.01))
                fail_msg("footprint %u (object %u) overlaps street polygon %u", f, fp.object, i);
        }
        sl_object_view ov = sl_scene_object(s, fp.object);
        sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
        float obox[4] = {ov.bounds.min.x, ov.bounds.min.y, ov.bounds.max.x, ov.bounds.max.y};
        for (uint32_t i = 0; i < np; i++) {
            if (!boxes_overlap(obox, pbox[i], 0.01f))
                continue;
            sl_polygon_view p = sl_scene_street_polygon(s, i);
            for (uint32_t v = 0; v < mv.vertex_count; v++)
                if (strictly_inside(p.xy, p.vertex_count, mv.positions + 3 * (size_t)v, 0.01))
                    fail_msg("building %u: mesh vertex %u (%g, %g) lies in street polygon %u", fp.object, v,
                             mv.positions[3 * v], mv.positions[3 * v + 1], i);
        }
    }
    free(pbox);
}

/* BFS over the centre-line graph; returns the number of components. Also checks that every edge's
 * centre line runs through free space (sampled every metre). */
static uint32_t check_street_graph(sl_scene s)
{
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nn, ne;
    sl_scene_street_graph(s, &nodes, &nn, &edges, &ne);
    assert_true(nn > 1 && ne > 0);
    uint32_t np = sl_scene_street_polygon_count(s);
    for (uint32_t e = 0; e < ne; e++) {
        assert_true(edges[e].a < nn && edges[e].b < nn && edges[e].a != edges[e].b);
        assert_true(edges[e].width > 0);
        float a[2] = {nodes[edges[e].a].x, nodes[edges[e].a].y}, b[2] = {nodes[edges[e].b].x, nodes[edges[e].b].y};
        double len = hypot((double)b[0] - a[0], (double)b[1] - a[1]);
        int steps = (int)ceil(len);
        for (int k = 0; k <= steps; k++) {
            float p[2] = {(float)(a[0] + (b[0] - a[0]) * (double)k / steps), (float)(a[1] + (b[1] - a[1]) * (double)k / steps)};
            bool free_space = false;
            for (uint32_t i = 0; i < np && !free_space; i++) {
                sl_polygon_view pv = sl_scene_street_polygon(s, i);
                free_space = on_or_inside(pv.xy, pv.vertex_count, p, 0.02);
            }
            if (!free_space)
                fail_msg("street edge %u (flags %u): point (%g, %g) is not in any street polygon", e, edges[e].flags, p[0],
                         p[1]);
        }
    }
    /* union-find is enough for components; a BFS in the same spirit as the brief asks */
    uint32_t *adj_start = calloc(nn + 1, sizeof(uint32_t)), *adj = malloc(2 * ne * sizeof(uint32_t));
    uint32_t *fill = calloc(nn, sizeof(uint32_t)), *queue = malloc(nn * sizeof(uint32_t));
    uint8_t *seen = calloc(nn, 1);
    assert_true(adj_start && adj && fill && queue && seen);
    for (uint32_t e = 0; e < ne; e++)
        adj_start[edges[e].a + 1]++, adj_start[edges[e].b + 1]++;
    for (uint32_t i = 0; i < nn; i++)
        adj_start[i + 1] += adj_start[i];
    for (uint32_t e = 0; e < ne; e++) {
        adj[adj_start[edges[e].a] + fill[edges[e].a]++] = edges[e].b;
        adj[adj_start[edges[e].b] + fill[edges[e].b]++] = edges[e].a;
    }
    uint32_t components = 0;
    for (uint32_t start = 0; start < nn; start++) {
        if (seen[start])
            continue;
        components++;
        uint32_t head = 0, tail = 0;
        queue[tail++] = start;
        seen[start] = 1;
        while (head < tail) {
            uint32_t u = queue[head++];
            for (uint32_t k = adj_start[u]; k < adj_start[u + 1]; k++)
                if (!seen[adj[k]]) {
                    seen[adj[k]] = 1;
                    queue[tail++] = adj[k];
                }
        }
    }
    free(adj_start), free(adj), free(fill), free(queue), free(seen);
    return components;
}

static void check_props(sl_scene s)
{
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        sl_object_view v = sl_scene_object(s, i);
        if (v.kind == SL_KIND_CAR) {
            assert_true(v.flags & SL_OBJECT_DYNAMIC);
            assert_false(v.identity);
        } else {
            assert_false(v.flags & SL_OBJECT_DYNAMIC);
        }
        if (v.kind == SL_KIND_TREE || v.kind == SL_KIND_LAMP)
            assert_false(v.identity);
    }
}

static void check_city(sl_scene s, const sl_city_options *o, bool connected)
{
    check_footprints(s);
    check_extent(s, o);
    check_clear_of_streets(s);
    check_props(s);
    uint32_t comps = check_street_graph(s);
    if (connected)
        assert_int_equal(comps, 1);
}

/* ---- tests ---- */

static void test_presets(void **state)
{
    (void)state;
    sl_city_preset p;
    sl_error err;
    assert_int_equal(sl_city_preset_from_name("tiny", &p, &err), SL_OK);
    assert_int_equal(p, SL_CITY_TINY);
    assert_int_equal(sl_city_preset_from_name("small", &p, &err), SL_OK);
    assert_int_equal(p, SL_CITY_SMALL);
    assert_int_equal(sl_city_preset_from_name("vienna", &p, &err), SL_OK);
    assert_int_equal(p, SL_CITY_VIENNA);
    assert_int_equal(sl_city_preset_from_name("paris", &p, &err), SL_ERROR_NOT_FOUND);
    assert_non_null(strstr(err.message, "paris"));
    assert_int_equal(sl_city_preset_from_name(NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_string_equal(sl_city_preset_name(SL_CITY_VIENNA), "vienna");
    assert_string_equal(sl_city_preset_name((sl_city_preset)7), "unknown");
    for (int k = 0; k < 3; k++) {
        sl_city_options o = sl_city_defaults((sl_city_preset)k);
        assert_int_equal(o.preset, k);
        assert_int_equal(sl_city_options_validate(&o, &err), SL_OK);
    }
    /* the presets grow */
    sl_city_options t = sl_city_defaults(SL_CITY_TINY), s = sl_city_defaults(SL_CITY_SMALL), v = sl_city_defaults(SL_CITY_VIENNA);
    assert_true(t.extent_x * t.extent_y < s.extent_x * s.extent_y);
    assert_true(s.extent_x * s.extent_y < v.extent_x * v.extent_y);
    assert_true(v.extent_x * v.extent_y > 7.5e6 && v.extent_x * v.extent_y < 8.5e6);
}

static void test_tiny(void **state)
{
    (void)state;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    double t0 = sl_now();
    sl_scene s = gen(&o);
    double dt = sl_now() - t0;
    if (!sanitized())
        assert_true(dt < 0.3);
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    assert_true(st.instanced_triangle_count < 50000);
    assert_true(st.instanced_triangle_count > 5000);
    assert_true(st.objects_per_kind[SL_KIND_BUILDING] >= 20);
    assert_true(st.objects_per_kind[SL_KIND_GROUND] > 0);
    assert_true(st.objects_per_kind[SL_KIND_WATER] > 0);
    assert_true(st.objects_per_kind[SL_KIND_CAR] > 0);
    assert_true(st.objects_per_kind[SL_KIND_TREE] > 0);
    assert_true(st.objects_per_kind[SL_KIND_LAMP] > 0);
    assert_true(st.street_polygon_count > 10);
    assert_false(st.has_terrain);
    /* instancing: props share a handful of meshes */
    assert_true(st.mesh_count < st.object_count);
    long blocks = strtol(sl_scene_meta(s, "city.blocks"), NULL, 10);
    assert_true(blocks >= 3 && blocks <= 40);
    check_city(s, &o, true);
    sl_scene_destroy(s);
}

static void test_metadata(void **state)
{
    (void)state;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.seed = 123456789012345ull;
    sl_scene s = gen(&o);
    assert_string_equal(sl_scene_meta(s, "generator"), "sightline city");
    assert_string_equal(sl_scene_meta(s, "preset"), "tiny");
    assert_string_equal(sl_scene_meta(s, "seed"), "123456789012345");
    assert_string_equal(sl_scene_meta(s, "extent"), "-150 -130 150 130");
    assert_string_equal(sl_scene_meta(s, "city.river"), "yes");
    assert_int_equal(strtoul(sl_scene_meta(s, "city.buildings"), NULL, 10), sl_scene_footprint_count(s));
    sl_scene_destroy(s);
}

static void test_determinism(void **state)
{
    (void)state;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.terrain = true;
    o.detail = 4;
    sl_scene a = gen(&o), b = gen(&o);
    assert_int_equal(sl_scene_object_count(a), sl_scene_object_count(b));
    assert_true(scene_hash(a) == scene_hash(b));
    assert_true(views_hash(a) == views_hash(b));
    o.seed = 2;
    sl_scene c = gen(&o);
    assert_true(scene_hash(a) != scene_hash(c));
    assert_true(views_hash(a) != views_hash(c));
    /* a different seed changes the layout itself, not just a colour */
    const sl_street_node *na, *nc;
    uint32_t nna, nnc;
    sl_scene_street_graph(a, &na, &nna, NULL, NULL);
    sl_scene_street_graph(c, &nc, &nnc, NULL, NULL);
    assert_true(nna != nnc || memcmp(na, nc, nna * sizeof *na) != 0);
    sl_scene_destroy(a);
    sl_scene_destroy(b);
    sl_scene_destroy(c);
}

/* The grid style's output is pinned: these hashes were taken before the oldtown style existed
 * (scene arrays byte for byte, metadata included), so any change to the grid generator shows
 * here. Hashes of float arrays pin this platform's libm as well (x86-64, glibc). */
static void test_grid_pinned(void **state)
{
    (void)state;
    static const struct {
        sl_city_preset preset;
        bool terrain;
        uint32_t detail; /* 99: the preset's */
        uint64_t hash;
    } pins[] = {
        {SL_CITY_TINY, false, 99, 0x487b7f90c7749377ull},
        {SL_CITY_TINY, true, 4, 0x04619cf6eed6b98full},
        {SL_CITY_SMALL, false, 99, 0xc32f3a046c820a94ull},
        {SL_CITY_SMALL, true, 99, 0xfc549ddbc15d20fcull},
        {SL_CITY_VIENNA, false, 99, 0x8e731a8b26751e78ull},
    };
    int bad = 0;
    for (size_t k = 0; k < sizeof pins / sizeof pins[0]; k++) {
        if (pins[k].preset == SL_CITY_VIENNA && sanitized())
            continue; /* 1.5 s in a release build, minutes under the sanitizers */
        sl_city_options o = sl_city_defaults(pins[k].preset);
        o.terrain = pins[k].terrain;
        if (pins[k].detail != 99)
            o.detail = pins[k].detail;
        sl_scene s = gen(&o);
        uint64_t h = scene_hash(s);
        if (h != pins[k].hash)
            print_error("pin %zu (%s): scene hash 0x%016llxull, pinned 0x%016llxull\n", k,
                        sl_city_preset_name(pins[k].preset), (unsigned long long)h, (unsigned long long)pins[k].hash);
        bad += h != pins[k].hash;
        sl_scene_destroy(s);
    }
    assert_int_equal(bad, 0);
}

/* ---- the oldtown style ---- */

static void expect_invalid(const sl_city_options *o, sl_status want, const char *needle);

/* Some edge midpoint of a lies strictly inside b (catches an edge cutting through b between two
 * points on b's boundary, which neither vertices nor proper crossings show). */
static bool midpoint_inside(const float *a, uint32_t na, const float *b, uint32_t nb, double tol)
{
    for (uint32_t i = 0; i < na; i++) {
        const float *p = a + 2 * i, *q = a + 2 * ((i + 1) % na);
        float m[2] = {0.5f * (p[0] + q[0]), 0.5f * (p[1] + q[1])};
        if (strictly_inside(b, nb, m, tol))
            return true;
    }
    return false;
}

/* No two building footprints overlap (they may share walls): no vertex or edge midpoint strictly
 * inside the other, no proper crossing of edges, and neither's centroid (when inside itself)
 * inside the other. */
static void check_buildings_disjoint(sl_scene s)
{
    uint32_t nf = sl_scene_footprint_count(s);
    float(*box)[4] = malloc(sizeof(float[4]) * (nf ? nf : 1));
    float(*ctr)[2] = malloc(sizeof(float[2]) * (nf ? nf : 1));
    assert_true(box && ctr);
    for (uint32_t f = 0; f < nf; f++) {
        sl_footprint_view v = sl_scene_footprint(s, f);
        poly_box(v.xy, v.vertex_count, box[f]);
        double cx = 0, cy = 0;
        for (uint32_t k = 0; k < v.vertex_count; k++)
            cx += v.xy[2 * k], cy += v.xy[2 * k + 1];
        ctr[f][0] = (float)(cx / v.vertex_count), ctr[f][1] = (float)(cy / v.vertex_count);
    }
    for (uint32_t f = 0; f < nf; f++) {
        sl_footprint_view a = sl_scene_footprint(s, f);
        bool ca = strictly_inside(a.xy, a.vertex_count, ctr[f], 0.01);
        for (uint32_t g = f + 1; g < nf; g++) {
            if (!boxes_overlap(box[f], box[g], 0.01f))
                continue;
            sl_footprint_view b = sl_scene_footprint(s, g);
            bool cb = strictly_inside(b.xy, b.vertex_count, ctr[g], 0.01);
            if (polygons_overlap(a.xy, a.vertex_count, b.xy, b.vertex_count, 0.01) ||
                midpoint_inside(a.xy, a.vertex_count, b.xy, b.vertex_count, 0.01) ||
                midpoint_inside(b.xy, b.vertex_count, a.xy, a.vertex_count, 0.01) ||
                (ca && strictly_inside(b.xy, b.vertex_count, ctr[f], 0.01)) ||
                (cb && strictly_inside(a.xy, a.vertex_count, ctr[g], 0.01)))
                fail_msg("footprints %u and %u (objects %u, %u) overlap", f, g, a.object, b.object);
        }
    }
    free(box);
    free(ctr);
}

static double rel(double a, double b) { return fabs(a - b) / fabs(b); }

static void test_oldtown(void **state)
{
    (void)state;
    sl_error err;
    sl_city_preset p;
    assert_int_equal(sl_city_preset_from_name("oldtown", &p, &err), SL_OK);
    assert_int_equal(p, SL_CITY_OLDTOWN);
    assert_int_equal(sl_city_preset_from_name("oldtown-small", &p, &err), SL_OK);
    assert_int_equal(p, SL_CITY_OLDTOWN_SMALL);
    assert_string_equal(sl_city_preset_name(SL_CITY_OLDTOWN_SMALL), "oldtown-small");
    sl_city_style style;
    assert_int_equal(sl_city_style_from_name("oldtown", &style, &err), SL_OK);
    assert_int_equal(style, SL_CITY_STYLE_OLDTOWN);
    assert_int_equal(sl_city_style_from_name("grid", &style, &err), SL_OK);
    assert_int_equal(style, SL_CITY_STYLE_GRID);
    assert_int_equal(sl_city_style_from_name("baroque", &style, &err), SL_ERROR_NOT_FOUND);
    assert_non_null(strstr(err.message, "baroque"));
    assert_string_equal(sl_city_style_name((sl_city_style)9), "unknown");

    /* the oldtown presets: the extents of their grid counterparts, validated, style recorded */
    sl_city_options ov = sl_city_defaults(SL_CITY_OLDTOWN), v = sl_city_defaults(SL_CITY_VIENNA);
    sl_city_options o = sl_city_defaults(SL_CITY_OLDTOWN_SMALL), g = sl_city_defaults(SL_CITY_SMALL);
    assert_int_equal(ov.style, SL_CITY_STYLE_OLDTOWN);
    assert_int_equal(v.style, SL_CITY_STYLE_GRID);
    assert_true(ov.extent_x == v.extent_x && ov.extent_y == v.extent_y);
    assert_true(o.extent_x == g.extent_x && o.extent_y == g.extent_y);
    assert_int_equal(sl_city_options_validate(&ov, &err), SL_OK);
    assert_int_equal(sl_city_options_validate(&o, &err), SL_OK);

    sl_scene a = gen(&o), b = gen(&o);
    /* deterministic: the same options give the same bytes; another seed another city */
    assert_true(scene_hash(a) == scene_hash(b));
    assert_true(views_hash(a) == views_hash(b));
    sl_city_options o2 = o;
    o2.seed = 2;
    sl_scene c = gen(&o2);
    assert_true(scene_hash(a) != scene_hash(c));
    assert_string_equal(sl_scene_meta(a, "city.style"), "oldtown");
    assert_string_equal(sl_scene_meta(a, "preset"), "oldtown-small");
    assert_string_equal(sl_scene_meta(a, "city.river"), "no");

    /* a proper city: footprints, extent, clear streets, one connected street graph, and no two
     * buildings on top of each other */
    check_city(a, &o, true);
    check_buildings_disjoint(a);
    check_city(c, &o2, true);
    check_buildings_disjoint(c);

    /* comparable with the grid city of the same extent (within 10%), with much shorter sight
     * lines along its streets */
    sl_scene grid = gen(&g);
    sl_city_stats so, sg;
    assert_int_equal(sl_city_measure(a, &so, &err), SL_OK);
    assert_int_equal(sl_city_measure(grid, &sg, &err), SL_OK);
    print_message("oldtown-small vs small: objects %u / %u, mean height %.2f / %.2f m, street fraction %.4f / %.4f, "
                  "sight lines mean %.0f / %.0f m, p90 %.0f / %.0f m\n",
                  so.object_count, sg.object_count, so.mean_building_height, sg.mean_building_height, so.street_fraction,
                  sg.street_fraction, so.sight_mean, sg.sight_mean, so.sight_p90, sg.sight_p90);
    assert_true(so.extent_x == sg.extent_x && so.extent_y == sg.extent_y);
    assert_true(rel(so.object_count, sg.object_count) <= 0.10);
    assert_true(rel(so.mean_building_height, sg.mean_building_height) <= 0.10);
    assert_true(rel(so.street_fraction, sg.street_fraction) <= 0.10);
    assert_int_equal(so.building_count, sl_scene_footprint_count(a));
    assert_true(so.sight_rays > 100);
    assert_true(so.sight_mean < 0.6 * sg.sight_mean);
    assert_true(so.sight_p90 < 0.6 * sg.sight_p90);
    /* the measure itself: street length of the graph, a street fraction in (0,1) */
    assert_true(so.street_length > 1000 && so.street_fraction > 0.2 && so.street_fraction < 0.8);

    /* view cells come from its street space as from the grid's */
    sl_viewcell_options vo = {0};
    vo.max_edge = 12;
    sl_viewcells cells;
    if (sl_viewcells_from_streets(a, &vo, &cells, &err) != SL_OK)
        fail_msg("view cells: %s", err.message);
    sl_viewcells_stats vs;
    sl_viewcells_get_stats(cells, &vs);
    print_message("oldtown-small: %u view cells over %.0f m² (street area %.0f m²)\n", sl_viewcells_count(cells), vs.area,
                  so.street_area);
    assert_true(sl_viewcells_count(cells) > 1000);
    assert_true(fabs(vs.area - so.street_area) < 0.02 * so.street_area);
    sl_viewcells_destroy(cells);

    sl_scene_destroy(a);
    sl_scene_destroy(b);
    sl_scene_destroy(c);
    sl_scene_destroy(grid);
}

static void test_oldtown_options(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options o = sl_city_defaults(SL_CITY_OLDTOWN_SMALL);
    o.meander = 0.5f * o.block_size_min;
    expect_invalid(&o, SL_ERROR_INVALID_ARGUMENT, "meander");
    o = sl_city_defaults(SL_CITY_OLDTOWN_SMALL);
    o.meander_wavelength = 10;
    expect_invalid(&o, SL_ERROR_INVALID_ARGUMENT, "meander_wavelength");
    o = sl_city_defaults(SL_CITY_OLDTOWN_SMALL);
    o.district = 1;
    expect_invalid(&o, SL_ERROR_INVALID_ARGUMENT, "district");
    o = sl_city_defaults(SL_CITY_OLDTOWN_SMALL);
    o.style = (sl_city_style)5;
    expect_invalid(&o, SL_ERROR_INVALID_ARGUMENT, "style");
    /* the grid ignores the district; meander 0 is the grid presets' value */
    o = sl_city_defaults(SL_CITY_TINY);
    o.district = 0;
    assert_int_equal(sl_city_options_validate(&o, &err), SL_OK);
    /* the style on a grid preset's options, terrain and full detail, several seeds: valid cities */
    for (int k = 0; k < (sanitized() ? 2 : 6); k++) {
        sl_city_options t = sl_city_defaults(SL_CITY_TINY);
        t.style = SL_CITY_STYLE_OLDTOWN;
        t.meander = 8, t.district = 3, t.extent_x = 400, t.extent_y = 360;
        t.seed = 500 + (uint64_t)k;
        t.terrain = k & 1, t.detail = k == 0 ? 4 : 2;
        sl_scene s = gen(&t);
        check_city(s, &t, true);
        check_buildings_disjoint(s);
        sl_scene_destroy(s);
    }
    /* sl_city_measure refuses what is not a city */
    sl_city_stats cs;
    assert_int_equal(sl_city_measure(NULL, &cs, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene empty;
    assert_int_equal(sl_scene_create(NULL, &empty, &err), SL_OK);
    assert_int_equal(sl_city_measure(empty, &cs, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "not a city"));
    sl_scene_destroy(empty);
}

static void test_detail_levels(void **state)
{
    (void)state;
    uint64_t prev = 0;
    for (uint32_t d = 0; d <= 4; d++) {
        sl_city_options o = sl_city_defaults(SL_CITY_TINY);
        o.detail = d;
        sl_scene s = gen(&o);
        sl_scene_stats st;
        sl_scene_get_stats(s, &st);
        uint64_t tris = st.triangles_per_kind[SL_KIND_BUILDING];
        double per = (double)tris / st.objects_per_kind[SL_KIND_BUILDING];
        assert_true(tris > prev);
        if (d == 0)
            assert_true(per < 20); /* prisms with flat roofs: a dozen for a box */
        if (d == 4)
            assert_true(per > 500);
        prev = tris;
        check_footprints(s);
        check_clear_of_streets(s);
        sl_scene_destroy(s);
    }
}

static void test_terrain(void **state)
{
    (void)state;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.terrain = true;
    o.relief = 30;
    o.river = false; /* the relief then covers the whole map */
    sl_scene s = gen(&o);
    sl_terrain_view tv;
    assert_true(sl_scene_terrain(s, &tv));
    float lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < (size_t)tv.nx * tv.ny; k++)
        lo = fminf(lo, tv.heights[k]), hi = fmaxf(hi, tv.heights[k]);
    assert_true(hi - lo > 10);
    assert_true(lo >= -1e-3f && hi <= 30 + 1e-3f);
    assert_true(tv.origin_x <= -0.5f * o.extent_x && tv.origin_y <= -0.5f * o.extent_y);
    assert_true(tv.origin_x + (tv.nx - 1) * tv.cell >= 0.5f * o.extent_x);
    /* every building's base is the lowest ground under its footprint: at or below the ground at
     * its corners, along its edges (every 25 cm) and at the height samples inside it, and no
     * more than a few centimetres below the lowest of them */
    for (uint32_t f = 0; f < sl_scene_footprint_count(s); f++) {
        sl_footprint_view fp = sl_scene_footprint(s, f);
        float gmin = INFINITY;
        for (uint32_t k = 0; k < fp.vertex_count; k++) {
            const float *a = fp.xy + 2 * k, *b = fp.xy + 2 * ((k + 1) % fp.vertex_count);
            int steps = (int)ceil(hypot(b[0] - a[0], b[1] - a[1]) / 0.25);
            for (int t = 0; t <= steps; t++) {
                float x = a[0] + (b[0] - a[0]) * (float)t / steps, y = a[1] + (b[1] - a[1]) * (float)t / steps;
                gmin = fminf(gmin, sl_scene_ground_height(s, x, y));
            }
        }
        for (uint32_t j = 0; j < tv.ny; j++)
            for (uint32_t i = 0; i < tv.nx; i++) {
                float p[2] = {tv.origin_x + i * tv.cell, tv.origin_y + j * tv.cell};
                if (crossing_inside(fp.xy, fp.vertex_count, p))
                    gmin = fminf(gmin, tv.heights[(size_t)j * tv.nx + i]);
            }
        assert_true(fp.base_z <= gmin + 1e-3f);
        assert_true(fp.base_z >= gmin - 0.05f);
    }
    /* trees and lamps stand on the ground (no bridges here) */
    uint32_t props = 0;
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        sl_object_view v = sl_scene_object(s, i);
        if (v.kind != SL_KIND_TREE && v.kind != SL_KIND_LAMP && v.kind != SL_KIND_CAR)
            continue;
        float g = sl_scene_ground_height(s, v.transform.m[3], v.transform.m[7]);
        assert_true(fabsf(v.transform.m[11] - g) < 1e-3f);
        props++;
    }
    assert_true(props > 0);
    /* and the ground meshes follow the terrain: their vertices sit on the height field */
    uint32_t checked = 0;
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        sl_object_view v = sl_scene_object(s, i);
        if (v.kind != SL_KIND_GROUND)
            continue;
        sl_mesh_view mv = sl_scene_mesh(s, v.mesh);
        for (uint32_t k = 0; k < mv.vertex_count; k += 7, checked++) {
            const float *p = mv.positions + 3 * (size_t)k;
            assert_true(fabsf(p[2] - sl_scene_ground_height(s, p[0], p[1])) < 0.01f);
        }
    }
    assert_true(checked > 100);
    check_city(s, &o, true);
    sl_scene_destroy(s);
}

static void test_variants(void **state)
{
    (void)state;
    for (int k = 0; k < 6; k++) {
        sl_city_options o = sl_city_defaults(SL_CITY_TINY);
        o.seed = 1000 + (uint64_t)k;
        o.extent_x = 360, o.extent_y = 320;
        switch (k) {
        case 0: /* many dropped streets, strong jitter */
            o.street_removal = 0.5f, o.jitter = 0.22f;
            break;
        case 1: /* open city: parks and squares everywhere, no river */
            o.river = false, o.park_fraction = 0.3f, o.square_fraction = 0.3f;
            break;
        case 2: /* towers and terrain, no avenues */
            o.tower_fraction = 0.5f, o.terrain = true, o.avenue_spacing = 0;
            break;
        case 3: /* no props at all, no banks */
            o.cars_per_km = 0, o.trees_per_ha = 0, o.street_tree_spacing = 0, o.lamp_spacing = 0, o.bank_width = 0;
            break;
        case 4: /* wide streets on big blocks, full detail */
            o.block_size_min = 90, o.block_size_max = 130, o.street_width_max = 22, o.avenue_width = 40, o.detail = 4;
            o.extent_x = 420, o.extent_y = 400;
            break;
        default: /* regular lattice */
            o.jitter = 0, o.street_removal = 0, o.street_width_min = o.street_width_max = 12;
            break;
        }
        sl_scene s = gen(&o);
        check_city(s, &o, true);
        sl_scene_stats st;
        sl_scene_get_stats(s, &st);
        if (k == 3) {
            assert_int_equal(st.objects_per_kind[SL_KIND_CAR] + st.objects_per_kind[SL_KIND_TREE] +
                                 st.objects_per_kind[SL_KIND_LAMP],
                             0);
        }
        if (k == 1)
            assert_int_equal(st.objects_per_kind[SL_KIND_WATER], 0);
        sl_scene_destroy(s);
    }
}

static void test_many_seeds(void **state)
{
    (void)state;
    /* layouts must never fail for valid options: many seeds of a compact city, strong jitter */
    int n = sanitized() ? 8 : 40;
    for (int k = 0; k < n; k++) {
        sl_city_options o = sl_city_defaults(SL_CITY_TINY);
        o.seed = 77 + (uint64_t)k * 7919;
        o.jitter = 0.2f;
        o.street_removal = 0.4f;
        o.detail = 1;
        o.terrain = k % 2;
        sl_scene s = gen(&o);
        check_footprints(s);
        check_clear_of_streets(s);
        assert_int_equal(check_street_graph(s), 1);
        sl_scene_destroy(s);
    }
}

static void test_no_bridges(void **state)
{
    (void)state;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.bridge_spacing = 0;
    sl_scene s = gen(&o);
    const sl_street_edge *edges;
    uint32_t ne;
    sl_scene_street_graph(s, NULL, NULL, &edges, &ne);
    for (uint32_t e = 0; e < ne; e++)
        assert_false(edges[e].flags & SL_STREET_BRIDGE);
    /* the river splits the network in two (documented) */
    assert_int_equal(check_street_graph(s), 2);
    check_footprints(s);
    sl_scene_destroy(s);
    /* with bridges, some edges are flagged */
    o.bridge_spacing = 100;
    s = gen(&o);
    sl_scene_street_graph(s, NULL, NULL, &edges, &ne);
    uint32_t bridges = 0, avenues = 0;
    for (uint32_t e = 0; e < ne; e++)
        bridges += (edges[e].flags & SL_STREET_BRIDGE) != 0, avenues += (edges[e].flags & SL_STREET_AVENUE) != 0;
    assert_true(bridges >= 1);
    assert_true(avenues >= 1);
    sl_scene_destroy(s);
}

static void expect_invalid(const sl_city_options *o, sl_status want, const char *needle)
{
    sl_error err;
    memset(&err, 0, sizeof err);
    assert_int_equal(sl_city_options_validate(o, &err), want);
    if (!strstr(err.message, needle))
        fail_msg("message '%s' does not mention '%s'", err.message, needle);
    sl_scene s = (sl_scene)(uintptr_t)1;
    assert_int_equal(sl_gen_city(o, NULL, &s, &err), want);
    assert_null(s);
}

static void test_validation(void **state)
{
    (void)state;
    sl_city_options o;
#define BAD(stmt, want, needle)                    \
    do {                                           \
        o = sl_city_defaults(SL_CITY_TINY);        \
        stmt;                                      \
        expect_invalid(&o, want, needle);          \
    } while (0)
    BAD(o.detail = 5, SL_ERROR_INVALID_ARGUMENT, "detail");
    BAD(o.extent_x = 50, SL_ERROR_INVALID_ARGUMENT, "extent_x");
    BAD(o.extent_y = NAN, SL_ERROR_INVALID_ARGUMENT, "extent_y");
    BAD(o.jitter = 0.5f, SL_ERROR_INVALID_ARGUMENT, "jitter");
    BAD(o.block_size_max = 40, SL_ERROR_INVALID_ARGUMENT, "block_size_max");
    BAD(o.street_width_max = 8, SL_ERROR_INVALID_ARGUMENT, "street_width_max");
    BAD(o.avenue_width = INFINITY, SL_ERROR_INVALID_ARGUMENT, "avenue_width");
    BAD(o.park_fraction = 0.6f; o.square_fraction = 0.6f, SL_ERROR_INVALID_ARGUMENT, "park_fraction");
    BAD(o.height_max = 5, SL_ERROR_INVALID_ARGUMENT, "height_max");
    BAD(o.cars_per_km = -1, SL_ERROR_INVALID_ARGUMENT, "cars_per_km");
    BAD(o.lamp_spacing = 1, SL_ERROR_INVALID_ARGUMENT, "lamp_spacing");
    BAD(o.relief = 1e6f, SL_ERROR_INVALID_ARGUMENT, "relief");
    BAD(o.preset = (sl_city_preset)9, SL_ERROR_INVALID_ARGUMENT, "preset");
    BAD(o.street_width_min = 30; o.street_width_max = 40; o.avenue_width = 40, SL_ERROR_INVALID_ARGUMENT, "streets");
    BAD(o.river_width = 200, SL_ERROR_INVALID_ARGUMENT, "extent_y");
    BAD(o.extent_x = o.extent_y = 20000; o.detail = 4, SL_ERROR_LIMIT, "triangles");
#undef BAD
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_city_options_validate(NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_gen_city(NULL, NULL, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_city_defaults(SL_CITY_TINY);
    assert_int_equal(sl_gen_city(&o, NULL, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    /* a NULL error pointer is fine */
    o.detail = 9;
    assert_int_equal(sl_gen_city(&o, NULL, &s, NULL), SL_ERROR_INVALID_ARGUMENT);
}

static bool cancel_after(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)stage, (void)done, (void)total;
    int *calls = user;
    return ++*calls < 3;
}

static void test_cancel(void **state)
{
    (void)state;
    int calls = 0;
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.progress.fn = cancel_after;
    o.progress.user = &calls;
    sl_scene s = (sl_scene)(uintptr_t)1;
    sl_error err;
    assert_int_equal(sl_gen_city(&o, NULL, &s, &err), SL_ERROR_CANCELLED);
    assert_null(s);
    assert_int_equal(calls, 3);
}

/* A counting allocator: every byte handed out comes back, and the scene uses it. */
typedef struct counter {
    long blocks;
    size_t bytes;
} counter;

static void *c_alloc(void *user, size_t size, size_t align)
{
    counter *c = user;
    void *p = NULL;
    if (posix_memalign(&p, align < sizeof(void *) ? sizeof(void *) : align, size ? size : 1))
        return NULL;
    c->blocks++, c->bytes += size;
    return p;
}

static void *c_realloc(void *user, void *ptr, size_t old_size, size_t new_size, size_t align)
{
    counter *c = user;
    void *p = c_alloc(user, new_size, align);
    if (p && ptr) {
        memcpy(p, ptr, old_size < new_size ? old_size : new_size);
        free(ptr);
        c->blocks--, c->bytes -= old_size;
    }
    return p;
}

static void c_free(void *user, void *ptr, size_t size)
{
    counter *c = user;
    if (!ptr)
        return;
    free(ptr);
    c->blocks--, c->bytes -= size;
}

static void test_allocator(void **state)
{
    (void)state;
    counter cnt = {0, 0};
    sl_allocator a = {c_alloc, c_realloc, c_free, &cnt};
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.terrain = true;
    sl_scene s = NULL;
    sl_error err;
    assert_int_equal(sl_gen_city(&o, &a, &s, &err), SL_OK);
    assert_true(cnt.blocks > 0 && cnt.bytes > 0);
    sl_scene_destroy(s);
    assert_int_equal(cnt.blocks, 0);
    assert_int_equal(cnt.bytes, 0);
    /* a failure (cancel) also gives everything back */
    int calls = 0;
    o.progress.fn = cancel_after;
    o.progress.user = &calls;
    assert_int_equal(sl_gen_city(&o, &a, &s, &err), SL_ERROR_CANCELLED);
    assert_int_equal(cnt.blocks, 0);
    assert_int_equal(cnt.bytes, 0);
}


/* ---- the command: sightline gen city ---- */

static int run(const char *fmt, ...) SL_PRINTF(1, 2);
static int run(const char *fmt, ...)
{
    char cmd[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int rc = system(cmd);
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

static char *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    if (buf)
        buf[n] = 0;
    fclose(f);
    *size = (size_t)n;
    return buf;
}

static void test_cli(void **state)
{
    (void)state;
    const char *sl = getenv("SL_SIGHTLINE");
    if (!sl || access(sl, X_OK) != 0)
        skip();
    char dir[] = "/tmp/sl_test_gen_city_XXXXXX";
    assert_non_null(mkdtemp(dir));
    assert_int_equal(run("%s gen --help > %s/help.txt", sl, dir), 0);
    assert_int_equal(run("%s gen 2> /dev/null", sl), 2);
    assert_int_equal(run("%s gen town 2> /dev/null", sl), 2);
    assert_int_equal(run("%s gen city --bogus 2> /dev/null", sl), 2);
    assert_int_equal(run("%s gen city --preset paris 2> /dev/null", sl), 2);
    assert_int_equal(run("%s gen city --preset tiny --detail 9 --dry-run 2> %s/err.txt", sl, dir), 2);
    size_t n;
    char path[512];
    snprintf(path, sizeof path, "%s/err.txt", dir);
    char *text = slurp(path, &n);
    assert_non_null(text);
    assert_non_null(strstr(text, "detail"));
    free(text);
    /* two runs, byte-identical files; the JSON summary agrees with the file */
    assert_int_equal(run("%s gen city --preset tiny --seed 5 --terrain -o %s/a.slscene --json --quiet > %s/a.json", sl, dir,
                         dir),
                     0);
    assert_int_equal(run("%s gen city --seed 5 --terrain --preset=tiny --output %s/b.slscene --quiet > /dev/null", sl, dir),
                     0);
    char pa[512], pb[512];
    snprintf(pa, sizeof pa, "%s/a.slscene", dir);
    snprintf(pb, sizeof pb, "%s/b.slscene", dir);
    size_t na, nb;
    char *fa = slurp(pa, &na), *fb = slurp(pb, &nb);
    assert_true(fa && fb);
    assert_true(na == nb && memcmp(fa, fb, na) == 0);
    free(fa), free(fb);
    snprintf(pa, sizeof pa, "%s/a.json", dir);
    char *json = slurp(pa, &n);
    assert_non_null(json);
    sl_city_options o = sl_city_defaults(SL_CITY_TINY);
    o.seed = 5, o.terrain = true;
    sl_scene mem = gen(&o);
    char want[64];
    snprintf(want, sizeof want, "\"footprints\":%u", sl_scene_footprint_count(mem));
    assert_non_null(strstr(json, want));
    assert_non_null(strstr(json, "\"preset\":\"tiny\""));
    free(json);
    snprintf(pa, sizeof pa, "%s/a.slscene", dir);
    sl_scene loaded = NULL;
    sl_error err;
    if (sl_scene_load(pa, NULL, NULL, &loaded, &err) != SL_OK)
        fail_msg("loading the generated file: %s", err.message);
    assert_int_equal(sl_scene_object_count(loaded), sl_scene_object_count(mem));
    assert_int_equal(sl_scene_footprint_count(loaded), sl_scene_footprint_count(mem));
    assert_int_equal(sl_scene_street_polygon_count(loaded), sl_scene_street_polygon_count(mem));
    assert_string_equal(sl_scene_meta(loaded, "seed"), "5");
    sl_scene_destroy(loaded);
    sl_scene_destroy(mem);
    /* the default output name */
    assert_int_equal(run("cd %s && %s gen city --preset tiny --seed 3 --quiet > /dev/null", dir, sl), 0);
    snprintf(pa, sizeof pa, "%s/city-tiny-3.slscene", dir);
    assert_int_equal(access(pa, R_OK), 0);
    /* the oldtown style and the stats */
    assert_int_equal(run("%s gen city --preset tiny --style baroque --dry-run 2> /dev/null", sl), 2);
    /* the scene spec city:oldtown-small[:SEED] */
    assert_int_equal(run("%s info city:oldtown-small:4 > /dev/null", sl), 0);
    assert_int_equal(run("%s info city:oldtown-big 2> /dev/null", sl), 1);
    assert_int_equal(run("%s gen city --preset oldtown-small --stats --dry-run --json --quiet > %s/o.json", sl, dir), 0);
    snprintf(pa, sizeof pa, "%s/o.json", dir);
    json = slurp(pa, &n);
    assert_non_null(json);
    assert_non_null(strstr(json, "\"style\":\"oldtown\""));
    assert_non_null(strstr(json, "\"street_fraction\":"));
    assert_non_null(strstr(json, "\"sight_mean\":"));
    free(json);
    assert_int_equal(run("%s gen city --preset tiny --style oldtown --district 3 --meander 6 --stats --quiet -o %s/t.slscene "
                         "> %s/t.txt", sl, dir, dir),
                     0);
    snprintf(pa, sizeof pa, "%s/t.txt", dir);
    text = slurp(pa, &n);
    assert_non_null(text);
    assert_non_null(strstr(text, "style oldtown"));
    assert_non_null(strstr(text, "street area"));
    free(text);
    snprintf(pa, sizeof pa, "%s/t.slscene", dir);
    if (sl_scene_load(pa, NULL, NULL, &loaded, &err) != SL_OK)
        fail_msg("loading the generated file: %s", err.message);
    assert_string_equal(sl_scene_meta(loaded, "city.style"), "oldtown");
    sl_city_stats cs;
    assert_int_equal(sl_city_measure(loaded, &cs, &err), SL_OK);
    assert_true(cs.extent_x == 300 && cs.extent_y == 260);
    sl_scene_destroy(loaded);
    /* no partial output when the target cannot be written */
    assert_int_equal(run("%s gen city --preset tiny -o %s/missing/x.slscene --quiet 2> /dev/null", sl, dir), 1);
    assert_int_equal(run("rm -rf %s", dir), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_presets),       cmocka_unit_test(test_tiny),        cmocka_unit_test(test_metadata),
        cmocka_unit_test(test_determinism),   cmocka_unit_test(test_grid_pinned),   cmocka_unit_test(test_oldtown), cmocka_unit_test(test_oldtown_options),   cmocka_unit_test(test_detail_levels), cmocka_unit_test(test_terrain),
        cmocka_unit_test(test_variants),      cmocka_unit_test(test_many_seeds),  cmocka_unit_test(test_no_bridges),
        cmocka_unit_test(test_validation),    cmocka_unit_test(test_cancel),      cmocka_unit_test(test_allocator),
        cmocka_unit_test(test_cli),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

/* The online occlusion methods on hand-built scenes where the answer is obvious (a wall in front
 * of a box), plus the shared machinery: occluder proxies that lie inside their buildings, the
 * selection, moving occluders and occludees, option handling, allocation-free steady state,
 * lazy versus busy grid, and the debugging outputs (PNG dumps, a recorded frame that replays
 * bit for bit, hostile recordings rejected with a clear message). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/opts.h"
#include "core/sl_core.h"
#include "cull/occlusion/exact.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/select.h"
#include "cull/occlusion/view.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"
#include "support/counting_alloc.h"
#include "support/city_views.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

/* The occlusion framework's frame view of a camera (through its sl_view). */
static void occ_view_cam(sl_occ_view *v, const sl_camera *cam)
{
    sl_view view;
    assert_int_equal(sl_view_from_camera(cam, &view, NULL), SL_OK);
    sl_occ_view_init(v, &view);
}

/* every method of this file, with its default options */
static const char *const g_all[] = {"hzb", "hom", "lazygrid", "lazygrid-z", "busygrid", "frusta", "plp", "cplp"};
static const char *const g_conservative[] = {"hzb", "hom", "lazygrid", "lazygrid-z", "busygrid", "frusta", "cplp"};

/* ---- scene helpers ---- */

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind, uint32_t flags, const sl_affine *xf)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    sl_error err;
    sl_mesh_desc md = {p, NULL, 8, idx, 12, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, xf, 0xffffffffu, kind, flags, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* A building: a box object flagged OCCLUDER plus its footprint prism (the same rectangle). */
static uint32_t add_building(sl_scene s, float x0, float y0, float x1, float y1, float h)
{
    uint32_t o = add_box(s, (sl_vec3){x0, y0, 0}, (sl_vec3){x1, y1, h}, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER, NULL);
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    sl_footprint_desc fd = {xy, 4, 0, h, o};
    sl_error err;
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    return o;
}

/* The wall scene: a building across x = 20..22, y = -30..10 and a small box behind it (hidden from
 * the origin looking along +x), a box in front of it (visible), and a box beyond its end. */
typedef struct wall_scene {
    sl_scene s;
    uint32_t wall, hidden, front, beside;
} wall_scene;

static wall_scene wall_scene_make(void)
{
    wall_scene w;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &w.s, &err), SL_OK);
    w.wall = add_building(w.s, 20, -30, 22, 10, 15);
    w.hidden = add_box(w.s, (sl_vec3){40, -2, 0.5f}, (sl_vec3){42, 2, 3}, SL_KIND_OTHER, 0, NULL);
    w.front = add_box(w.s, (sl_vec3){10, -1, 0}, (sl_vec3){11, 1, 2}, SL_KIND_OTHER, 0, NULL);
    w.beside = add_box(w.s, (sl_vec3){40, 26, 0}, (sl_vec3){42, 30, 3}, SL_KIND_OTHER, 0, NULL);
    return w;
}

static sl_camera wall_camera(uint32_t w, uint32_t h)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){0, 0, 1.7f};
    c.yaw = 0; /* along +x: the wall fills the right of the view, "beside" shows past its end */
    c.fov_y = 1.2f;
    c.width = w;
    c.height = h;
    c.far_plane = 1000;
    return c;
}

static bool contains(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

static uint32_t cull(sl_culler c, const sl_camera *cam, uint32_t *out, uint32_t n)
{
    uint32_t k;
    sl_error err;
    if (sl_culler_cull(c, cam, out, n, &k, &err) != SL_OK)
        fail_msg("%s: %s", sl_culler_method(c), err.message);
    return k;
}

/* A field of n thin vertical poles (side `w` metres, 3 m tall) at random 100-400 m ahead of
 * wall_camera, in a new scene. */
static sl_scene pole_field(uint64_t seed, uint32_t n, float w)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_rng rng;
    sl_rng_seed(&rng, seed, 1);
    for (uint32_t i = 0; i < n; i++) {
        float x = 100.0f + 300.0f * sl_rng_float(&rng), y = (sl_rng_float(&rng) - 0.5f) * 0.8f * x;
        add_box(s, (sl_vec3){x, y, 0}, (sl_vec3){x + w, y + w, 3}, SL_KIND_LAMP, 0, NULL);
    }
    return s;
}

/* Fail unless every object of the oracle frame is among the k objects kept. */
static void assert_keeps_visible(const char *what, const uint32_t *out, uint32_t k, const sl_oracle_frame *fr)
{
    for (uint32_t i = 0; i < fr->visible_count; i++)
        if (!contains(out, k, fr->visible[i]))
            fail_msg("%s dropped object %u, which the oracle sees", what, fr->visible[i]);
}

/* ---- proxies ---- */

/* Every prism of the tiny city lies inside its footprint: each vertex at least `inset` from
 * every footprint edge and inside the polygon, its heights inset from base and roof. */
static void test_prisms_inside(void **state)
{
    (void)state;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_occ_options oo = {0.1f, false, true, 16, false};
    sl_occ_set *set;
    assert_int_equal(sl_occ_set_create(s, &oo, sl_default_allocator(), &set, &err), SL_OK);
    assert_true(set->prisms > 0);
    assert_true(set->prisms_rejected * 10 <= set->prisms); /* almost every footprint certifies */
    uint32_t checked = 0;
    for (uint32_t p = 0; p < set->proxy_count; p++) {
        const sl_occ_proxy *pr = &set->proxies[p];
        if (pr->kind != SL_OCC_PRISM)
            continue;
        sl_footprint_view fp = sl_scene_footprint(s, pr->source);
        assert_true(pr->inset >= 0.009f && pr->inset <= 0.1f);
        assert_int_equal(set->object_proxy[fp.object], p);
        for (uint32_t t = 0; t < pr->count; t++)
            for (int c = 0; c < 3; c++) {
                const float *v = set->prism_pos + 3 * set->prism_idx[3 * (pr->first + t) + (uint32_t)c];
                assert_true(v[2] >= fp.base_z + pr->inset - 1e-4f && v[2] <= fp.roof_z - pr->inset + 1e-4f);
                bool in = false;
                double dmin = INFINITY;
                for (uint32_t i = 0, j = fp.vertex_count - 1; i < fp.vertex_count; j = i++) {
                    double ax = fp.xy[2 * j], ay = fp.xy[2 * j + 1], bx = fp.xy[2 * i], by = fp.xy[2 * i + 1];
                    if ((by > v[1]) != (ay > v[1]) && v[0] < (ax - bx) * (v[1] - by) / (ay - by) + bx)
                        in = !in;
                    double ex = ax - bx, ey = ay - by, l2 = ex * ex + ey * ey;
                    double tt = l2 > 0 ? ((v[0] - bx) * ex + (v[1] - by) * ey) / l2 : 0;
                    tt = tt < 0 ? 0 : (tt > 1 ? 1 : tt);
                    dmin = fmin(dmin, hypot(bx + tt * ex - v[0], by + tt * ey - v[1]));
                }
                assert_true(in);
                assert_true(dmin >= pr->inset * 0.999);
                checked++;
            }
        /* faces: walls and roof/floor pieces, each planar convex with a unit normal */
        assert_true(pr->face_count >= fp.vertex_count + 2);
        for (uint32_t f = 0; f < pr->face_count; f++) {
            const sl_occ_face *fc = &set->faces[pr->face_first + f];
            float l = sqrtf(fc->normal.x * fc->normal.x + fc->normal.y * fc->normal.y + fc->normal.z * fc->normal.z);
            assert_true(fabsf(l - 1) < 1e-4f);
            assert_true(fc->area > 0);
        }
    }
    assert_true(checked > 1000);
    sl_occ_set_destroy(set);
    sl_scene_destroy(s);
}

/* Selection: the wall is the best occluder from in front of it; nothing is chosen when the eye is
 * inside the building; a prism too far for its inset is not usable. */
static void test_selection(void **state)
{
    (void)state;
    wall_scene w = wall_scene_make();
    sl_error err;
    sl_occ_options oo = {0.1f, false, false, 0, false};
    sl_occ_set *set;
    assert_int_equal(sl_occ_set_create(w.s, &oo, sl_default_allocator(), &set, &err), SL_OK);
    assert_int_equal(set->proxy_count, 1);
    sl_bvh bvh;
    assert_int_equal(sl_bvh_build(w.s, NULL, &bvh, &err), SL_OK);
    float *area = malloc(bvh->node_slots * sizeof(float));
    sl_occ_node_areas(set, bvh, area);
    sl_occ_pick heap[4], out[4];
    sl_camera cam = wall_camera(320, 240);
    sl_occ_view v;
    occ_view_cam(&v, &cam);
    assert_int_equal(sl_occ_select(set, &v, bvh, area, 4, 1000, 0.0005f, heap, out, NULL), 1);
    assert_int_equal(out[0].proxy, 0);
    assert_true(out[0].quality > 0.5f); /* a 60x15 m wall at 20 m: about 1.5 sr */
    /* the triangle budget can exclude it */
    assert_int_equal(sl_occ_select(set, &v, bvh, area, 4, 5, 0.0005f, heap, out, NULL), 0);
    /* inside the building: not usable */
    cam.position = (sl_vec3){21, 0, 5};
    occ_view_cam(&v, &cam);
    assert_false(sl_occ_usable(set, 0, &v));
    /* 30 km away at 320x240: 0.1 m is less than 1/32 pixel */
    cam.position = (sl_vec3){-30000, 0, 5};
    cam.far_plane = 100000;
    occ_view_cam(&v, &cam);
    assert_false(sl_occ_usable(set, 0, &v));
    cam.position = (sl_vec3){-100, 0, 5};
    occ_view_cam(&v, &cam);
    assert_true(sl_occ_usable(set, 0, &v));
    free(area);
    sl_bvh_destroy(bvh);
    sl_occ_set_destroy(set);
    sl_scene_destroy(w.s);
}

/* ---- the methods on the wall scene ---- */

static void check_wall(const char *method, const char *options, const sl_camera *cam, bool expect_cull)
{
    wall_scene w = wall_scene_make();
    sl_culler c;
    sl_error err;
    if (sl_culler_create(method, w.s, options, NULL, &c, &err) != SL_OK)
        fail_msg("%s: %s", method, err.message);
    uint32_t out[8];
    for (int rep = 0; rep < 2; rep++) {
        uint32_t k = cull(c, cam, out, 8);
        if (!contains(out, k, w.wall) || !contains(out, k, w.front) || !contains(out, k, w.beside))
            fail_msg("%s %s: dropped a visible object (%u kept)", method, options ? options : "", k);
        if (expect_cull && contains(out, k, w.hidden))
            fail_msg("%s %s: kept the box behind the wall", method, options ? options : "");
        for (uint32_t i = 1; i < k; i++)
            assert_true(out[i - 1] < out[i]);
        sl_cull_stats st;
        sl_culler_stats(c, &st);
        assert_int_equal(st.objects_visible, k);
        assert_true(st.phase_count >= 1);
    }
    /* the oracle agrees that the box is hidden and the others are seen */
    sl_oracle o;
    assert_int_equal(sl_oracle_create(w.s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(o, cam, &fr, &err), SL_OK);
    assert_false(contains(fr.visible, fr.visible_count, w.hidden));
    assert_true(contains(fr.visible, fr.visible_count, w.beside));
    sl_oracle_destroy(o);
    sl_culler_destroy(c);
    sl_scene_destroy(w.s);
}

static void test_wall_every_method(void **state)
{
    (void)state;
    sl_camera cam = wall_camera(320, 240);
    /* plp and cplp project whole octree cells until their budget: this scene is one cell below it */
    for (size_t i = 0; i < SL_COUNTOF(g_all); i++)
        check_wall(g_all[i], NULL, &cam, strcmp(g_all[i], "plp") != 0 && strcmp(g_all[i], "cplp") != 0);
    /* options that change the work, not the guarantee */
    check_wall("hzb", "pyramid=false", &cam, true);
    check_wall("hzb", "render_visible=false,refresh=0", &cam, true);
    check_wall("hzb", "occluders=0", &cam, false); /* the wall itself is then found visible and rendered */
    check_wall("hzb", "threads=1,isa=scalar", &cam, true);
    check_wall("hom", "depth=zbuffer", &cam, true);
    check_wall("lazygrid", "cell=8", &cam, true);
    check_wall("lazygrid-z", "cell=128", &cam, true);
    check_wall("cplp", "budget=0", &cam, true);
    /* orthographic, looking along +x from behind the origin */
    cam.projection = SL_ORTHOGRAPHIC;
    cam.ortho_height = 40;
    cam.yaw = 0;
    cam.position = (sl_vec3){-5, 20, 5};
    for (size_t i = 0; i < SL_COUNTOF(g_conservative); i++) {
        wall_scene w = wall_scene_make();
        sl_culler c;
        sl_error err;
        assert_int_equal(sl_culler_create(g_conservative[i], w.s, NULL, NULL, &c, &err), SL_OK);
        uint32_t out[8], k = cull(c, &cam, out, 8);
        assert_true(contains(out, k, w.wall));
        if (strcmp(g_conservative[i], "cplp") != 0 && contains(out, k, w.hidden))
            fail_msg("%s (orthographic) kept the box behind the wall", g_conservative[i]);
        sl_culler_destroy(c);
        sl_scene_destroy(w.s);
    }
}

/* ---- objects tested by their own triangles ---- */

/* A thin sliver behind the wall whose box reaches past the wall's end: the box test keeps it, the
 * pixel-centre test of its triangles (sample_tris) drops it, and so does the outward-conservative
 * mesh test (mesh_test); the oracle agrees it is hidden. In hzb and the lazy grids. */
static void test_sampled_mesh_test(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t wall = add_building(s, 20, -30, 22, 10, 15);
    /* from (60, -10) to (100, 45), 1 to 2 m high: inside the wall's shadow wedge (angles -56 to 27
     * degrees from the eye), its box's corner (60, 45) at 37 degrees is not; the box's rectangle
     * holds some 700 pixels */
    const float p[12] = {60, -10, 1, 100, 45, 1, 100, 45, 2, 60, -10, 2};
    const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    sl_mesh_desc md = {p, NULL, 4, idx, 2, NULL};
    uint32_t mesh, sliver;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &sliver, &err), SL_OK);
    sl_camera cam = wall_camera(320, 240);
    sl_oracle o;
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
    assert_true(contains(fr.visible, fr.visible_count, wall));
    assert_false(contains(fr.visible, fr.visible_count, sliver));
    sl_oracle_destroy(o);
    static const struct {
        const char *method, *options;
        bool dropped;
    } cases[] = {
        {"hzb", "res=culling,mesh_test=0,sample_tris=0", false},
        {"hzb", "res=culling,mesh_test=0,sample_px=1024", true},
        {"hzb", "res=culling,mesh_test=0,sample_px=4", false}, /* the box's rectangle is larger */
        {"hzb", "res=culling,sample_tris=0", true},
        {"hzb", "res=culling", true},
        {"lazygrid", "res=culling,mesh_test=0,sample_tris=0", false},
        {"lazygrid", "res=culling,mesh_test=0,sample_px=1024", true},
        {"lazygrid-z", "res=culling,mesh_test=0,sample_px=1024", true},
        {"busygrid", "res=culling,mesh_test=0,sample_px=1024", true},
        {"busygrid", "res=culling", true},
    };
    for (size_t i = 0; i < SL_COUNTOF(cases); i++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(cases[i].method, s, cases[i].options, NULL, &c, &err), SL_OK);
        uint32_t out[4], k = cull(c, &cam, out, 4);
        assert_true(contains(out, k, wall));
        if (contains(out, k, sliver) == cases[i].dropped)
            fail_msg("%s %s: the sliver was %s", cases[i].method, cases[i].options ? cases[i].options : "",
                     cases[i].dropped ? "kept" : "dropped");
        sl_culler_destroy(c);
    }
    sl_scene_destroy(s);
}

/* The pixel-centre test asks one rectangle query for a triangle's centres, then one per row, and
 * only then pixel by pixel; that is exact because a rectangle hidden in a buffer proves each of its
 * pixels hidden. Checked on every available path over random occluders, rectangles and depths:
 * a rectangle answered OCCLUDED has every 1x1 query inside it OCCLUDED. */
static void test_rect_query_monotone(void **state)
{
    (void)state;
    sl_rng rng;
    for (int isa = SL_RASTER_ISA_SCALAR; isa <= SL_RASTER_ISA_AVX512; isa++) {
        if (!sl_raster_isa_available((sl_raster_isa)isa))
            continue;
        sl_rng_seed(&rng, 7, (uint64_t)isa);
        sl_raster_options ro = sl_raster_default_options(160, 96);
        ro.isa = (sl_raster_isa)isa;
        sl_raster *r;
        sl_error err;
        assert_int_equal(sl_raster_create(&ro, NULL, &r, &err), SL_OK);
        assert_int_equal(sl_raster_begin_frame(r, SL_RASTER_DEPTH_INV_W, &err), SL_OK);
        /* triangles given as (x_clip, y_clip, w) at w between 2 and 50, mapped to clip (x, y, 0, w)
         * as render_mesh_shrunk does: partial layers along their edges, full coverage inside */
        enum { TRIS = 40 };
        float v[TRIS * 3 * 3];
        uint32_t idx[TRIS * 3];
        for (uint32_t t = 0; t < TRIS * 3; t++) {
            float w = sl_rng_range(&rng, 2.0f, 50.0f);
            v[3 * t] = sl_rng_range(&rng, -1.2f, 1.2f) * w;
            v[3 * t + 1] = sl_rng_range(&rng, -1.2f, 1.2f) * w;
            v[3 * t + 2] = w;
            idx[t] = t;
        }
        static const float to_clip[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0};
        assert_int_equal(
            sl_raster_render_triangles(r, v, TRIS * 3, idx, TRIS, 12, to_clip, SL_RASTER_CULL_NONE, &err), SL_OK);
        uint32_t occluded = 0;
        for (int q = 0; q < 4000; q++) {
            int32_t x0 = (int32_t)sl_rng_below(&rng, 160), y0 = (int32_t)sl_rng_below(&rng, 96);
            int32_t x1 = x0 + 1 + (int32_t)sl_rng_below(&rng, 24), y1 = y0 + 1 + (int32_t)sl_rng_below(&rng, 12);
            float d = 1.0f / sl_rng_range(&rng, 1.0f, 80.0f);
            if (sl_raster_test_rect(r, x0, y0, x1, y1, d) != SL_RASTER_OCCLUDED)
                continue;
            occluded++;
            for (int32_t y = y0; y < y1 && y < 96; y++)
                for (int32_t x = x0; x < x1 && x < 160; x++)
                    if (sl_raster_test_rect(r, x, y, x + 1, y + 1, d) != SL_RASTER_OCCLUDED)
                        fail_msg("%s: rectangle [%d,%d)x[%d,%d) hidden at %g but not pixel (%d, %d)",
                                 sl_raster_isa_name((sl_raster_isa)isa), x0, x1, y0, y1, (double)d, x, y);
        }
        assert_true(occluded > 100); /* the property was exercised */
        sl_raster_destroy(r);
    }
}

/* Poles far thinner than a pixel in an empty field: the pixel-centre test drops the ones whose
 * triangles come within 1/32 pixel of no pixel centre (most of them), never one the oracle sees,
 * and keeps every one when turned off. */
static void test_sampled_subpixel(void **state)
{
    (void)state;
    const uint32_t n = 200;
    sl_scene s = pole_field(7, n, 0.02f);
    sl_error err;
    sl_camera cam = wall_camera(320, 240);
    sl_oracle o;
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
    uint32_t out[256];
    static const char *const methods[] = {"hzb", "lazygrid", "lazygrid-z"};
    for (size_t m = 0; m < SL_COUNTOF(methods); m++) {
        sl_culler c;
        /* the pixel-centre tests: the tighter mode (res=culling, conservative at this resolution) */
        assert_int_equal(sl_culler_create(methods[m], s, "res=culling", NULL, &c, &err), SL_OK);
        uint32_t k = cull(c, &cam, out, 256);
        assert_keeps_visible(methods[m], out, k, &fr);
        if (k > n / 2)
            fail_msg("%s kept %u of %u sub-pixel poles (the oracle sees %u)", methods[m], k, n, fr.visible_count);
        sl_culler_destroy(c);
        /* hzb's silhouette test of the box and its exact layer would cull them too */
        assert_int_equal(sl_culler_create(methods[m], s,
                                          m == 0 ? "sample_tris=0,mesh_test=0,box_rows=0,exact_px=0"
                                                 : "sample_tris=0,mesh_test=0",
                                          NULL, &c, &err),
                         SL_OK);
        uint32_t in_view = cull(c, &cam, out, 256);
        assert_true(in_view > k);
        sl_culler_destroy(c);
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* The exact layer reproduces the oracle's fragments bit for bit: every object of the tiny city
 * (instanced, closed convex parts, objects crossing the near plane) drawn into it gives the
 * oracle's depth and id buffers exactly, for a street view and a pitched, rolled one. */
static void test_exact_layer_is_oracle(void **state)
{
    (void)state;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_aabb sb = sl_scene_bounds(s);
    for (int view = 0; view < 2; view++) {
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){0.5f * (sb.min.x + sb.max.x) + 3.0f, 0.5f * (sb.min.y + sb.max.y) + 1.0f, 1.7f};
        cam.yaw = view ? 2.3f : 0.4f;
        cam.pitch = view ? 0.35f : 0.0f;
        cam.roll = view ? 0.2f : 0.0f;
        cam.width = 320;
        cam.height = 240;
        cam.near_plane = 0.1f;
        cam.far_plane = 2000.0f;
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        sl_oracle_view ov;
        assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
        sl_occ_view v;
        occ_view_cam(&v, &cam);
        sl_occ_exact e;
        assert_int_equal(sl_occ_exact_init(&e, sl_default_allocator(), &err), SL_OK);
        for (int pass = 0; pass < 2; pass++) { /* the second pass clears the first's rectangles */
            assert_int_equal(sl_occ_exact_begin(&e, &v, &err), SL_OK);
            for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
                sl_aabb b = sl_scene_object_bounds(s, i);
                sl_occ_rect r;
                int k = sl_occ_project_box(&v, &b, &r);
                if (k == SL_OCC_OUT)
                    continue;
                if (k == SL_OCC_NEAR)
                    r = (sl_occ_rect){0, 0, (int32_t)cam.width, (int32_t)cam.height, INFINITY};
                assert_int_equal(sl_occ_exact_draw(&e, s, i, &r, &err), SL_OK);
            }
        }
        size_t n = (size_t)cam.width * cam.height, same = 0;
        for (size_t i = 0; i < n; i++)
            same += memcmp(&e.depth[i], &ov.depth[i], sizeof(float)) == 0 && e.ids[i] == ov.ids[i];
        if (same != n)
            fail_msg("view %d: %zu of %zu pixels differ from the oracle's", view, n - same, n);
        /* a drawn pixel hides depths a little farther than its own, never its own */
        for (size_t i = 0; i < n; i += 7) {
            if (!(ov.depth[i] > 0.0f))
                continue;
            double rd = ov.depth[i];
            int32_t x = (int32_t)(i % cam.width), y = (int32_t)(i / cam.width);
            assert_false(sl_occ_exact_hides(&e, x, y, rd));
            assert_false(sl_occ_exact_hides(&e, x, y, rd * (1.0 - 1e-7)));
            assert_true(sl_occ_exact_hides(&e, x, y, rd * (1.0 - 1e-5)));
        }
        /* a box's depth bound is at least the depth of every pixel its object owns */
        for (size_t i = 0; i < n; i++) {
            if (ov.ids[i] == SL_NONE)
                continue;
            sl_aabb b = sl_scene_object_bounds(s, ov.ids[i]);
            assert_true(sl_occ_exact_box_depth(&e, &b) >= (double)ov.depth[i]);
        }
        sl_occ_exact_free(&e);
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* A row of small boxes straight down the view axis (a line of trees at the end of a street), each
 * hidden by the one before it, none of them an occluder: only the exact layer can hide them. hzb
 * keeps the first few, exact_px=0 keeps them all; nothing the oracle sees is dropped. */
static void test_exact_layer_row(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    const uint32_t n = 60;
    for (uint32_t i = 0; i < n; i++) {
        float x = 300.0f + 12.0f * (float)i;
        add_box(s, (sl_vec3){x, -1.5f, 0}, (sl_vec3){x + 3.0f, 1.5f, 4.0f}, SL_KIND_TREE, 0, NULL);
    }
    sl_camera cam = wall_camera(320, 240);
    sl_oracle o;
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
    assert_true(fr.visible_count < n / 4);
    uint32_t out[64];
    sl_culler c;
    assert_int_equal(sl_culler_create("hzb", s, "res=culling", NULL, &c, &err), SL_OK);
    uint32_t k = cull(c, &cam, out, 64);
    assert_keeps_visible("hzb", out, k, &fr);
    if (k > 2 * fr.visible_count + 2)
        fail_msg("hzb kept %u of %u boxes (the oracle sees %u)", k, n, fr.visible_count);
    sl_culler_destroy(c);
    assert_int_equal(sl_culler_create("hzb", s, "res=culling,exact_px=0", NULL, &c, &err), SL_OK);
    uint32_t without = cull(c, &cam, out, 64);
    assert_true(without > 2 * k);
    sl_culler_destroy(c);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* Boxes whose silhouette covers no pixel centre (thin poles between pixel columns) are culled by
 * the silhouette test of their box alone (box_rows; the triangle tests are off), and none the
 * oracle sees is dropped; box_rows=0 keeps more of them. */
static void test_box_rows(void **state)
{
    (void)state;
    const uint32_t n = 200;
    sl_scene s = pole_field(11, n, 0.05f);
    sl_error err;
    sl_camera cam = wall_camera(320, 240);
    sl_oracle o;
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
    uint32_t out[256];
    sl_culler c;
    assert_int_equal(sl_culler_create("hzb", s, "res=culling,sample_tris=0,mesh_test=0,exact_px=0", NULL, &c, &err), SL_OK);
    uint32_t k = cull(c, &cam, out, 256);
    assert_keeps_visible("hzb", out, k, &fr);
    sl_culler_destroy(c);
    assert_int_equal(sl_culler_create("hzb", s, "res=culling,sample_tris=0,mesh_test=0,exact_px=0,box_rows=0", NULL, &c, &err),
                     SL_OK);
    uint32_t without = cull(c, &cam, out, 256);
    if (!(k < without && k < n / 2))
        fail_msg("box_rows kept %u poles, box_rows=0 %u, of %u (the oracle sees %u)", k, without, n,
                 fr.visible_count);
    sl_culler_destroy(c);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* The city generator flags its props (trees, lamps, cars) as occluders, and cars stay dynamic. */
static void test_city_props_occlude(void **state)
{
    (void)state;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    uint32_t props = 0;
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        sl_object_view v = sl_scene_object(s, i);
        if (v.kind != SL_KIND_TREE && v.kind != SL_KIND_LAMP && v.kind != SL_KIND_CAR)
            continue;
        props++;
        assert_true(v.flags & SL_OBJECT_OCCLUDER);
        assert_int_equal((v.flags & SL_OBJECT_DYNAMIC) != 0, v.kind == SL_KIND_CAR);
    }
    assert_true(props > 0);
    sl_scene_destroy(s);
}

/* A moving occluder (an OCCLUDER mesh without footprint, flagged DYNAMIC) hides a box and a
 * car only while it stands in front of them; once it (and the car) moved, both are kept again,
 * and hidden again when everything is back. */
static void test_moving(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* a 1 x 40 x 20 m panel at x = 20, moved by its transform */
    sl_affine at = sl_affine_identity();
    uint32_t panel = add_box(s, (sl_vec3){20, -20, 0}, (sl_vec3){21, 20, 20}, SL_KIND_OTHER,
                             SL_OBJECT_OCCLUDER | SL_OBJECT_DYNAMIC, &at);
    uint32_t box = add_box(s, (sl_vec3){40, -2, 0}, (sl_vec3){42, 2, 3}, SL_KIND_OTHER, 0, NULL);
    sl_affine car_at = sl_affine_identity();
    car_at.m[3] = 45, car_at.m[7] = 8;
    uint32_t car = add_box(s, (sl_vec3){-1, -1, 0}, (sl_vec3){1, 1, 1.5f}, SL_KIND_CAR, SL_OBJECT_DYNAMIC, &car_at);
    uint32_t n = sl_scene_object_count(s), out[8];
    sl_camera cam = wall_camera(320, 240);
    for (size_t i = 0; i < SL_COUNTOF(g_conservative); i++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(g_conservative[i], s, NULL, NULL, &c, &err), SL_OK);
        /* frusta keeps no faces of moving meshes; cplp's octree cells are coarse here */
        bool culls = strcmp(g_conservative[i], "frusta") != 0 && strcmp(g_conservative[i], "cplp") != 0;
        uint32_t k = cull(c, &cam, out, n);
        assert_true(contains(out, k, panel));
        if (culls && (contains(out, k, box) || contains(out, k, car)))
            fail_msg("%s: the panel does not hide the box and the car", g_conservative[i]);
        /* move the panel away and the car in front of it */
        sl_affine away = sl_affine_identity(), car_near = car_at;
        away.m[7] = -200;
        car_near.m[3] = 12, car_near.m[7] = 3;
        assert_int_equal(sl_scene_set_object_transform(s, panel, &away, &err), SL_OK);
        assert_int_equal(sl_scene_set_object_transform(s, car, &car_near, &err), SL_OK);
        assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
        k = cull(c, &cam, out, n);
        if (!contains(out, k, box) || !contains(out, k, car))
            fail_msg("%s: a moved object is still culled", g_conservative[i]);
        assert_false(contains(out, k, panel));
        /* and back */
        assert_int_equal(sl_scene_set_object_transform(s, panel, &at, &err), SL_OK);
        assert_int_equal(sl_scene_set_object_transform(s, car, &car_at, &err), SL_OK);
        assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
        k = cull(c, &cam, out, n);
        assert_true(contains(out, k, panel));
        if (culls && (contains(out, k, box) || contains(out, k, car)))
            fail_msg("%s: the panel moved back does not hide the box and the car", g_conservative[i]);
        sl_culler_destroy(c);
    }
    sl_scene_destroy(s);
}

/* A building moved off its footprint: its prism is no longer trusted (the box it used to hide
 * comes back); its mesh takes over as a MESH proxy only if it has one (here it has not). */
static void test_moved_building(void **state)
{
    (void)state;
    wall_scene w = wall_scene_make();
    sl_error err;
    sl_camera cam = wall_camera(320, 240);
    sl_culler c;
    assert_int_equal(sl_culler_create("hzb", w.s, NULL, NULL, &c, &err), SL_OK);
    uint32_t out[8], k = cull(c, &cam, out, 8);
    assert_false(contains(out, k, w.hidden));
    sl_affine up = sl_affine_identity();
    up.m[11] = 100; /* lift the building 100 m */
    assert_int_equal(sl_scene_set_object_transform(w.s, w.wall, &up, &err), SL_OK);
    assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
    k = cull(c, &cam, out, 8);
    assert_true(contains(out, k, w.hidden));
    sl_culler_destroy(c);
    sl_scene_destroy(w.s);
}

/* ---- options, guarantees, allocation ---- */

static void test_options(void **state)
{
    (void)state;
    sl_error err;
    assert_int_equal(sl_cull_method_check_options("hzb", "nosuch=1", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "nosuch"));
    assert_non_null(strstr(err.message, "pyramid"));
    assert_int_equal(sl_cull_method_check_options("hzb", "threads=0", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("hzb", "isa=neon", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("lazygrid", "cell=4", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("hom", "threshold=1.5", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("hom", "depth=exact", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("frusta", "dump=x", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("cplp", "budget=0,leaf_tris=64", &err), SL_OK);
    assert_int_equal(sl_cull_method_check_options("plp", "leaf_tris=8", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("hzb", "dump=/tmp/a,record=/tmp/b,debug_frame=3", &err), SL_OK);
    /* the string getter: absent is NULL (reported as none), present points into the text, and the
     * key counts as known */
    sl_opts o;
    const char *v;
    assert_int_equal(sl_opts_parse(&o, "test", "dump=/tmp/x,other=1", &err), SL_OK);
    assert_int_equal(sl_opts_string(&o, "record", &v, &err), SL_OK);
    assert_null(v);
    assert_int_equal(sl_opts_string(&o, "dump", &v, &err), SL_OK);
    assert_string_equal(v, "/tmp/x");
    assert_string_equal(o.effective, "record=none,dump=/tmp/x");
    assert_int_equal(sl_opts_check_unused(&o, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "other"));
    assert_non_null(strstr(err.message, "dump"));
    /* guarantees */
    wall_scene w = wall_scene_make();
    sl_culler c;
    assert_int_equal(sl_culler_create("hom", w.s, "threshold=0.8", NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_AGGRESSIVE);
    assert_non_null(strstr(sl_culler_options(c), "threshold=0.8"));
    sl_culler_destroy(c);
    assert_int_equal(sl_culler_create("hom", w.s, NULL, NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_CONSERVATIVE);
    assert_non_null(strstr(sl_culler_options(c), "dump=none"));
    sl_culler_destroy(c);
    assert_int_equal(sl_culler_create("plp", w.s, NULL, NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_AGGRESSIVE);
    sl_culler_destroy(c);
    /* every registered occlusion method describes itself */
    for (size_t i = 0; i < SL_COUNTOF(g_all); i++) {
        uint32_t idx;
        sl_cull_method_desc d;
        assert_int_equal(sl_cull_method_find(g_all[i], &idx, &err), SL_OK);
        assert_int_equal(sl_cull_method_info(idx, &d, &err), SL_OK);
        assert_true(strlen(d.summary) > 20);
        assert_non_null(strstr(d.options_help, "(default"));
    }
    sl_scene_destroy(w.s);
}

/* Culling allocates nothing in steady state, whatever the method: once a walk of views has been
 * culled (the rasterizer's bin queues grow to the largest batch they see), culling the same views
 * again allocates nothing; a change of resolution reallocates; every byte comes back at destroy. */
static void test_no_allocation(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    sl_path p;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, 6, 3, 256, 192, &s, &p, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *out = malloc(n * sizeof *out);
    for (size_t i = 0; i < SL_COUNTOF(g_all); i++) {
        sl_test_counter cnt = {0};
        sl_allocator a = sl_test_counting_allocator(&cnt);
        sl_culler c;
        assert_int_equal(sl_culler_create(g_all[i], s, NULL, &a, &c, &err), SL_OK);
        sl_camera cam;
        for (uint32_t f = 0; f < sl_path_count(p); f++) {
            cam = sl_path_camera(p, f);
            cull(c, &cam, out, n);
        }
        size_t calls = cnt.calls;
        for (uint32_t f = 0; f < sl_path_count(p); f++) {
            cam = sl_path_camera(p, f);
            cull(c, &cam, out, n);
        }
        if (cnt.calls != calls)
            fail_msg("%s allocated %zu times in steady state", g_all[i], cnt.calls - calls);
        cam.width = 300;
        cam.height = 200;
        cull(c, &cam, out, n);
        sl_culler_destroy(c);
        assert_int_equal(cnt.live, 0);
    }
    free(out);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

/* An empty scene and a scene without any occluder: every method runs and keeps what vfc keeps
 * (hzb without its exact layer, which hides objects behind visible non-occluders too). */
static void test_degenerate_scenes(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_camera cam = wall_camera(64, 48);
    uint32_t out[16], k;
    for (size_t i = 0; i < SL_COUNTOF(g_all); i++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(g_all[i], s, NULL, NULL, &c, &err), SL_OK);
        assert_int_equal(sl_culler_cull(c, &cam, out, 0, &k, &err), SL_OK);
        assert_int_equal(k, 0);
        sl_culler_destroy(c);
    }
    for (int i = 0; i < 10; i++)
        add_box(s, (sl_vec3){5.0f + 3 * (float)i, -1, 0}, (sl_vec3){6.0f + 3 * (float)i, 1, 2}, SL_KIND_OTHER, 0, NULL);
    sl_culler v;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &v, &err), SL_OK);
    uint32_t ref[16], kr = cull(v, &cam, ref, 16);
    for (size_t i = 0; i < SL_COUNTOF(g_conservative); i++) {
        sl_culler c;
        assert_int_equal(
            sl_culler_create(g_conservative[i], s, strcmp(g_conservative[i], "hzb") ? NULL : "exact_px=0", NULL, &c, &err),
            SL_OK);
        k = cull(c, &cam, out, 16);
        assert_int_equal(k, kr);
        assert_memory_equal(out, ref, k * sizeof *out);
        sl_culler_destroy(c);
    }
    sl_culler_destroy(v);
    sl_scene_destroy(s);
}

/* lazygrid and busygrid make the same decisions; busygrid pays for them with more queries. */
static void test_lazy_equals_busy(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    uint32_t views = sanitized() ? 6 : 30;
    sl_path p;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, views, 5, 640, 480, &s, &p, &err), SL_OK);
    sl_culler lazy, busy;
    assert_int_equal(sl_culler_create("lazygrid", s, NULL, NULL, &lazy, &err), SL_OK);
    assert_int_equal(sl_culler_create("busygrid", s, NULL, NULL, &busy, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
    uint64_t ql = 0, qb = 0;
    for (uint32_t f = 0; f < views; f++) {
        sl_camera cam = sl_path_camera(p, f);
        uint32_t ka = cull(lazy, &cam, a, n), kb = cull(busy, &cam, b, n);
        assert_int_equal(ka, kb);
        assert_memory_equal(a, b, ka * sizeof *a);
        sl_cull_stats sa, sb;
        sl_culler_stats(lazy, &sa);
        sl_culler_stats(busy, &sb);
        ql += sa.queries;
        qb += sb.queries;
    }
    print_message("pixel queries per frame: lazy %.1f, busy %.1f\n", (double)ql / views, (double)qb / views);
    assert_true(qb > ql);
    free(a);
    free(b);
    sl_culler_destroy(lazy);
    sl_culler_destroy(busy);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

/* ---- debugging ---- */

static bool is_png(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return false;
    unsigned char sig[8] = {0};
    size_t n = fread(sig, 1, 8, f);
    fclose(f);
    static const unsigned char png[8] = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a};
    return n == 8 && memcmp(sig, png, 8) == 0;
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(p, 1, n, f), n);
    fclose(f);
}

/* A recording edited on purpose gets its checksum (the last 8 bytes) recomputed, so that the
 * field checks behind it are reached (tests/test_occ_record.c: damage without it is refused). */
static void reseal(uint8_t *bytes, size_t size)
{
    uint64_t sum = sl_hash64(bytes, size - 8, 0);
    memcpy(bytes + size - 8, &sum, 8);
}

/* Dump the depth buffer and pyramid of frame 1, record frame 1, replay it on every instruction
 * set: same answers and the same depth buffer; hostile recordings fail with a message. */
static void test_dump_record_replay(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    sl_path p;
    assert_int_equal(sl_test_city_views(SL_CITY_TINY, 3, 8, 320, 240, &s, &p, &err), SL_OK);
    char dir[] = "/tmp/sl_occ_testXXXXXX";
    assert_non_null(mkdtemp(dir));
    static const char *const methods[] = {"hzb", "hom", "lazygrid-z", "cplp"};
    static const char *const extra[] = {"", "", "", ",budget=0"};
    uint32_t n = sl_scene_object_count(s), *out = malloc(n * sizeof *out);
    for (size_t m = 0; m < SL_COUNTOF(methods); m++) {
        char opts[512], rec[300], depth[300], pyr[300];
        snprintf(rec, sizeof rec, "%s/%s.rec", dir, methods[m]);
        snprintf(depth, sizeof depth, "%s/%s-depth.png", dir, methods[m]);
        snprintf(pyr, sizeof pyr, "%s/%s-pyramid.png", dir, methods[m]);
        snprintf(opts, sizeof opts, "dump=%s/%s,record=%s,debug_frame=1%s", dir, methods[m], rec, extra[m]);
        sl_culler c;
        assert_int_equal(sl_culler_create(methods[m], s, opts, NULL, &c, &err), SL_OK);
        for (uint32_t f = 0; f < 3; f++) {
            sl_camera cam = sl_path_camera(p, f);
            cull(c, &cam, out, n);
            assert_int_equal(access(rec, F_OK) == 0, f >= 1);
        }
        sl_culler_destroy(c);
        assert_true(is_png(depth));
        bool has_pyramid = strcmp(methods[m], "cplp") != 0; /* hzb, hom: pyramids; lazygrid-z: its grid */
        assert_int_equal(is_png(pyr), has_pyramid);
        for (int isa = SL_RASTER_ISA_AUTO; isa <= SL_RASTER_ISA_AVX512; isa++) {
            if (!sl_raster_isa_available((sl_raster_isa)isa))
                continue;
            sl_occ_replay_report r;
            if (sl_occ_replay(rec, (sl_raster_isa)isa, NULL, &r, &err) != SL_OK)
                fail_msg("%s", err.message);
            assert_int_equal(r.width, 320);
            assert_int_equal(r.mismatches, 0);
            assert_true(r.queries > 0 || strcmp(methods[m], "hom") == 0); /* hom's default depth test is the DEB */
            assert_true(r.batches > 0);
            sl_occ_replay_report r2;
            assert_int_equal(sl_occ_replay(rec, SL_RASTER_ISA_SCALAR, NULL, &r2, &err), SL_OK);
            assert_true(r.depth_hash == r2.depth_hash);
        }
        unlink(depth);
        unlink(pyr);
        /* hostile copies */
        uint8_t *bytes;
        size_t size;
        assert_int_equal(sl_file_read_all(sl_default_allocator(), rec, &bytes, &size, &err), SL_OK);
        char bad[300];
        snprintf(bad, sizeof bad, "%s/bad.rec", dir);
        sl_occ_replay_report r;
        /* truncated in the middle of a record */
        write_bytes(bad, bytes, size - 7);
        assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_FORMAT);
        assert_non_null(strstr(err.message, "offset"));
        /* wrong magic */
        bytes[0] ^= 0xff;
        write_bytes(bad, bytes, size);
        assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_FORMAT);
        bytes[0] ^= 0xff;
        /* an unknown record type */
        uint32_t type = 7;
        memcpy(bytes + 36, &type, 4);
        reseal(bytes, size);
        write_bytes(bad, bytes, size);
        assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_FORMAT);
        assert_non_null(strstr(err.message, "type 7"));
        /* a record count beyond the data */
        type = 1;
        memcpy(bytes + 36, &type, 4);
        uint32_t many = 0xffffffu;
        memcpy(bytes + 32, &many, 4);
        reseal(bytes, size);
        write_bytes(bad, bytes, size);
        assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_FORMAT);
        /* a huge triangle count */
        memcpy(bytes + 40, &many, 4);
        reseal(bytes, size);
        write_bytes(bad, bytes, size);
        assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_FORMAT);
        /* a width of 0 */
        uint32_t zero = 0;
        memcpy(bytes + 12, &zero, 4);
        reseal(bytes, size);
        write_bytes(bad, bytes, size);
        assert_int_equal(sl_occ_replay(bad, SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_FORMAT);
        free(bytes);
        unlink(bad);
        unlink(rec);
    }
    /* a missing file */
    sl_occ_replay_report r;
    assert_int_equal(sl_occ_replay("/nonexistent/x.rec", SL_RASTER_ISA_AUTO, NULL, &r, &err), SL_ERROR_NOT_FOUND);
    /* an unwritable dump path fails the cull with a message, and leaves no file */
    sl_culler c;
    assert_int_equal(sl_culler_create("hzb", s, "dump=/nonexistent/dir/x", NULL, &c, &err), SL_OK);
    sl_camera cam = sl_path_camera(p, 0);
    uint32_t k;
    assert_int_not_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
    assert_non_null(strstr(err.message, "/nonexistent/dir/x-depth.png"));
    sl_culler_destroy(c);
    rmdir(dir);
    free(out);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

/* The frame view of an off-axis view (issue 13 §1): the near region reaches the farthest near
 * corner, the focal length is the smaller per-axis one (the larger one for what must cover pixels). */
static void test_occ_view_off_axis(void **state)
{
    (void)state;
    sl_camera cam = sl_camera_default();
    cam.width = 320, cam.height = 240;
    sl_mat4 vm = sl_camera_view(&cam), pm = sl_camera_proj(&cam);
    /* off-axis with non-square pixels: x scaled 3 and shifted left, y scaled 2 and shifted up */
    for (int c = 0; c < 4; c++) {
        pm.m[4 * c] = 3 * pm.m[4 * c] + 2 * pm.m[4 * c + 3];
        pm.m[4 * c + 1] = 2 * pm.m[4 * c + 1] - 2 * pm.m[4 * c + 3];
    }
    sl_view view;
    assert_int_equal(sl_view_from_matrices(vm.m, pm.m, SL_CLIP_DEPTH_GL, 320, 240, &view, NULL), SL_OK);
    sl_occ_view v;
    sl_occ_view_init(&v, &view);
    for (int i = 0; i < 4; i++) {
        const sl_vec3 *p = &v.fr.corners[i];
        double dx = p->x - v.eye.x, dy = p->y - v.eye.y, dz = p->z - v.eye.z;
        assert_true(v.near_reach >= sqrt(dx * dx + dy * dy + dz * dz));
    }
    assert_true(v.focal <= (float)view.focal_x && v.focal <= (float)view.focal_y);
    assert_true(v.focal_max >= (float)view.focal_x && v.focal_max >= (float)view.focal_y);
    assert_true(view.focal_x != view.focal_y);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_occ_view_off_axis),
        cmocka_unit_test(test_prisms_inside),     cmocka_unit_test(test_selection),
        cmocka_unit_test(test_wall_every_method), cmocka_unit_test(test_moving),
        cmocka_unit_test(test_moved_building),    cmocka_unit_test(test_options),
        cmocka_unit_test(test_no_allocation),     cmocka_unit_test(test_degenerate_scenes),
        cmocka_unit_test(test_lazy_equals_busy),  cmocka_unit_test(test_dump_record_replay),
        cmocka_unit_test(test_sampled_mesh_test), cmocka_unit_test(test_sampled_subpixel),
        cmocka_unit_test(test_rect_query_monotone),
        cmocka_unit_test(test_city_props_occlude),
        cmocka_unit_test(test_exact_layer_is_oracle), cmocka_unit_test(test_exact_layer_row),
        cmocka_unit_test(test_box_rows),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

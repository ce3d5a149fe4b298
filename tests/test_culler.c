/* The culler interface, its option parser, the registry, and the vfc baseline: vfc must keep every
 * object a brute-force box test keeps and every object the oracle sees, whatever its options. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/sl_core.h"
#include "cull/culler_internal.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/truth.h"
#include "support/counting_alloc.h"

/* ---- scene helpers ---- */

static uint32_t add_box_xf(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t flags, const sl_affine *xf)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    /* counter-clockwise seen from outside */
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    sl_error err;
    sl_mesh_desc md = {p, NULL, 8, idx, 12, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, xf, 0xffffffffu, SL_KIND_OTHER, flags, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

static sl_scene random_scene(const sl_allocator *a, uint64_t seed, uint32_t boxes)
{
    sl_scene s;
    assert_int_equal(sl_scene_create(a, &s, NULL), SL_OK);
    sl_rng r;
    sl_rng_seed(&r, seed, 9);
    for (uint32_t i = 0; i < boxes; i++) {
        sl_vec3 lo = {sl_rng_range(&r, -100, 100), sl_rng_range(&r, -100, 100), sl_rng_range(&r, -3, 3)};
        sl_vec3 hi = {lo.x + sl_rng_range(&r, 0.3f, 12), lo.y + sl_rng_range(&r, 0.3f, 12),
                      lo.z + sl_rng_range(&r, 0.3f, 20)};
        uint32_t flags = (sl_rng_below(&r, 3) ? SL_OBJECT_CLOSED_CONVEX : 0) | SL_OBJECT_DYNAMIC;
        add_box_xf(s, lo, hi, flags, NULL);
    }
    return s;
}

static sl_camera random_camera(sl_rng *r)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){sl_rng_range(r, -110, 110), sl_rng_range(r, -110, 110), sl_rng_range(r, -2, 25)};
    c.yaw = sl_rng_range(r, -4, 4);
    c.pitch = sl_rng_range(r, -1.4f, 1.4f);
    c.roll = sl_rng_below(r, 4) == 0 ? sl_rng_range(r, -1, 1) : 0;
    c.fov_y = sl_rng_range(r, 0.3f, 2.2f);
    c.near_plane = sl_rng_range(r, 0.05f, 1);
    c.far_plane = sl_rng_range(r, 30, 400);
    c.width = 160 + sl_rng_below(r, 200);
    c.height = 120 + sl_rng_below(r, 150);
    if (sl_rng_below(r, 4) == 0) {
        c.projection = SL_ORTHOGRAPHIC;
        c.ortho_height = sl_rng_range(r, 5, 150);
    }
    return c;
}

static bool contains(const uint32_t *ids, uint32_t n, uint32_t id)
{
    uint32_t lo = 0, hi = n;
    while (lo < hi) {
        uint32_t m = (lo + hi) / 2;
        if (ids[m] < id)
            lo = m + 1;
        else
            hi = m;
    }
    return lo < n && ids[lo] == id;
}

static bool eye_in_box(sl_vec3 e, sl_aabb b)
{
    return e.x >= b.min.x && e.x <= b.max.x && e.y >= b.min.y && e.y <= b.max.y && e.z >= b.min.z && e.z <= b.max.z;
}

/* ---- registry and options ---- */

static void test_registry(void **state)
{
    (void)state;
    uint32_t n = sl_cull_method_count();
    assert_true(n >= 1);
    sl_error err;
    for (uint32_t i = 0; i < n; i++) {
        sl_cull_method_desc d;
        assert_int_equal(sl_cull_method_info(i, &d, &err), SL_OK);
        assert_true(strlen(d.name) > 0 && strlen(d.summary) > 0 && d.options_help);
        uint32_t k;
        assert_int_equal(sl_cull_method_find(d.name, &k, &err), SL_OK);
        assert_int_equal(k, i);
        for (uint32_t j = 0; j < i; j++) {
            sl_cull_method_desc e;
            assert_int_equal(sl_cull_method_info(j, &e, &err), SL_OK);
            assert_string_not_equal(e.name, d.name);
        }
    }
    sl_cull_method_desc d;
    assert_int_equal(sl_cull_method_info(n, &d, &err), SL_ERROR_NOT_FOUND);
    assert_int_equal(sl_cull_method_find("nosuch", NULL, &err), SL_ERROR_NOT_FOUND);
    assert_non_null(strstr(err.message, "nosuch"));
    assert_non_null(strstr(err.message, "vfc"));
    uint32_t v;
    assert_int_equal(sl_cull_method_find("vfc", &v, &err), SL_OK);
    assert_int_equal(sl_cull_method_info(v, &d, &err), SL_OK);
    assert_int_equal(d.guarantee, SL_CONSERVATIVE);
    assert_string_equal(sl_cull_guarantee_name(SL_CONSERVATIVE), "conservative");
    assert_string_equal(sl_cull_guarantee_name(SL_AGGRESSIVE), "aggressive");
}

static void test_option_errors(void **state)
{
    (void)state;
    struct {
        const char *options;
        sl_status status;
        const char *says[3]; /* words the message must contain */
    } cases[] = {
        {"foo=1", SL_ERROR_INVALID_ARGUMENT, {"unknown option 'foo'", "plane_masks", "leaf_size"}},
        {"coherence=maybe", SL_ERROR_INVALID_ARGUMENT, {"coherence=maybe", "true/false", NULL}},
        {"leaf_size=abc", SL_ERROR_INVALID_ARGUMENT, {"leaf_size=abc", "whole number", NULL}},
        {"leaf_size=-1", SL_ERROR_INVALID_ARGUMENT, {"leaf_size=-1", NULL, NULL}},
        {"leaf_size=4x", SL_ERROR_INVALID_ARGUMENT, {"leaf_size=4x", NULL, NULL}},
        {"leaf_size=99", SL_ERROR_INVALID_ARGUMENT, {"leaf_size=99", "outside [1, 16]", NULL}},
        {"leaf_size=99999999999999", SL_ERROR_INVALID_ARGUMENT, {"leaf_size", NULL, NULL}},
        {"coherence=1,coherence=0", SL_ERROR_INVALID_ARGUMENT, {"'coherence' is given twice", NULL, NULL}},
        {"coherence=", SL_ERROR_INVALID_ARGUMENT, {"'coherence' has an empty value", NULL, NULL}},
        {"coherence", SL_ERROR_INVALID_ARGUMENT, {"'coherence' is not key=value", NULL, NULL}},
        {"coherence = 1", SL_ERROR_INVALID_ARGUMENT, {"is not key=value", NULL, NULL}},
        {"=1", SL_ERROR_INVALID_ARGUMENT, {"has no key", NULL, NULL}},
        {"co/herence=1", SL_ERROR_INVALID_ARGUMENT, {"'/'", NULL, NULL}},
        {"", SL_OK, {NULL, NULL, NULL}},
        {" ,, ", SL_OK, {NULL, NULL, NULL}},
        {"coherence=0  plane_masks=off,\tbackface=YES, leaf_size=8", SL_OK, {NULL, NULL, NULL}},
    };
    sl_scene s = random_scene(NULL, 1, 10);
    for (size_t i = 0; i < SL_COUNTOF(cases); i++) {
        sl_error err = {0};
        sl_culler c = NULL;
        sl_status st = sl_culler_create("vfc", s, cases[i].options, NULL, &c, &err);
        assert_int_equal(st, cases[i].status);
        assert_int_equal(sl_cull_method_check_options("vfc", cases[i].options, &err), cases[i].status);
        for (int k = 0; k < 3; k++)
            if (cases[i].says[k] && !strstr(err.message, cases[i].says[k]))
                fail_msg("options '%s': message '%s' lacks '%s'", cases[i].options, err.message, cases[i].says[k]);
        if (st == SL_OK) {
            assert_non_null(c);
            assert_string_equal(sl_culler_method(c), "vfc");
            assert_int_equal(sl_culler_guarantee(c), SL_CONSERVATIVE);
            sl_culler_destroy(c);
        } else {
            assert_null(c);
        }
    }
    /* the effective options name every key, defaults included */
    sl_culler c;
    sl_error err;
    assert_int_equal(sl_culler_create("vfc", s, "coherence=0  plane_masks=off", NULL, &c, &err), SL_OK);
    assert_string_equal(sl_culler_options(c), "plane_masks=false,coherence=false,backface=true,leaf_size=4");
    sl_culler_destroy(c);
    assert_int_equal(sl_culler_create("nosuch", s, NULL, NULL, &c, &err), SL_ERROR_NOT_FOUND);
    assert_int_equal(sl_cull_method_check_options("nosuch", "", &err), SL_ERROR_NOT_FOUND);
    /* too long, too many */
    char big[SL_OPTS_MAX_CHARS + 8];
    memset(big, 'a', sizeof big - 1);
    big[sizeof big - 1] = 0;
    assert_int_equal(sl_cull_method_check_options("vfc", big, &err), SL_ERROR_INVALID_ARGUMENT);
    char many[600] = "";
    for (int i = 0; i < 40; i++) {
        size_t n = strlen(many);
        snprintf(many + n, sizeof many - n, "k%d=1,", i);
    }
    assert_int_equal(sl_cull_method_check_options("vfc", many, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "more than"));
    sl_scene_destroy(s);
}

/* The getters vfc does not use, straight through the internal API. */
static void test_option_getters(void **state)
{
    (void)state;
    sl_opts o;
    sl_error err;
    assert_int_equal(sl_opts_parse(&o, "m", "scale=0.25 mode=fast n=7 f=1e3 bad=nan", &err), SL_OK);
    float f;
    assert_int_equal(sl_opts_float(&o, "scale", 1.0f, 0.0f, 1.0f, &f, &err), SL_OK);
    assert_true(f == 0.25f);
    assert_int_equal(sl_opts_float(&o, "absent", 0.5f, 0.0f, 1.0f, &f, &err), SL_OK);
    assert_true(f == 0.5f);
    assert_int_equal(sl_opts_float(&o, "f", 1.0f, 0.0f, 100.0f, &f, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "f=1e3 is outside"));
    assert_int_equal(sl_opts_float(&o, "bad", 1.0f, 0.0f, 100.0f, &f, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "finite number"));
    static const char *const modes[] = {"slow", "fast", "exact"};
    uint32_t m;
    assert_int_equal(sl_opts_enum(&o, "mode", modes, 3, 0, &m, &err), SL_OK);
    assert_int_equal(m, 1);
    uint32_t n;
    assert_int_equal(sl_opts_u32(&o, "n", 1, 0, 10, &n, &err), SL_OK);
    assert_int_equal(n, 7);
    assert_int_equal(sl_opts_check_unused(&o, &err), SL_OK);
    assert_string_equal(o.effective, "scale=0.25,absent=0.5,mode=fast,n=7");
    assert_int_equal(sl_opts_parse(&o, "m", "mode=quick", &err), SL_OK);
    assert_int_equal(sl_opts_enum(&o, "mode", modes, 3, 0, &m, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "slow, fast, exact"));
    /* a method that reads nothing says so */
    assert_int_equal(sl_opts_parse(&o, "none", "x=1", &err), SL_OK);
    assert_int_equal(sl_opts_check_unused(&o, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "none takes no options"));
}

static void test_sort_ids(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 4, 4);
    const uint32_t sizes[] = {0, 1, 2, 63, 64, 65, 1000, 20000};
    for (size_t k = 0; k < SL_COUNTOF(sizes); k++) {
        uint32_t n = sizes[k];
        uint32_t *a = malloc((n + 1) * sizeof *a), *scratch = malloc((n + 1) * sizeof *a);
        uint32_t shift = (uint32_t)(k % 3) * 11;
        for (uint32_t i = 0; i < n; i++)
            a[i] = (sl_rng_u32(&r) >> shift) ^ (k == 7 ? 0x80000000u : 0);
        sl_cull_sort_ids(a, n, scratch);
        for (uint32_t i = 1; i < n; i++)
            assert_true(a[i - 1] <= a[i]);
        free(a);
        free(scratch);
    }
}

/* ---- vfc ---- */

/* vfc against a brute-force test of every box, over random cameras; the option variants must
 * give the same lists. */
static void test_vfc_brute_force(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_scene s = random_scene(NULL, 42, 3000);
    uint32_t n = sl_scene_object_count(s);
    static const char *variants[] = {"backface=false", "backface=false,plane_masks=false,coherence=false",
                                     "backface=false,coherence=false,leaf_size=1", "backface=false,plane_masks=false,leaf_size=16"};
    sl_culler c[SL_COUNTOF(variants)], cb;
    sl_error err;
    for (size_t v = 0; v < SL_COUNTOF(variants); v++)
        assert_int_equal(sl_culler_create("vfc", s, variants[v], &a, &c[v], &err), SL_OK);
    assert_int_equal(sl_culler_create("vfc", s, NULL, &a, &cb, &err), SL_OK);
    uint32_t *out = malloc(n * sizeof *out), *ref = malloc(n * sizeof *ref);
    sl_rng r;
    sl_rng_seed(&r, 8, 8);
    size_t calls = cnt.calls;
    uint64_t total = 0, extra = 0;
    const uint32_t frames = getenv("SL_SANITIZED") ? 60 : 300;
    for (uint32_t f = 0; f < frames; f++) {
        sl_camera cam = random_camera(&r);
        sl_frustum fr = sl_camera_frustum(&cam);
        uint32_t rc = 0;
        for (uint32_t i = 0; i < n; i++) {
            sl_aabb b = sl_scene_object_bounds(s, i);
            if (sl_frustum_test_aabb(&fr, &b) != 0)
                ref[rc++] = i;
        }
        uint32_t first_count = 0;
        for (size_t v = 0; v < SL_COUNTOF(variants); v++) {
            /* several frames from nearby positions exercise the coherence hints */
            for (int rep = 0; rep < 2; rep++) {
                uint32_t k;
                assert_int_equal(sl_culler_cull(c[v], &cam, out, n, &k, &err), SL_OK);
                for (uint32_t i = 0; i < rc; i++)
                    if (!contains(out, k, ref[i]))
                        fail_msg("vfc %s dropped object %u (frame %u)", variants[v], ref[i], f);
                if (v == 0 && rep == 0) {
                    first_count = k;
                    total += rc;
                    extra += k - rc;
                } else {
                    assert_int_equal(k, first_count);
                }
                sl_cull_stats st;
                sl_culler_stats(c[v], &st);
                assert_int_equal(st.objects_visible, k);
                assert_int_equal(st.triangles_visible, 12ull * k);
                assert_true(st.nodes_visited > 0);
                assert_true(st.total_ms >= 0);
                assert_int_equal(st.phase_count, 2);
                assert_string_equal(st.phase_names[0], "traverse");
            }
        }
        /* with back-face rejection, only closed convex objects around the eye may go */
        uint32_t k;
        assert_int_equal(sl_culler_cull(cb, &cam, out, n, &k, &err), SL_OK);
        for (uint32_t i = 0; i < rc; i++)
            if (!contains(out, k, ref[i])) {
                sl_object_view ov = sl_scene_object(s, ref[i]);
                assert_true(ov.flags & SL_OBJECT_CLOSED_CONVEX);
                assert_true(eye_in_box(cam.position, ov.bounds));
            }
    }
    /* the slack admits almost nothing beyond the exact box test */
    assert_true(extra * 1000 <= total + 10);
    assert_int_equal(cnt.calls, calls); /* culling never allocates */
    for (size_t v = 0; v < SL_COUNTOF(variants); v++)
        sl_culler_destroy(c[v]);
    sl_culler_destroy(cb);
    assert_int_equal(cnt.live, 0);
    free(out);
    free(ref);
    sl_scene_destroy(s);
}

/* Every object the oracle sees is in vfc's set, from random viewpoints including some inside
 * closed boxes (where back-face rejection applies). */
static void test_vfc_against_oracle(void **state)
{
    (void)state;
    sl_scene s = random_scene(NULL, 77, 600);
    /* a mirrored closed box and a plain open box around known points */
    sl_affine mirror = sl_affine_identity();
    mirror.m[0] = -1;
    uint32_t mirrored = add_box_xf(s, (sl_vec3){-5, 150, 0}, (sl_vec3){5, 160, 8}, SL_OBJECT_CLOSED_CONVEX, &mirror);
    uint32_t open_box = add_box_xf(s, (sl_vec3){-5, 180, 0}, (sl_vec3){5, 190, 8}, 0, NULL);
    uint32_t n = sl_scene_object_count(s);
    sl_culler c;
    sl_error err;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &c, &err), SL_OK);
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = 200;
    oo.height = 150;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
    uint32_t *out = malloc(n * sizeof *out);
    sl_rng r;
    sl_rng_seed(&r, 21, 2);
    const uint32_t frames = getenv("SL_SANITIZED") ? 15 : 60;
    uint32_t inside_rejections = 0;
    for (uint32_t f = 0; f < frames + 2; f++) {
        sl_camera cam = random_camera(&r);
        if (f % 4 == 1) {
            /* inside some closed box */
            for (uint32_t t = 0; t < n; t++) {
                sl_object_view ov = sl_scene_object(s, (f * 31 + t) % n);
                if (ov.flags & SL_OBJECT_CLOSED_CONVEX) {
                    cam.position = (sl_vec3){0.5f * (ov.bounds.min.x + ov.bounds.max.x), 0.5f * (ov.bounds.min.y + ov.bounds.max.y),
                                             0.5f * (ov.bounds.min.z + ov.bounds.max.z)};
                    break;
                }
            }
        }
        if (f == frames)
            cam.position = (sl_vec3){-1, 155, 4}; /* inside the mirrored closed box */
        if (f == frames + 1)
            cam.position = (sl_vec3){-1, 185, 4}; /* inside the open box */
        cam.projection = f % 5 == 3 ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE;
        uint32_t k;
        assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        sl_cull_metrics m;
        assert_int_equal(sl_metrics_compare(s, &fr, out, k, &m, NULL, NULL, 0, &err), SL_OK);
        if (m.missed_count)
            fail_msg("frame %u: vfc missed %u objects (%llu pixels)", f, m.missed_count, (unsigned long long)m.missed_pixels);
        if (f == frames) {
            assert_false(contains(out, k, mirrored));
            inside_rejections++;
        }
        if (f == frames + 1) {
            assert_true(contains(out, k, open_box));
            assert_true(fr.visible_count >= 1 && contains(fr.visible, fr.visible_count, open_box));
        }
    }
    assert_int_equal(inside_rejections, 1);
    free(out);
    sl_oracle_destroy(o);
    sl_culler_destroy(c);
    sl_scene_destroy(s);
}

/* The tiny generated city from street level: vfc misses nothing the oracle sees. */
static void test_vfc_city(void **state)
{
    (void)state;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s);
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nn, ne;
    sl_scene_street_graph(s, &nodes, &nn, &edges, &ne);
    assert_true(ne > 0);
    sl_culler c;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &c, &err), SL_OK);
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = 320;
    oo.height = 240;
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o, &err), SL_OK);
    uint32_t *out = malloc(n * sizeof *out);
    sl_rng r;
    sl_rng_seed(&r, 99, 1);
    for (int v = 0; v < 12; v++) {
        const sl_street_edge *e = &edges[sl_rng_below(&r, ne)];
        float t = sl_rng_float(&r);
        float x = nodes[e->a].x + t * (nodes[e->b].x - nodes[e->a].x), y = nodes[e->a].y + t * (nodes[e->b].y - nodes[e->a].y);
        sl_camera cam = sl_camera_default();
        cam.position = (sl_vec3){x, y, sl_scene_ground_height(s, x, y) + 1.7f};
        cam.yaw = sl_rng_range(&r, -3.14f, 3.14f);
        cam.pitch = v % 3 == 2 ? -0.6f : 0.05f;
        uint32_t k;
        assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
        sl_oracle_frame f;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        assert_true(f.visible_count > 0);
        sl_cull_metrics m;
        assert_int_equal(sl_metrics_compare(s, &f, out, k, &m, NULL, NULL, 0, &err), SL_OK);
        assert_int_equal(m.missed_count, 0);
        assert_true(m.overestimation >= 1.0);
    }
    free(out);
    sl_oracle_destroy(o);
    sl_culler_destroy(c);
    sl_scene_destroy(s);
}

/* Objects move; after sl_culler_scene_changed vfc follows them. */
static void test_vfc_dynamic(void **state)
{
    (void)state;
    sl_scene s = random_scene(NULL, 5, 500);
    uint32_t n = sl_scene_object_count(s);
    sl_culler c;
    sl_error err;
    assert_int_equal(sl_culler_create("vfc", s, "backface=false", NULL, &c, &err), SL_OK);
    uint32_t *out = malloc(n * sizeof *out);
    sl_rng r;
    sl_rng_seed(&r, 6, 6);
    for (int step = 0; step < 20; step++) {
        /* move a tenth of the objects, some far away (forcing a rebuild eventually) */
        for (uint32_t i = 0; i < n / 10; i++) {
            sl_affine t = sl_affine_identity();
            float far = step > 10 ? 400.0f : 30.0f;
            t.m[3] = sl_rng_range(&r, -far, far);
            t.m[7] = sl_rng_range(&r, -far, far);
            assert_int_equal(sl_scene_set_object_transform(s, sl_rng_below(&r, n), &t, &err), SL_OK);
        }
        assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
        for (int f = 0; f < 5; f++) {
            sl_camera cam = random_camera(&r);
            sl_frustum fr = sl_camera_frustum(&cam);
            uint32_t k;
            assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
            for (uint32_t i = 0; i < n; i++) {
                sl_aabb b = sl_scene_object_bounds(s, i);
                if (sl_frustum_test_aabb(&fr, &b) != 0 && !contains(out, k, i))
                    fail_msg("step %d: vfc dropped moved object %u", step, i);
            }
        }
    }
    free(out);
    sl_culler_destroy(c);
    sl_scene_destroy(s);
}

/* Applicability: a method that would cull only to the frustum on a scene is said to be so. */
static void test_applicable(void **state)
{
    (void)state;
    sl_error err;
    char why[512];
    bool ok = false;
    /* the tiny city has everything: footprints, occluder objects */
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene city;
    assert_int_equal(sl_gen_city(&co, NULL, &city, &err), SL_OK);
    uint32_t n = sl_cull_method_count();
    for (uint32_t i = 0; i < n; i++) {
        sl_cull_method_desc d;
        assert_int_equal(sl_cull_method_info(i, &d, &err), SL_OK);
        if (!strcmp(d.name, "pvs"))
            continue;
        assert_int_equal(sl_cull_method_applicable(d.name, NULL, city, &ok, why, sizeof why, &err), SL_OK);
        assert_true(ok);
        assert_string_equal(why, "");
    }
    sl_scene_destroy(city);
    /* boxes without any occluder flag: no 2.5D and no occlusion method applies; vfc, the query
     * cullers and plp do */
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box_xf(s, (sl_vec3){0, 0, 0}, (sl_vec3){1, 1, 1}, 0, NULL);
    uint32_t see = add_box_xf(s, (sl_vec3){3, 0, 0}, (sl_vec3){4, 1, 1}, SL_OBJECT_OCCLUDER | SL_OBJECT_SEE_THROUGH, NULL);
    (void)see;
    static const char *none[] = {"cullmap", "horizon", "dhorizon", "hzb", "lazygrid", "lazygrid-z", "busygrid", "hom",
                                 "frusta"};
    for (size_t i = 0; i < sizeof none / sizeof none[0]; i++) {
        ok = true;
        assert_int_equal(sl_cull_method_applicable(none[i], NULL, s, &ok, why, sizeof why, &err), SL_OK);
        assert_false(ok);
        assert_non_null(strstr(why, i < 3 ? "no building footprints" : "no occluders"));
    }
    static const char *all[] = {"vfc", "plp", "gl-stopwait", "chc", "chc++"};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) {
        assert_int_equal(sl_cull_method_applicable(all[i], NULL, s, &ok, why, sizeof why, &err), SL_OK);
        assert_true(ok);
    }
    /* all_objects=true lets the objects' own meshes occlude */
    assert_int_equal(sl_cull_method_applicable("hzb", "all_objects=true", s, &ok, NULL, 0, &err), SL_OK);
    assert_true(ok);
    /* an occluder mesh is enough for the occlusion methods (a scene of its own: no flagged object) */
    {
        sl_scene o;
        assert_int_equal(sl_scene_create(NULL, &o, &err), SL_OK);
        uint32_t b = add_box_xf(o, (sl_vec3){0, 0, 0}, (sl_vec3){1, 1, 1}, 0, NULL);
        assert_int_equal(sl_cull_method_applicable("hom", NULL, o, &ok, why, sizeof why, &err), SL_OK);
        assert_false(ok);
        assert_int_equal(sl_scene_add_occluder(o, sl_scene_object(o, b).mesh, NULL, b, &err), SL_OK);
        assert_int_equal(sl_cull_method_applicable("hom", NULL, o, &ok, why, sizeof why, &err), SL_OK);
        assert_true(ok);
        assert_int_equal(sl_cull_method_applicable("dhorizon", NULL, o, &ok, why, sizeof why, &err), SL_OK);
        assert_false(ok);
        sl_scene_destroy(o);
    }
    /* one solid occluder object is enough for the occlusion methods, not for the 2.5D ones */
    add_box_xf(s, (sl_vec3){0, 3, 0}, (sl_vec3){1, 4, 1}, SL_OBJECT_OCCLUDER, NULL);
    assert_int_equal(sl_cull_method_applicable("lazygrid", NULL, s, &ok, why, sizeof why, &err), SL_OK);
    assert_true(ok);
    assert_int_equal(sl_cull_method_applicable("cullmap", NULL, s, &ok, why, 8, &err), SL_OK);
    assert_false(ok);
    assert_int_equal(strlen(why), 7); /* cut to the buffer */
    /* errors: the method's and the options' */
    assert_int_equal(sl_cull_method_applicable("nope", NULL, s, &ok, why, sizeof why, &err), SL_ERROR_NOT_FOUND);
    assert_int_equal(sl_cull_method_applicable("hzb", "bogus=1", s, &ok, why, sizeof why, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_applicable("pvs", NULL, s, &ok, why, sizeof why, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_applicable("vfc", NULL, NULL, &ok, why, sizeof why, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(s);
}

static void test_culler_errors(void **state)
{
    (void)state;
    sl_scene s = random_scene(NULL, 2, 50);
    uint32_t n = sl_scene_object_count(s);
    sl_culler c;
    sl_error err;
    assert_int_equal(sl_culler_create("vfc", NULL, NULL, NULL, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &c, &err), SL_OK);
    sl_cull_stats st;
    sl_culler_stats(c, &st);
    assert_int_equal(st.objects_visible, 0);
    uint32_t out[64], k = 99;
    sl_camera cam = sl_camera_default();
    assert_int_equal(sl_culler_cull(c, &cam, out, n - 1, &k, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "capacity"));
    assert_int_equal(k, 0);
    cam.near_plane = -1;
    assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "near"));
    cam = sl_camera_default();
    assert_int_equal(sl_culler_cull(c, &cam, out, n, &k, &err), SL_OK);
    assert_int_equal(sl_culler_cull(c, NULL, out, n, &k, &err), SL_ERROR_INVALID_ARGUMENT);
    /* the scene grew: the culler refuses instead of reading past its arrays */
    add_box_xf(s, (sl_vec3){0, 0, 0}, (sl_vec3){1, 1, 1}, 0, NULL);
    assert_int_equal(sl_culler_cull(c, &cam, out, n + 1, &k, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "create a new culler"));
    assert_int_equal(sl_culler_scene_changed(c, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_culler_destroy(c);
    sl_culler_destroy(NULL);
    /* an empty scene culls to nothing */
    sl_scene e;
    assert_int_equal(sl_scene_create(NULL, &e, NULL), SL_OK);
    assert_int_equal(sl_culler_create("vfc", e, NULL, NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_cull(c, &cam, out, 0, &k, &err), SL_OK);
    assert_int_equal(k, 0);
    assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
    sl_culler_destroy(c);
    sl_scene_destroy(e);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_registry),
        cmocka_unit_test(test_option_errors),
        cmocka_unit_test(test_option_getters),
        cmocka_unit_test(test_sort_ids),
        cmocka_unit_test(test_vfc_brute_force),
        cmocka_unit_test(test_vfc_against_oracle),
        cmocka_unit_test(test_vfc_city),
        cmocka_unit_test(test_vfc_dynamic),
        cmocka_unit_test(test_culler_errors),
        cmocka_unit_test(test_applicable),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

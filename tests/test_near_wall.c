/* Near-wall views against the point oracle (issue 12 §1): every conservative method must keep every
 * object the oracle sees when the eye is 0.001-0.2 m in front of a surface, where the near plane
 * (0.1 m, 0.139 m at the frustum's corners) cuts the surface and the oracle sees through the hole.
 * Views: bench/near_wall_views.h (a random point of a random triangle, stepped out along its
 * normal, looking towards the surface). Scenes: 10 OpenArena maps (openarena-081-maps) and the
 * small city. Every conservative method of the registry but pvs (it reads a baked file and has
 * no occluders), frusta and hzb with all_objects=true besides their defaults.
 * CTest: 60 views per map and 80 of the city at 320x240 (680 in all); under SL_SANITIZED 3 maps of
 * 8 views and the city's 10. bench/near_wall.c sweeps every map. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/truth.h"

#include "../bench/near_wall_views.h"

#define OA_PK3 "/usr/share/games/openarena/baseoa/pak1-maps.pk3"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static const struct {
    const char *name, *options;
} g_methods[] = {
    {"vfc", NULL},
    {"cullmap", NULL},
    {"horizon", NULL},
    {"dhorizon", NULL},
    {"hzb", NULL},
    {"hzb", "all_objects=true"},
    {"lazygrid", NULL},
    {"lazygrid-z", NULL},
    {"busygrid", NULL},
    {"hom", NULL},
    {"frusta", NULL},
    {"frusta", "all_objects=true"},
    {"cplp", NULL},
};
#define NM SL_COUNTOF(g_methods)

typedef struct tally {
    uint64_t frames, missed_frames, missed_objects;
} tally;

/* Cull `views` near-wall views of s with every method; returns the frames any method missed in. */
static uint64_t run_scene(sl_scene s, const char *label, uint32_t views, uint64_t seed, tally *t)
{
    sl_error err;
    sl_culler c[NM];
    bool ok[NM];
    for (size_t i = 0; i < NM; i++) {
        ok[i] = sl_culler_create(g_methods[i].name, s, g_methods[i].options, NULL, &c[i], &err) == SL_OK;
        if (!ok[i])
            print_message("%s: %s not run: %s\n", label, g_methods[i].name, err.message);
        else
            assert_int_equal(sl_culler_guarantee(c[i]), SL_CONSERVATIVE);
    }
    nw_table tb;
    assert_true(nw_table_build(s, &tb));
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out), missed[4], mpx[4];
    sl_camera in = sl_camera_default();
    in.width = 320;
    in.height = 240;
    nw_rng r = {seed};
    uint64_t bad = 0;
    for (uint32_t f = 0; f < views; f++) {
        sl_camera cam;
        double d = nw_view(s, &tb, &r, &in, 0.001, 0.2, &cam);
        assert_true(d >= 0);
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
        bool any = false;
        for (size_t i = 0; i < NM; i++) {
            if (!ok[i])
                continue;
            uint32_t k;
            if (sl_culler_cull(c[i], &cam, out, n, &k, &err) != SL_OK)
                fail_msg("%s %s frame %u: %s", label, g_methods[i].name, f, err.message);
            sl_cull_metrics mt;
            assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
            t[i].frames++;
            if (mt.missed_count) {
                any = true;
                t[i].missed_frames++;
                t[i].missed_objects += mt.missed_count;
                print_message("%s: %s%s%s view %u missed %u objects (first %u, %u pixels); eye %.3f m from the "
                              "surface at (%.4f, %.4f, %.4f) yaw %.5f pitch %.5f roll %.5f\n",
                              label, g_methods[i].name, g_methods[i].options ? " " : "",
                              g_methods[i].options ? g_methods[i].options : "", f, mt.missed_count, missed[0], mpx[0],
                              d, (double)cam.position.x, (double)cam.position.y, (double)cam.position.z,
                              (double)cam.yaw, (double)cam.pitch, (double)cam.roll);
            }
        }
        bad += any;
    }
    free(out);
    sl_oracle_destroy(o);
    nw_table_free(&tb);
    for (size_t i = 0; i < NM; i++)
        if (ok[i])
            sl_culler_destroy(c[i]);
    return bad;
}

static void report(const tally *t)
{
    for (size_t i = 0; i < NM; i++)
        print_message("near-wall %-10s %-18s %llu views, %llu with misses, %llu objects missed\n", g_methods[i].name,
                      g_methods[i].options ? g_methods[i].options : "", (unsigned long long)t[i].frames,
                      (unsigned long long)t[i].missed_frames, (unsigned long long)t[i].missed_objects);
}

typedef struct name_list {
    char names[128][96];
    int count;
} name_list;

static void collect(void *user, const char *entry)
{
    name_list *l = user;
    if (l->count < 128)
        snprintf(l->names[l->count++], sizeof l->names[0], "%s", entry);
}

/* 10 OpenArena maps spread over the pk3's list, then the small city. */
static void test_near_wall_views(void **state)
{
    (void)state;
    tally t[NM];
    memset(t, 0, sizeof t);
    uint64_t bad = 0, views = 0;
    if (access(OA_PK3, R_OK) != 0) {
        print_message("maps skipped: %s is not installed (Debian package openarena-081-maps)\n", OA_PK3);
    } else {
        name_list *list = calloc(1, sizeof *list);
        sl_error err;
        assert_int_equal(sl_pk3_list_maps(OA_PK3, collect, list, &err), SL_OK);
        assert_true(list->count >= 10);
        int maps = sanitized() ? 3 : 10;
        uint32_t per_map = sanitized() ? 8 : 60;
        for (int m = 0; m < maps; m++) {
            int i = m * list->count / maps;
            sl_scene s;
            if (sl_import_q3bsp(OA_PK3, list->names[i], NULL, NULL, &s, &err) != SL_OK)
                fail_msg("%s", err.message);
            bad += run_scene(s, list->names[i], per_map, 1000 + (uint64_t)i, t);
            views += per_map;
            sl_scene_destroy(s);
        }
        free(list);
    }
    sl_city_options co = sl_city_defaults(SL_CITY_SMALL);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    uint32_t nc = sanitized() ? 10 : 80;
    bad += run_scene(s, "small city", nc, 77, t);
    views += nc;
    sl_scene_destroy(s);
    report(t);
    print_message("near-wall: %llu views, %llu with a conservative miss\n", (unsigned long long)views,
                  (unsigned long long)bad);
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_near_wall_views),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}

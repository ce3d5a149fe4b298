#include "support/city_views.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

sl_scene sl_test_tiny_city(void)
{
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s = NULL;
    sl_error err;
    if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
        fail_msg("%s", err.message);
    return s;
}

sl_status sl_test_city_views(sl_city_preset preset, uint32_t count, uint64_t seed, uint32_t w, uint32_t h, sl_scene *s,
                             sl_path *views, sl_error *err)
{
    *s = NULL;
    *views = NULL;
    sl_city_options co = sl_city_defaults(preset);
    sl_status st = sl_gen_city(&co, NULL, s, err);
    if (st != SL_OK)
        return st;
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = w;
    po.intrinsics.height = h;
    if ((st = sl_path_random_views(*s, SL_VIEWS_STREET, count, seed, &po, NULL, views, err)) != SL_OK) {
        sl_scene_destroy(*s);
        *s = NULL;
    }
    return st;
}

sl_viewcells sl_test_row_cells(uint32_t n, const sl_allocator *a)
{
    sl_viewcell *c = calloc(n ? n : 1, sizeof *c);
    if (!c)
        return NULL;
    for (uint32_t i = 0; i < n; i++) {
        c[i].shape = SL_CELL_BOX;
        c[i].cluster = -1;
        c[i].z_min = 1;
        c[i].z_max = 2;
        c[i].bounds = (sl_aabb){{(float)i, 0, 1}, {(float)i + 1, 1, 2}};
    }
    sl_viewcells vc = NULL;
    sl_error err;
    if (sl_viewcells_create(c, n, a, &vc, &err) != SL_OK)
        vc = NULL;
    free(c);
    return vc;
}

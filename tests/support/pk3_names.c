#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sightline/import.h"
#include "support/pk3_names.h"

void sl_test_collect_name(void *user, const char *entry)
{
    sl_test_name_list *l = user;
    if (l->count < (int)(sizeof l->names / sizeof l->names[0]))
        snprintf(l->names[l->count++], sizeof l->names[0], "%s", entry);
}

bool sl_test_open_map(int index, uint32_t width, uint32_t height, uint32_t count, uint32_t seed,
                      sl_test_map *out)
{
    memset(out, 0, sizeof *out);
    if (access(SL_TEST_OA_PK3, R_OK) != 0) {
        print_message("skipped: %s is not installed (Debian package openarena-081-maps)\n", SL_TEST_OA_PK3);
        return false;
    }
    sl_test_name_list *list = calloc(1, sizeof *list);
    assert_non_null(list);
    sl_error err;
    if (sl_pk3_list_maps(SL_TEST_OA_PK3, sl_test_collect_name, list, &err) != SL_OK)
        fail_msg("%s", err.message);
    assert_true(list->count >= 1);
    int k = index < list->count ? index : list->count - 1;
    snprintf(out->name, sizeof out->name, "%s", list->names[k]);
    free(list);
    if (sl_import_q3bsp(SL_TEST_OA_PK3, out->name, NULL, NULL, &out->scene, &err) != SL_OK)
        fail_msg("%s: %s", out->name, err.message);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = width;
    po.intrinsics.height = height;
    if (sl_path_random_views(out->scene, SL_VIEWS_STREET, count, seed, &po, NULL, &out->views, &err) != SL_OK)
        fail_msg("%s: %s", out->name, err.message);
    return true;
}

void sl_test_map_free(sl_test_map *m)
{
    sl_path_destroy(m->views);
    sl_scene_destroy(m->scene);
    memset(m, 0, sizeof *m);
}

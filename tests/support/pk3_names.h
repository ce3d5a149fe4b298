/* The map entries of a pk3, collected by sl_pk3_list_maps (its callback), for the tests that
 * import Quake III maps (test_backend, test_near_wall, test_occlusion_oracle, test_q3bsp), and the
 * set-up those tests share: one map of the OpenArena package imported, random street views on it. */
#ifndef SL_TEST_PK3_NAMES_H
#define SL_TEST_PK3_NAMES_H

#include <stdbool.h>
#include <stdint.h>

#include "sightline/path.h"
#include "sightline/scene.h"

/* The Debian package openarena-081-maps's maps. */
#define SL_TEST_OA_PK3 "/usr/share/games/openarena/baseoa/pak1-maps.pk3"

/* Up to 128 names of up to 95 characters (longer ones are cut, later ones dropped). */
typedef struct sl_test_name_list {
    char names[128][96];
    int count;
} sl_test_name_list;

/* sl_pk3_list_maps's callback: user is a sl_test_name_list. */
void sl_test_collect_name(void *user, const char *entry);

/* One OpenArena map and views on it. */
typedef struct sl_test_map {
    sl_scene scene;
    sl_path views; /* `count` random street views (SL_VIEWS_STREET) of the asked size */
    char name[96]; /* the map's entry name, for messages */
} sl_test_map;

/* Imports the map at `index` of the package's list (the last one when the list is shorter) and
 * draws `count` random street views of width x height from `seed`. Returns false, after printing
 * why, when the package is not installed (the caller then calls skip()); any other failure fails
 * the running test with the importer's message. Free with sl_test_map_free. */
bool sl_test_open_map(int index, uint32_t width, uint32_t height, uint32_t count, uint32_t seed,
                      sl_test_map *out);
void sl_test_map_free(sl_test_map *m);
#endif

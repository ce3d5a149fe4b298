/* The map entries of a pk3, collected by sl_pk3_list_maps (its callback), for the tests that
 * import Quake III maps (test_backend, test_near_wall, test_occlusion_oracle, test_q3bsp). */
#ifndef SL_TEST_PK3_NAMES_H
#define SL_TEST_PK3_NAMES_H

/* Up to 128 names of up to 95 characters (longer ones are cut, later ones dropped). */
typedef struct sl_test_name_list {
    char names[128][96];
    int count;
} sl_test_name_list;

/* sl_pk3_list_maps's callback: user is a sl_test_name_list. */
void sl_test_collect_name(void *user, const char *entry);
#endif

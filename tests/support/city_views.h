/* Set-ups many culling and PVS tests share: a generated city with seeded random street views, and
 * a row of unit box view cells. */
#ifndef SL_TEST_CITY_VIEWS_H
#define SL_TEST_CITY_VIEWS_H
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/pvs.h"

/* The city of a preset (its default options) and `count` random street views of it (seed, a
 * walk's eye height, w x h pixels: sl_path_random_views with sl_path_options_default(WALK)).
 * SL_OK, or the failing call's status and message with nothing left to free. */
sl_status sl_test_city_views(sl_city_preset preset, uint32_t count, uint64_t seed, uint32_t w, uint32_t h, sl_scene *s,
                             sl_path *views, sl_error *err);

/* The tiny city (sl_city_defaults(SL_CITY_TINY)), for the tests that cull it (test_backend,
 * test_shared_accel); a failure to make it fails the running cmocka test with the message. */
sl_scene sl_test_tiny_city(void);

/* n box view cells in a row along x: cell i is [i, i + 1] x [0, 1] x [1, 2] (eye heights 1..2, no
 * cluster). NULL when they cannot be made. */
sl_viewcells sl_test_row_cells(uint32_t n, const sl_allocator *a);
#endif

/* One BOX view cell for tests that bake by hand. */
#ifndef SL_TEST_BOX_CELL_H
#define SL_TEST_BOX_CELL_H
#include "sightline/region.h"

/* A set of one BOX cell over x in [x0, x1], y in [y0, y1], its eyes 1 to 2 m up (fails the test
 * when the cell is refused). */
sl_viewcells sl_test_box_cell(float x0, float y0, float x1, float y1);
/* The same with eyes from z0 to z1. */
sl_viewcells sl_test_box_cell_z(float x0, float y0, float x1, float y1, float z0, float z1);
#endif

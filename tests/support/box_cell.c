#include "box_cell.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include <string.h>

sl_viewcells sl_test_box_cell(float x0, float y0, float x1, float y1)
{
    return sl_test_box_cell_z(x0, y0, x1, y1, 1, 2);
}

sl_viewcells sl_test_box_cell_z(float x0, float y0, float x1, float y1, float z0, float z1)
{
    sl_viewcell c;
    memset(&c, 0, sizeof c);
    c.shape = SL_CELL_BOX;
    c.cluster = -1;
    c.z_min = z0;
    c.z_max = z1;
    c.bounds = (sl_aabb){{x0, y0, z0}, {x1, y1, z1}};
    sl_viewcells vc = NULL;
    sl_error err;
    if (sl_viewcells_create(&c, 1, NULL, &vc, &err) != SL_OK)
        fail_msg("box cell: %s", err.message);
    return vc;
}

/* The finite view every method and the oracle see (issue 13 §1): an infinite far plane replaced by
 * one just beyond the scene's box (sl_view_bound_far: the same visible set). */
#include "scene/scene_internal.h"

#include <math.h>

sl_status sl_scene_finite_view(sl_scene s, const sl_view *v, sl_view *tmp, const sl_view **out, sl_error *err)
{
    *out = v;
    if (!isinf(v->far_plane))
        return SL_OK;
    sl_aabb world = sl_scene_bounds(s);
    sl_status st = sl_view_bound_far(v, &world, tmp, err);
    if (st == SL_OK)
        *out = tmp;
    return st;
}

/* Footprints above the ground (docs/pvs.md, "Footprints above the ground"): the distinct bases of
 * the scene's footprints, and per view cell the lowest eye and the highest base at or below it.
 * The methods that take their eyes at the cell's top (adjustable, sample) treat an occluder as a
 * wall from the ground up; that holds for the sight lines that pass it above its base, which
 * every line between points at or above the base does. */
#include "pvs_internal.h"

#include "scene/scene_internal.h"

#include <math.h>
#include <stdlib.h>

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

bool sl_base_levels_of_scene(sl_base_levels *b, sl_scene scene, const sl_allocator *a)
{
    const uint32_t nf = sl_scene_footprint_count(scene);
    b->n = 0;
    b->cap = (size_t)nf + 1;
    if (!(b->v = sl_alloc(a, b->cap * sizeof(double))))
        return false;
    for (uint32_t f = 0; f < nf; f++)
        b->v[f] = sl_scene_footprint(scene, f).base_z;
    qsort(b->v, nf, sizeof(double), cmp_double);
    for (uint32_t k = 0; k < nf; k++)
        if (b->n == 0 || b->v[k] != b->v[b->n - 1])
            b->v[b->n++] = b->v[k];
    return true;
}

void sl_base_levels_free(sl_base_levels *b, const sl_allocator *a)
{
    sl_free(a, b->v, b->v ? b->cap * sizeof(double) : 0);
    memset(b, 0, sizeof *b);
}

double sl_base_levels_top(const sl_base_levels *b) { return b->n ? b->v[b->n - 1] : -INFINITY; }

double sl_cell_floor(const sl_base_levels *b, const sl_viewcell *vc, double *tb)
{
    const double zfloor = fmin((double)vc->z_min, (double)vc->bounds.min.z);
    uint32_t lo = 0, hi = b->n; /* the first base above zfloor */
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (b->v[mid] <= zfloor)
            lo = mid + 1;
        else
            hi = mid;
    }
    *tb = lo ? b->v[lo - 1] : -INFINITY;
    return zfloor;
}

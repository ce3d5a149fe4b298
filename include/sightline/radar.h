/* Sightline radar echo generation: which triangles of a terrain a ground radar illuminates, by a
 * front-to-back occlusion-horizon sweep, and the echo image (the visible terrain seen from above).
 *
 * G. Koldaş, PhD thesis, METU 2008, §3.3 (Koldaş, Çevikbaş, İşler, TEHOSS 2006): the terrain's
 * triangles are bucketed in a regular grid (a triangle in every cell it touches), each cell keeps
 * its highest point and its triangles sorted from the highest down; cells are swept front to back
 * from the transmitter over the sector; a cell below the horizon is skipped whole; in a visible
 * cell triangles are tested highest first until the rest must lie below the horizon; a visible
 * triangle's edges raise the horizon (terrain is solid below its surface).
 *
 * The terrain is a height field of nx * ny samples, two triangles per quad: quad (i, j) has
 * triangle 2q = (i,j) (i+1,j) (i+1,j+1) and 2q+1 = (i,j) (i+1,j+1) (i,j+1), q = j*(nx-1) + i.
 * Conservative: every triangle with a point whose segment to the transmitter never passes below
 * the surface is reported (sl_radar_line_of_sight is the exact check the tests compare with);
 * triangles whose visible part is tiny count as visible, as in the thesis.
 */
#ifndef SIGHTLINE_RADAR_H
#define SIGHTLINE_RADAR_H

#include "core.h"
#include "geom.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_radar_t *sl_radar;

/* A generated terrain: fractal relief (several octaves of smooth noise with sharpened ridges,
 * valleys and plateaus), deterministic for a seed. */
typedef struct sl_radar_terrain_options {
    uint32_t nx, ny;        /* samples, 2..20000 each (default 1651 x 1401: 4.62M triangles) */
    float cell;             /* sample spacing in metres, > 0 (default 40: about 66 x 56 km) */
    float relief;           /* highest minus lowest point, metres, >= 0 (default 900) */
    uint64_t seed;          /* default 1 */
} sl_radar_terrain_options;

/* The defaults above. */
SL_API sl_radar_terrain_options sl_radar_terrain_defaults(void);
/* Generate the heights (nx*ny floats, row-major, allocated with alloc: free with
 * sl_radar_terrain_free) and describe the field in *out (origin at the south-west corner, 0 0). */
SL_API sl_status sl_radar_terrain_generate(const sl_radar_terrain_options *opt, const sl_allocator *alloc,
                                           sl_terrain_desc *out, sl_error *err);
/* Release heights made by sl_radar_terrain_generate. */
SL_API void sl_radar_terrain_free(sl_terrain_desc *t, const sl_allocator *alloc);

typedef struct sl_radar_options {
    uint32_t grid;          /* grid cells along the terrain's longer side, 2..4096 (default 100) */
    uint32_t bins;          /* azimuth bins of the horizon, 1024..2^20 (default 16384) */
    const sl_allocator *alloc; /* NULL: the default */
} sl_radar_options;

/* The defaults above. */
SL_API sl_radar_options sl_radar_default_options(void);

/* Bucket a terrain (the heights are copied). Fails on a bad field (sizes, spacing, non-finite
 * heights) or bad options, naming the field. */
SL_API sl_status sl_radar_create(const sl_terrain_desc *terrain, const sl_radar_options *opt, sl_radar *out,
                                 sl_error *err);
/* Release. NULL is ignored. */
SL_API void sl_radar_destroy(sl_radar radar);
/* Number of triangles, 2 (nx-1)(ny-1). */
SL_API uint64_t sl_radar_triangle_count(sl_radar radar);
/* Grid cells along x and y. */
SL_API void sl_radar_grid_size(sl_radar radar, uint32_t *gx, uint32_t *gy);
/* Terrain height at (x, y) on the triangles (clamped to the field). */
SL_API float sl_radar_height(sl_radar radar, float x, float y);

/* One sweep: the transmitter, the sector [azimuth, azimuth + width] (radians counter-clockwise
 * from +x, width in (0, 2 pi]) and the range (plan distance; INFINITY for the whole terrain). */
typedef struct sl_radar_sweep {
    sl_vec3 transmitter;
    float azimuth, width;
    float range;
} sl_radar_sweep;

typedef struct sl_radar_stats {
    uint64_t cells_tested, cells_culled;
    uint64_t triangles_tested, triangles_visible;
    uint64_t bins_written;
    double ms;              /* wall time of the sweep */
} sl_radar_stats;

/* Run a sweep: afterwards sl_radar_visible tells which triangles the sector illuminates (a triangle
 * partly in the sector or the range counts). The transmitter must be above the terrain. stats may
 * be NULL. Allocation-free. */
SL_API sl_status sl_radar_run(sl_radar radar, const sl_radar_sweep *sweep, sl_radar_stats *stats, sl_error *err);
/* Was triangle t found visible by the last sweep? */
SL_API bool sl_radar_visible(sl_radar radar, uint64_t triangle);

/* Exact line of sight over the triangulated terrain: false when the segment from a to b passes
 * below the surface by more than tolerance metres anywhere except within tolerance of b. */
SL_API bool sl_radar_line_of_sight(sl_radar radar, sl_vec3 a, sl_vec3 b, double tolerance);

/* Write the echo image of the last sweep as an RGB PNG, north up, covering the terrain: a pixel
 * shows the triangle under its centre, green by the cosine of the incidence angle when the sweep
 * found it visible, a dim shaded relief when hidden, black outside the sector and the range; the
 * transmitter in red. Written atomically. */
SL_API sl_status sl_radar_echo_png(sl_radar radar, const sl_radar_sweep *sweep, const char *path, uint32_t width,
                                   uint32_t height, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif

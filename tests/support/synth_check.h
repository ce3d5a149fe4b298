/* Checks of synthesised occluders (tests/test_synth*.c): boxes against their object's own mesh by
 * an independent point-in-mesh test, and culling runs against the oracle. */
#ifndef SL_TEST_SYNTH_CHECK_H
#define SL_TEST_SYNTH_CHECK_H
#include "sightline/camera.h"
#include "sightline/scene.h"
#include "sightline/truth.h"

typedef struct sl_synth_check {
    uint32_t boxes;            /* boxes of the object's occluder meshes (8 vertices each) */
    uint64_t points;           /* corners and grid points tested */
    uint64_t outside_points;   /* of those, outside the object's mesh (ray parity): must be 0 */
    uint64_t vertices_inside;  /* mesh vertices strictly inside a box (of the closed parts: an open part may lie inside): must be 0 */
    double box_volume;         /* sum of the boxes' volumes */
    double mesh_volume;        /* volume the object's mesh encloses */
} sl_synth_check;

/* Check every box of every occluder mesh of `object` (sl_synth_occluders' layout: 8 corners per
 * box, corner i at (i&1 ? hi.x : lo.x, i&2 ..., i&4 ...)): its corners and an n x n x n grid of
 * points across it (faces included) must lie inside the object's mesh, with the object's
 * transform, by ray parity along seeded random directions (a ray passing near an edge is cast
 * again in another direction), and no vertex of the mesh may lie strictly inside a box. */
sl_synth_check sl_synth_check_object(sl_scene s, uint32_t object, uint32_t n);

/* Totals of one method over a list of cameras, judged by the oracle. */
typedef struct sl_synth_views {
    uint64_t kept, visible, missed, frames;
    double overestimation;     /* kept / visible (ratio of sums) */
} sl_synth_views;
/* Run `method` (options may be NULL) on the cameras; fails the cmocka test on an error, and names
 * the first frame that missed an object in a message. */
sl_synth_views sl_synth_run_views(sl_scene s, const char *method, const char *options, const sl_camera *cams,
                                  uint32_t n);
/* The same, judged by an oracle of `scale` times the cameras' resolution with the given sample
 * pattern (4 samples for MSAA and jitter): what a method claiming SL_CONSERVATIVE (any
 * resolution) must keep. scale 0: the oracle of the cameras' own size and pixel centres. */
sl_synth_views sl_synth_run_views_judged(sl_scene s, const char *method, const char *options, const sl_camera *cams,
                                         uint32_t n, uint32_t scale, sl_oracle_samples samples);
#endif

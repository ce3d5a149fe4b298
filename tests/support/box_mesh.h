/* A closed axis-aligned box as a 12-triangle mesh, for tests that build scenes by hand. */
#ifndef SL_TEST_BOX_MESH_H
#define SL_TEST_BOX_MESH_H
#include "sightline/scene.h"

/* Triangles of the box whose corner i is (i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y,
 * i & 4 ? hi.z : lo.z), wound outward. */
extern const uint32_t sl_test_box_indices[36];
/* The eight corners of [lo, hi] in that order (x, y, z each). */
void sl_test_box_vertices(sl_vec3 lo, sl_vec3 hi, float p[24]);
/* Add the box as a mesh and one object of that kind and flags (colour white); its id, or SL_NONE
 * when the scene refuses it. */
uint32_t sl_test_add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind, uint32_t flags);
#endif

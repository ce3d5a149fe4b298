/* The open-space rule shared by the point oracle (oracle.c) and the region oracle
 * (region_oracle.c): on a map, a sight line that enters solid space (a BSP leaf without a cluster)
 * from open space is blocked. docs/oracle.md, "One set of rules", rule 4. */
#ifndef SL_TRUTH_OPEN_SPACE_H
#define SL_TRUTH_OPEN_SPACE_H

#include "sightline/scene.h"

/* Whether the segment p0-p1 never enters a leaf without a cluster after being in one with a
 * cluster, walking from p0 (the side rule is sl_scene_bsp_find_leaf's: front when d >= 0). With
 * solid_start false the segment must stay in open leaves from its start; with solid_start true a
 * solid stretch at its start is passed over (what a near plane cut open: the segment starts on
 * the near plane, which may lie inside a wall the eye stands next to). */
bool sl_bsp_sight_line_open(const sl_bsp_view *bsp, const double p0[3], const double p1[3], bool solid_start);

#endif

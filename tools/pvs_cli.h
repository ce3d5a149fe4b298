/* PVS helpers of the commands: the MPI bake driver of `sightline pvs build` (tools/pvs_mpi.c), the
 * choice of the view cells along a camera path (tools/cells_along.c), and the bake along a path with
 * which `sightline demo` and `sightline bench` give the pvs culler a file (tools/pvs_along.c). The MPI driver lives in the command, not in libsightline, so that the library never needs
 * MPI: a program that links Sightline bakes on its own cores with sl_pvs_build; only the command,
 * run under mpiexec, spans processes. */
#ifndef SL_TOOLS_PVS_CLI_H
#define SL_TOOLS_PVS_CLI_H

#include "sightline/path.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"

/* sl_pvs_build across the processes of an MPI job (mpiexec -n N): every process calls it with the
 * same scene, cells and options; process 0 hands out cells dynamically, bakes with its own threads
 * as well, gathers the sets, keeps the journal and writes the file (the same bytes as sl_pvs_build
 * whatever N). A chunk a process holds for `lease` seconds (0: for ever) without a result is
 * handed to an idle process as well, and the first result wins (a stopped or hung process no
 * longer stalls the bake). Initialises MPI if needed and finalises it if it did.
 * SL_ERROR_UNSUPPORTED when the command was built without MPI. *rank (may be NULL) receives the
 * process's rank. */
sl_status cli_pvs_build_mpi(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                            double lease, sl_pvs_build_stats *stats, int *rank, sl_error *err);
/* The default of `pvs build --lease`: seconds a process may hold a chunk without a result before
 * an idle process is handed the same cells (tools/pvs_mpi.c). */
#define CLI_PVS_LEASE_DEFAULT 300.0

/* The cells whose bounds come within `radius` metres of a camera position of `path`, as a new cell
 * set (ids renumbered, order kept). A PVS baked for them covers the path: an eye outside them
 * finds no cell, and the pvs culler falls back to frustum culling there, as for any eye in no
 * cell, so a cell left out is never taken for an empty one. Fails when no cell is that near.
 * far_cameras (may be NULL): how many of the path's cameras no cell comes that near. */
/* The distance between two boxes (0 when they touch or overlap), in doubles. */
double cli_box_gap(const sl_aabb *a, const sl_aabb *b);

sl_status cli_viewcells_along(sl_viewcells cells, sl_path path, float radius, sl_viewcells *out, uint32_t *far_cameras,
                              sl_error *err);

/* How the demo and the bench bake for the pvs culler: the street cells within this many metres of
 * a camera (as `pvs build --along PATH --radius R`), with this conservative method. */
#define CLI_PVS_ALONG_METHOD "adjustable"
#define CLI_PVS_ALONG_RADIUS 2.0f

/* What cli_pvs_bake_along baked, or why it baked nothing. */
typedef struct cli_pvs_along {
    char options[4500];         /* "file=FILE" for the pvs culler once baked, else empty */
    char why[512];              /* set when nothing was baked although the call succeeded */
    uint32_t cells;             /* cells in the file */
    double seconds;             /* wall time of the cells and the bake */
    double culled;              /* mean fraction of the objects culled per cell */
} cli_pvs_along;

/* Bake into `file` the PVS of the street cells within CLI_PVS_ALONG_RADIUS of the cameras of the
 * frames first..first+count-1 of `path` (the frames that will be run: count UINT32_MAX or past the
 * end means to the last frame; first must be a frame of the path) with CLI_PVS_ALONG_METHOD (a
 * journal left by an interrupted run is discarded, under the bake lock: a bake of `file` that
 * runs is reported, never disturbed), so that the pvs culler runs along those
 * frames; elsewhere it finds no cell and culls by the frustum. SL_OK with out->why set and nothing
 * written when the pvs culler's file= option cannot name `file` (a comma, '=' or white space), when
 * the scene has no street polygons, or when no cell is near those frames. A failed bake is an
 * error. */
sl_status cli_pvs_bake_along(sl_scene scene, sl_path path, uint32_t first, uint32_t count, const char *file,
                             const sl_progress *prog, cli_pvs_along *out, sl_error *err);

#endif

/* PVS helpers of the commands: the MPI bake driver of `sightline pvs build` (tools/pvs_mpi.c) and
 * the choice of the view cells along a camera path (tools/cmd_pvs.c), which `sightline demo` uses
 * too. The MPI driver lives in the command, not in libsightline, so that the library never needs
 * MPI: a program that links Sightline bakes on its own cores with sl_pvs_build; only the command,
 * run under mpiexec, spans processes. */
#ifndef SL_TOOLS_PVS_CLI_H
#define SL_TOOLS_PVS_CLI_H

#include "sightline/path.h"
#include "sightline/pvs.h"

/* sl_pvs_build across the processes of an MPI job (mpiexec -n N): every process calls it with the
 * same scene, cells and options; process 0 hands out cells dynamically, bakes with its own threads
 * as well, gathers the sets, keeps the journal and writes the file (the same bytes as sl_pvs_build
 * whatever N). Initialises MPI if needed and finalises it if it did. SL_ERROR_UNSUPPORTED when the
 * command was built without MPI. *rank (may be NULL) receives the process's rank. */
sl_status cli_pvs_build_mpi(sl_scene scene, sl_viewcells cells, const char *output, const sl_pvs_build_options *opt,
                            sl_pvs_build_stats *stats, int *rank, sl_error *err);

/* The cells whose bounds come within `radius` metres of a camera position of `path`, as a new cell
 * set (ids renumbered, order kept). A PVS baked for them covers the path: an eye outside them
 * finds no cell, and the pvs culler falls back to frustum culling there, as for any eye in no
 * cell, so a cell left out is never taken for an empty one. Fails when no cell is that near. */
sl_status cli_viewcells_along(sl_viewcells cells, sl_path path, float radius, sl_viewcells *out, sl_error *err);

#endif

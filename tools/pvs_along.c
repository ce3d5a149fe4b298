/* The PVS that `sightline demo` and `sightline bench` bake for the pvs culler along their camera
 * paths (tools/pvs_cli.h): one function, so that both commands bake the same cells with the same
 * method as `sightline pvs build --cells streets --along PATH --radius R`. */
#include "pvs_cli.h"

#include "tool.h"
#include "sightline/bake.h"
#include "sightline/region.h"

#include <string.h>

/* The frames first..first+count-1 of `path` (count clamped to its end) as a new path with the same
 * intrinsics: the cameras whose cells are baked. Poses of a valid path append without error. */
static sl_status path_slice(sl_path path, uint32_t first, uint32_t count, sl_path *out, sl_error *err)
{
    *out = NULL;
    uint32_t n = sl_path_count(path);
    if (first >= n)
        return tool_fail(err, SL_ERROR_INVALID_ARGUMENT, "frame %u is beyond the path's %u frames", first, n);
    if (count > n - first)
        count = n - first;
    sl_camera intrinsics = sl_path_intrinsics(path);
    const sl_pose *poses = sl_path_poses(path);
    sl_status st = sl_path_create(&intrinsics, NULL, out, err);
    for (uint32_t i = 0; st == SL_OK && i < count; i++)
        st = sl_path_append(*out, &poses[first + i], err);
    if (st != SL_OK) {
        sl_path_destroy(*out);
        *out = NULL;
    }
    return st;
}

sl_status cli_pvs_bake_along(sl_scene scene, sl_path path, uint32_t first, uint32_t count, const char *file,
                             const sl_progress *prog, cli_pvs_along *out, sl_error *err)
{
    memset(out, 0, sizeof out[0]);
    /* the culler's options are "key=value,...": its file name cannot hold a comma or a space */
    if (strpbrk(file, ", \t\n=")) {
        snprintf(out->why, sizeof out->why,
                 "the output folder's path holds a comma, '=' or a space, which the pvs culler's file= option "
                 "cannot take");
        return SL_OK;
    }
    if (strlen(file) + 5 >= sizeof out->options) {
        snprintf(out->why, sizeof out->why, "the output folder's path is too long for the pvs culler's file= option");
        return SL_OK;
    }
    if (sl_scene_street_polygon_count(scene) == 0) {
        snprintf(out->why, sizeof out->why,
                 "the scene has no streets to lay view cells along the views (bake a PVS with `sightline pvs "
                 "build` and give it with file=PATH)");
        return SL_OK;
    }
    double t0 = tool_now();
    sl_viewcells all = NULL, near = NULL;
    sl_path run = NULL;
    sl_status st = path_slice(path, first, count, &run, err);
    if (st == SL_OK)
        st = sl_viewcells_from_streets(scene, NULL, &all, err);
    if (st == SL_OK) {
        sl_error e;
        st = cli_viewcells_along(all, run, CLI_PVS_ALONG_RADIUS, &near, NULL, &e);
        if (st == SL_ERROR_INVALID_ARGUMENT) {
            /* no cell near the cameras (views above the streets): nothing to bake, not a failure */
            snprintf(out->why, sizeof out->why,
                     "no street view cell lies within %g m of the %u cameras (views above the streets?)",
                     (double)CLI_PVS_ALONG_RADIUS, sl_path_count(run));
            st = SL_OK;
        } else if (st != SL_OK && err) {
            *err = e;
        }
    }
    sl_viewcells_destroy(all);
    sl_path_destroy(run);
    if (st == SL_OK && near) {
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        /* a journal left by an interrupted run belongs to this output: start afresh. The bake
         * removes it under its lock, so the journal of a bake of this file that runs is never
         * removed: that bake is reported ("another bake of FILE is running (pid N)") */
        bo.fresh = true;
        bo.method = CLI_PVS_ALONG_METHOD;
        bo.progress = *prog;
        sl_pvs_build_stats stats;
        st = sl_pvs_build(scene, near, file, &bo, &stats, err);
        if (st == SL_OK) {
            out->cells = stats.cells;
            out->culled = stats.mean_culled;
            snprintf(out->options, sizeof out->options, "file=%s", file);
        }
    }
    sl_viewcells_destroy(near);
    out->seconds = tool_now() - t0;
    return st;
}

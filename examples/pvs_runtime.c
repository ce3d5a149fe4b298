/* A PVS at run time (examples/README.md): what a game does with a .slpvs baked offline.
 *
 * Load the scene and its PVS (baked beforehand: `sightline pvs build SCENE -o FILE.slpvs`), check
 * they belong together, then for each frame find the eye's view cell and draw its set, with the
 * frustum on top. The same through the `pvs` culler (one call per frame, the same result) and
 * from two threads at once through cursors. Links libsightline_runtime only.
 *
 *   pvs_runtime SCENE.slscene FILE.slpvs PATH.txt    (exit status 0 when every check held) */
#include <sightline/cull.h>
#include <sightline/path.h>
#include <sightline/pvs.h>
#include <sightline/region.h>
#include <sightline/slscene.h>

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int fail(const char *what, const sl_error *err)
{
    fprintf(stderr, "pvs_runtime: %s: %s\n", what, err ? err->message : "check failed");
    return 1;
}

typedef struct worker {
    sl_pvs pvs;
    sl_scene scene;
    sl_path path;
    uint32_t first, step, objects;
    uint64_t checksum; /* sum of (cell + 1) * set size over its frames */
    int status;
} worker;

/* One thread's frames (every `step`-th from `first`) through a cursor of its own. */
static void *run_worker(void *arg)
{
    worker *w = arg;
    sl_error err;
    sl_pvs_cursor cur;
    uint32_t *set = malloc(w->objects * sizeof *set);
    if (!set || sl_pvs_cursor_create(w->pvs, &cur, &err) != SL_OK) {
        free(set);
        w->status = 1;
        return NULL;
    }
    sl_viewcells cells = sl_pvs_cells(w->pvs);
    for (uint32_t f = w->first; f < sl_path_count(w->path); f += w->step) {
        sl_camera cam = sl_path_camera(w->path, f);
        uint32_t cell = sl_viewcells_locate(cells, w->scene, cam.position), n = 0;
        if (cell == SL_NONE)
            continue;
        if (sl_pvs_cursor_cell_set(cur, cell, set, w->objects, &n, &err) != SL_OK) {
            w->status = 1;
            break;
        }
        w->checksum += (uint64_t)(cell + 1) * n;
    }
    sl_pvs_cursor_destroy(cur);
    free(set);
    return NULL;
}

int main(int argc, char **argv)
{
    if (argc != 4) {
        fprintf(stderr, "usage: pvs_runtime SCENE.slscene FILE.slpvs PATH.txt\n");
        return 2;
    }
    sl_error err;
    sl_scene scene;
    sl_pvs pvs;
    sl_path path;
    if (sl_scene_load(argv[1], NULL, NULL, &scene, &err) != SL_OK)
        return fail("scene", &err);
    if (sl_pvs_load(argv[2], NULL, &pvs, &err) != SL_OK)
        return fail("pvs", &err);
    if (sl_pvs_check_scene(pvs, scene, &err) != SL_OK) /* the file was baked for this scene */
        return fail("pvs and scene", &err);
    if (sl_path_load(argv[3], NULL, &path, &err) != SL_OK)
        return fail("path", &err);
    uint32_t objects = sl_scene_object_count(scene), frames = sl_path_count(path);
    printf("%s: %u cells for %u objects; %u frames\n", argv[2], sl_viewcells_count(sl_pvs_cells(pvs)), objects, frames);

    /* by hand: cell lookup and set; and through the pvs culler, which adds the frustum */
    char opts[4200];
    snprintf(opts, sizeof opts, "file=%s", argv[2]);
    sl_culler culler, vfc;
    if (sl_culler_create("pvs", scene, opts, NULL, &culler, &err) != SL_OK)
        return fail("pvs culler", &err);
    if (sl_culler_create("vfc", scene, NULL, NULL, &vfc, &err) != SL_OK)
        return fail("vfc culler", &err);
    uint32_t *set = malloc(objects * sizeof *set), *ids = malloc(objects * sizeof *ids);
    uint32_t *frustum = malloc(objects * sizeof *frustum), nf = 0;
    if (!set || !ids || !frustum)
        return fail("memory", NULL);
    uint32_t in_cells = 0;
    uint64_t checksum = 0, drawn = 0;
    for (uint32_t f = 0; f < frames; f++) {
        sl_camera cam = sl_path_camera(path, f);
        uint32_t cell = sl_viewcells_locate(sl_pvs_cells(pvs), scene, cam.position), n = 0, count;
        if (cell != SL_NONE) {
            if (sl_pvs_cell_set(pvs, cell, set, objects, &n, &err) != SL_OK)
                return fail("cell set", &err);
            in_cells++;
            checksum += (uint64_t)(cell + 1) * n;
        }
        if (sl_culler_cull(culler, &cam, ids, objects, &count, &err) != SL_OK)
            return fail("cull", &err);
        /* the culler draws the sets of every cell its near-plane region meets (the eye's cell and
         * any cell a near-wall view reaches into), cut by the frustum: it holds the eye cell's
         * objects that are in the frustum */
        if (cell != SL_NONE) {
            if (sl_culler_cull(vfc, &cam, frustum, objects, &nf, &err) != SL_OK)
                return fail("vfc", &err);
            for (uint32_t k = 0, j = 0, i = 0; k < n; k++) {
                while (i < nf && frustum[i] < set[k])
                    i++;
                if (i == nf || frustum[i] != set[k])
                    continue; /* outside the frustum */
                while (j < count && ids[j] < set[k])
                    j++;
                if (j == count || ids[j] != set[k])
                    return fail("the culler left out an object of the eye's cell in the frustum", NULL);
            }
        }
        drawn += count;
    }
    printf("%u of %u eyes in a cell; %.1f objects drawn per frame of %u\n", in_cells, frames,
           (double)drawn / (frames ? frames : 1), objects);
    if (!in_cells)
        return fail("no eye of the path lies in a cell (bake along this path)", NULL);

    /* two threads, one cursor each, the frames split between them: the same sets */
    worker w[2];
    pthread_t th[2];
    for (int t = 0; t < 2; t++) {
        w[t] = (worker){.pvs = pvs, .scene = scene, .path = path, .first = (uint32_t)t, .step = 2, .objects = objects};
        if (pthread_create(&th[t], NULL, run_worker, &w[t]) != 0)
            return fail("thread", NULL);
    }
    for (int t = 0; t < 2; t++)
        pthread_join(th[t], NULL);
    if (w[0].status || w[1].status || w[0].checksum + w[1].checksum != checksum)
        return fail("the threads' sets differ from the single thread's", NULL);
    printf("two threads with a cursor each: the same sets\n");
    sl_culler_destroy(culler);
    sl_culler_destroy(vfc);
    free(frustum);
    sl_path_destroy(path);
    sl_pvs_destroy(pvs);
    sl_scene_destroy(scene);
    free(set);
    free(ids);
    return 0;
}

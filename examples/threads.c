/* Culling from several threads (examples/README.md): one scene, one shared acceleration handle
 * (the object BVH built once), one culler per thread, each thread culling its own views. The
 * results are the same as one thread's. Links libsightline_runtime only.
 *
 *   threads [THREADS] [VIEWS]    (defaults 4 and 64; exit status 0 when every check held) */
#include <sightline/accel.h>
#include <sightline/cull.h>
#include <sightline/gen.h>
#include <sightline/path.h>

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct job {
    sl_scene scene;
    sl_scene_accel accel;
    sl_path views;
    uint32_t first, step;
    uint64_t *hash; /* per view: a hash of its visible set */
    int status;
} job;

static uint64_t hash_ids(const uint32_t *ids, uint32_t n)
{
    uint64_t h = 1469598103934665603ull;
    for (uint32_t k = 0; k < n; k++)
        h = (h ^ ids[k]) * 1099511628211ull;
    return h ^ n;
}

static void *cull_views(void *arg)
{
    job *j = arg;
    sl_error err;
    sl_culler_params params = {.accel = j->accel}; /* the shared BVH: not built again per culler */
    sl_culler c;
    uint32_t n = sl_scene_object_count(j->scene), *ids = malloc(n * sizeof *ids), count;
    if (!ids || sl_culler_create_with("hzb", j->scene, "threads=1", &params, NULL, &c, &err) != SL_OK) {
        fprintf(stderr, "threads: %s\n", ids ? err.message : "out of memory");
        free(ids);
        j->status = 1;
        return NULL;
    }
    for (uint32_t v = j->first; v < sl_path_count(j->views); v += j->step) {
        sl_camera cam = sl_path_camera(j->views, v);
        if (sl_culler_cull(c, &cam, ids, n, &count, &err) != SL_OK) {
            fprintf(stderr, "threads: view %u: %s\n", v, err.message);
            j->status = 1;
            break;
        }
        j->hash[v] = hash_ids(ids, count);
    }
    sl_culler_destroy(c);
    free(ids);
    return NULL;
}

int main(int argc, char **argv)
{
    int nt = argc > 1 ? atoi(argv[1]) : 4, nv = argc > 2 ? atoi(argv[2]) : 64;
    if (nt < 1 || nt > 64 || nv < 1 || nv > 100000) {
        fprintf(stderr, "usage: threads [THREADS 1..64] [VIEWS]\n");
        return 2;
    }
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene scene;
    sl_scene_accel accel;
    sl_path views;
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK || sl_scene_accel_create(scene, NULL, &accel, &err) != SL_OK ||
        sl_path_random_views(scene, SL_VIEWS_STREET, (uint32_t)nv, 7, &po, NULL, &views, &err) != SL_OK) {
        fprintf(stderr, "threads: %s\n", err.message);
        return 1;
    }
    uint64_t *one = calloc((size_t)nv, sizeof *one), *many = calloc((size_t)nv, sizeof *many);
    job *jobs = calloc((size_t)nt, sizeof *jobs);
    pthread_t *th = calloc((size_t)nt, sizeof *th);
    if (!one || !many || !jobs || !th)
        return 1;
    /* one thread, all views */
    job single = {.scene = scene, .accel = accel, .views = views, .first = 0, .step = 1, .hash = one};
    cull_views(&single);
    /* nt threads at once, the views dealt out */
    for (int t = 0; t < nt; t++) {
        jobs[t] = (job){.scene = scene, .accel = accel, .views = views, .first = (uint32_t)t, .step = (uint32_t)nt,
                        .hash = many};
        if (pthread_create(&th[t], NULL, cull_views, &jobs[t]) != 0)
            return 1;
    }
    int bad = single.status;
    for (int t = 0; t < nt; t++) {
        pthread_join(th[t], NULL);
        bad |= jobs[t].status;
    }
    for (int v = 0; v < nv && !bad; v++)
        if (one[v] != many[v]) {
            fprintf(stderr, "threads: view %d: %d threads gave another set than one\n", v, nt);
            bad = 1;
        }
    if (!bad)
        printf("%d views culled by %d threads sharing one scene and one BVH: the sets of one thread\n", nv, nt);
    free(one);
    free(many);
    free(jobs);
    free(th);
    sl_path_destroy(views);
    sl_scene_accel_destroy(accel);
    sl_scene_destroy(scene);
    return bad;
}

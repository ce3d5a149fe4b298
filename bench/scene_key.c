/* Benchmark: the cost of sl_pvs_scene_key (format 2 hashes every array a PVS method reads) on a
 * procedural city, the median of several runs after a warm-up, with the scene's size and the
 * hash rate, so that loading a PVS or starting a bake stays cheap.
 *
 *   bench_scene_key [--city PRESET] [--runs N]      (default vienna, 9 runs)
 */
#include "scene/scene_internal.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "bench_common.h"

int main(int argc, char **argv)
{
    const char *city = "vienna";
    int runs = 9;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--city") && i + 1 < argc)
            city = argv[++i];
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc)
            runs = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_scene_key [--city PRESET] [--runs N]\n");
            return strcmp(argv[i], "--help") ? 2 : 0;
        }
    }
    if (runs < 1 || runs > 1000)
        runs = 9;
    sl_error err;
    sl_city_preset preset;
    if (sl_city_preset_from_name(city, &preset, &err) != SL_OK) {
        fprintf(stderr, "bench_scene_key: %s\n", err.message);
        return 2;
    }
    sl_city_options co = sl_city_defaults(preset);
    sl_scene s;
    double t0 = sl_now();
    if (sl_gen_city(&co, NULL, &s, &err) != SL_OK) {
        fprintf(stderr, "bench_scene_key: %s\n", err.message);
        return 1;
    }
    double gen = sl_now() - t0;
    const struct sl_scene_t *in = s;
    double bytes = (double)in->meshes.count * sizeof(sl_mesh_rec) + (double)in->positions.count * sizeof(float) +
                   (double)in->indices.count * sizeof(uint32_t) +
                   (double)in->objects.count * (sizeof(sl_object_rec) + sizeof(sl_affine) + sizeof(sl_aabb)) +
                   (double)in->footprint_xy.count * sizeof(float) + (double)in->terrain_heights.count * sizeof(float) +
                   (double)in->street_xy.count * sizeof(float);
    uint64_t key = sl_pvs_scene_key(s); /* warm-up */
    double *t = malloc((size_t)runs * sizeof *t);
    for (int r = 0; r < runs; r++) {
        double a = sl_now();
        uint64_t k = sl_pvs_scene_key(s);
        t[r] = sl_now() - a;
        if (k != key) {
            fprintf(stderr, "bench_scene_key: the key changed between runs\n");
            return 1;
        }
    }
    qsort(t, (size_t)runs, sizeof *t, bench_cmp_double);
    double med = t[runs / 2];
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    printf("city %s: %u objects, %llu stored triangles, %llu vertices, %.1f MiB hashed (generated in %.2f s)\n", city,
           st.object_count, (unsigned long long)st.triangle_count, (unsigned long long)st.vertex_count,
           bytes / (1024.0 * 1024.0), gen);
    printf("sl_pvs_scene_key (format %u): median %.2f ms over %d runs (min %.2f, max %.2f), %.1f GB/s, key %016llx\n",
           SL_PVS_SCENE_KEY_VERSION, med * 1e3, runs, t[0] * 1e3, t[runs - 1] * 1e3, bytes / med / 1e9,
           (unsigned long long)key);
    free(t);
    sl_scene_destroy(s);
    return 0;
}

/* Culling at one resolution, judged by the oracle at another (issue 13 §6).
 *
 *   bench_resolution [--preset tiny|small|vienna] [--views N | --walk N] [--seed S]
 *                    [--width W --height H] [--oracle-scale K | --oracle-size WxH]
 *                    [--samples center|msaa4|jitterN] [--jitter-seed S] [--rounds R]
 *                    [--methods LIST] [--threads T] [--by-kind]
 *
 * Every method culls each view at the culling resolution (default 320x240); the oracle renders the
 * same view and projection at K times that resolution (default 2; --oracle-size gives any size,
 * its projection is still the camera's, so a different aspect means non-square oracle pixels),
 * optionally with several samples per oracle pixel (--samples, docs/oracle.md "Supersampling").
 * Views: N random street views (sl_path_random_views, default 100, seed 1), or --walk N: the bench's
 * street walk (sl_path_generate, 5 fps, seed 1, as bench_occlusion and `sightline bench --walk`).
 * For each method: the objects it dropped that the oracle sees (summed over views, and the views
 * with a miss), the sum of objects drawn over the sum of the exact visible set (tightness, ratio
 * of sums), an FNV-1a hash of every view's output set (two builds culled the same sets when their
 * hashes match), and the time: R rounds (default 3), each culling the whole walk with every method
 * in turn, the methods' order alternating from round to round; a round's figure is the median
 * over the views of the cull's wall time, and the table gives the median over the rounds.
 * --by-kind adds a row under each method: the objects it drew that the oracle does not see, by
 * object kind, per object of the exact visible set (where the looseness is).
 * --methods takes comma-separated specs name[:key=value[:key=value...]] ("hzb,hzb:res=culling").
 * Exit status 1 when a method whose guarantee promises it (conservative; conservative at the
 * culling resolution when the oracle samples at the culling resolution's pixel centres) missed. */
#include "bench_common.h"
#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_METHODS 24

static const char *const g_default_methods[] = {"vfc",      "cullmap",   "horizon", "dhorizon",   "hzb",
                                                "lazygrid", "lazygrid-z", "busygrid", "hom",       "frusta",
                                                "cplp"};

typedef struct method {
    char spec[256], name[64], opts[320];
    sl_culler c;
    sl_cull_guarantee g;
    uint64_t missed, missed_views, drawn, hash;
    uint64_t extra[SL_KIND_COUNT]; /* --by-kind: drawn, not visible, per object kind */
    double round_ms[64];
} method;

static void die(const char *what, const sl_error *err) { bench_die("bench_resolution", what, err); }

/* The options of a method spec, as this build takes them. */
static void edit_opts(char *ob)
{
#ifndef SL_ORACLE_MAX_SAMPLES
    /* built against a tree from before res= (to compare sets and times): its only mode is today's
     * res=culling */
    char *rc = strstr(ob, "res=culling");
    if (rc) {
        size_t l = strlen("res=culling") + (rc[strlen("res=culling")] == ',');
        memmove(rc, rc + l, strlen(rc + l) + 1);
        size_t e = strlen(ob);
        if (e && ob[e - 1] == ',')
            ob[e - 1] = 0;
    }
#else
    (void)ob;
#endif
}

static uint64_t fnv(uint64_t h, const uint32_t *ids, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++)
        for (int b = 0; b < 4; b++) {
            h ^= (ids[i] >> (8 * b)) & 0xffu;
            h *= 1099511628211ull;
        }
    h ^= 0xffu; /* end of a view's set */
    return h * 1099511628211ull;
}

int main(int argc, char **argv)
{
    const char *preset = "tiny", *list = NULL, *samples = "center";
    uint32_t views = 100, walk = 0, width = 320, height = 240, scale = 2, ow = 0, oh = 0, rounds = 3, threads = 0;
    uint64_t seed = 1, jseed = 1;
    bool by_kind = false;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool more = i + 1 < argc;
        if (!strcmp(a, "--preset") && more)
            preset = argv[++i];
        else if (!strcmp(a, "--views") && more)
            views = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--walk") && more)
            walk = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--seed") && more)
            seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(a, "--width") && more)
            width = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--height") && more)
            height = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--oracle-scale") && more)
            scale = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--oracle-size") && more) {
            if (sscanf(argv[++i], "%ux%u", &ow, &oh) != 2)
                die("--oracle-size takes WxH", NULL);
        } else if (!strcmp(a, "--samples") && more)
            samples = argv[++i];
        else if (!strcmp(a, "--jitter-seed") && more)
            jseed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(a, "--rounds") && more)
            rounds = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--methods") && more)
            list = argv[++i];
        else if (!strcmp(a, "--threads") && more)
            threads = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--by-kind"))
            by_kind = true;
        else {
            fprintf(stderr, "usage: bench_resolution [--preset tiny|small|vienna] [--views N | --walk N] [--seed S]\n"
                            "       [--width W --height H] [--oracle-scale K | --oracle-size WxH]\n"
                            "       [--samples center|msaa4|jitterN] [--jitter-seed S] [--rounds R]\n"
                            "       [--methods LIST] [--threads T] [--by-kind]\n");
            return 2;
        }
    }
    if (!width || !height || !scale || rounds < 1 || rounds > 64 || (!views && !walk))
        die("bad numeric option", NULL);
    if (!ow) {
        ow = width * scale;
        oh = height * scale;
    }
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = ow;
    oo.height = oh;
#ifdef SL_ORACLE_MAX_SAMPLES
    if (!strcmp(samples, "msaa4"))
        oo.samples = SL_ORACLE_SAMPLES_MSAA4;
    else if (!strncmp(samples, "jitter", 6)) {
        oo.samples = SL_ORACLE_SAMPLES_JITTER;
        oo.sample_count = (uint32_t)atoi(samples + 6);
        oo.jitter_seed = jseed;
    } else if (strcmp(samples, "center"))
        die("--samples takes center, msaa4 or jitterN", NULL);
    bool centre = oo.samples == SL_ORACLE_SAMPLES_CENTER;
#else
    (void)jseed;
    if (strcmp(samples, "center"))
        die("this build's oracle samples pixel centres only", NULL);
    bool centre = true;
#endif
    method *ms = calloc(MAX_METHODS, sizeof *ms);
    bench_method_spec specs[MAX_METHODS];
    uint32_t nm = bench_methods_parse("bench_resolution", list, g_default_methods, SL_COUNTOF(g_default_methods),
                                      threads, edit_opts, specs, MAX_METHODS);
    _Static_assert(sizeof ms->spec == sizeof specs->spec && sizeof ms->name == sizeof specs->name &&
                       sizeof ms->opts == sizeof specs->opts,
                   "method and bench_method_spec hold the same strings");
    for (uint32_t i = 0; i < nm; i++) {
        memcpy(ms[i].spec, specs[i].spec, sizeof ms[i].spec);
        memcpy(ms[i].name, specs[i].name, sizeof ms[i].name);
        memcpy(ms[i].opts, specs[i].opts, sizeof ms[i].opts);
    }
    sl_error err;
    sl_city_preset p;
    if (sl_city_preset_from_name(preset, &p, &err) != SL_OK)
        die(preset, &err);
    sl_city_options co = sl_city_defaults(p);
    sl_scene s;
    if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
        die("gen city", &err);
    sl_path path;
    if (walk) {
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.frames = walk;
        po.fps = 5;
        po.seed = seed;
        po.intrinsics.width = width;
        po.intrinsics.height = height;
        if (sl_path_generate(s, &po, NULL, &path, &err) != SL_OK)
            die("walk", &err);
    } else {
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.intrinsics.width = width;
        po.intrinsics.height = height;
        if (sl_path_random_views(s, SL_VIEWS_STREET, views, seed, &po, NULL, &path, &err) != SL_OK)
            die("views", &err);
    }
    uint32_t frames = sl_path_count(path), n = sl_scene_object_count(s);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out);
    double *t = malloc(frames * sizeof *t);
    for (uint32_t i = 0; i < nm; i++) {
        if (sl_culler_create(ms[i].name, s, ms[i].opts, NULL, &ms[i].c, &err) != SL_OK)
            die(ms[i].spec, &err);
        ms[i].g = sl_culler_guarantee(ms[i].c);
        ms[i].hash = 1469598103934665603ull;
    }
    sl_oracle o;
    if (sl_oracle_create(s, &oo, NULL, &o, &err) != SL_OK)
        die("oracle", &err);
    uint64_t visible = 0;
    double oracle_ms = 0;
    bool at_res = centre && ow == width && oh == height, violation = false;
    for (uint32_t f = 0; f < frames; f++) {
        sl_camera cam = sl_path_camera(path, f);
        sl_oracle_frame fr;
        if (sl_oracle_render(o, &cam, &fr, &err) != SL_OK)
            die("oracle render", &err);
        visible += fr.visible_count;
        oracle_ms += fr.ms;
        for (uint32_t i = 0; i < nm; i++) {
            uint32_t k = 0;
            if (sl_culler_cull(ms[i].c, &cam, out, n, &k, &err) != SL_OK)
                die(ms[i].spec, &err);
            sl_cull_metrics mt;
            if (sl_metrics_compare(s, &fr, out, k, &mt, NULL, NULL, 0, &err) != SL_OK)
                die("metrics", &err);
            ms[i].drawn += k;
            ms[i].missed += mt.missed_count;
            ms[i].missed_views += mt.missed_count != 0;
            ms[i].hash = fnv(ms[i].hash, out, k);
            for (uint32_t q = 0; by_kind && q < k; q++) {
                uint32_t lo = 0, hi = fr.visible_count; /* fr.visible is ascending */
                while (lo < hi) {
                    uint32_t mid = lo + (hi - lo) / 2;
                    if (fr.visible[mid] < out[q])
                        lo = mid + 1;
                    else
                        hi = mid;
                }
                uint32_t kind = sl_scene_object(s, out[q]).kind;
                if ((lo == fr.visible_count || fr.visible[lo] != out[q]) && kind < SL_KIND_COUNT)
                    ms[i].extra[kind]++;
            }
#ifdef SL_ORACLE_MAX_SAMPLES
            if (mt.missed_count && sl_cull_guarantee_keeps_visible(ms[i].g, at_res))
                violation = true;
#else
            if (mt.missed_count && ms[i].g == SL_CONSERVATIVE && at_res)
                violation = true;
#endif
        }
    }
    sl_oracle_destroy(o);
    /* times: whole walks, methods in turn, the order reversed every other round */
    for (uint32_t r = 0; r < rounds; r++)
        for (uint32_t j = 0; j < nm; j++) {
            uint32_t i = r % 2 ? nm - 1 - j : j;
            for (uint32_t f = 0; f < frames; f++) {
                sl_camera cam = sl_path_camera(path, f);
                uint32_t k;
                if (sl_culler_cull(ms[i].c, &cam, out, n, &k, &err) != SL_OK)
                    die(ms[i].spec, &err);
                sl_cull_stats st;
                sl_culler_stats(ms[i].c, &st);
                t[f] = st.total_ms;
            }
            ms[i].round_ms[r] = bench_median(t, frames);
        }
    printf("%s city, %u %s, culling at %ux%u, oracle %ux%u, samples %s; exact visible: %.1f objects per view "
           "(oracle %.1f ms per view); time: median over %u alternating rounds of the median cull over the views\n\n",
           preset, frames, walk ? "walk frames" : "street views", width, height, ow, oh, samples,
           (double)visible / frames, oracle_ms / frames, rounds);
    printf("| method | guarantee | missed objects | views with a miss | drawn / visible | median ms | set hash |\n"
           "|---|---|---:|---:|---:|---:|---|\n");
    for (uint32_t i = 0; i < nm; i++) {
        printf("| %s | %s | %llu | %llu | %.3f | %.4f | %016llx |\n", ms[i].spec, sl_cull_guarantee_name(ms[i].g),
               (unsigned long long)ms[i].missed, (unsigned long long)ms[i].missed_views,
               visible ? (double)ms[i].drawn / (double)visible : 0, bench_median(ms[i].round_ms, rounds),
               (unsigned long long)ms[i].hash);
        if (by_kind) {
            printf("|   drawn, not visible, by kind (per visible object):");
            for (uint32_t q = 0; q < SL_KIND_COUNT; q++)
                if (ms[i].extra[q])
                    printf(" %s %.3f", sl_object_kind_name(q), (double)ms[i].extra[q] / (double)(visible ? visible : 1));
            printf(" | | | | | |\n");
        }
        sl_culler_destroy(ms[i].c);
    }
    free(ms);
    free(out);
    free(t);
    sl_path_destroy(path);
    sl_scene_destroy(s);
    return violation ? 1 : 0;
}

/* `sightline radar`: which part of a terrain a ground radar illuminates, by the occlusion-horizon
 * sweep of Koldaş 2008 §3.3 (include/sightline/radar.h), written as an echo image; the timing
 * table of the thesis (a 60-degree sector for several grid sizes); an exact line-of-sight check. */
#include "cli.h"

#include "sightline/import.h"
#include "sightline/radar.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"
#include "tool.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEG (M_PI / 180.0)

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline radar [SCENE] [options]\n\n"
            "Radar echo generation (Koldas 2008, section 3.3): the terrain's triangles are bucketed in a grid with\n"
            "per-cell maximum heights and sorted by height; a sweep from the transmitter, front to back over the\n"
            "sector, keeps an occlusion horizon (elevation over azimuth) and finds every triangle the radar\n"
            "illuminates; the echo image shows them from above (green, brighter facing the radar), the hidden\n"
            "terrain as dim relief, black outside the sector and range, the transmitter in red.\n"
            "SCENE is a .slscene (or any scene sightline reads) with a terrain height field; without it a fractal\n"
            "terrain is generated, by default the size of the thesis' test terrain: 1651 x 1401 samples at 40 m,\n"
            "4.62M triangles, 66 x 56 km.\n\n"
            "options:\n"
            "  --samples NXxNY   generated terrain: samples (default 1651x1401)\n"
            "  --cell M          generated terrain: sample spacing in metres (default 40)\n"
            "  --relief M        generated terrain: highest minus lowest point in metres (default 900)\n"
            "  --seed N          generated terrain: seed (default 1)\n"
            "  --tx X,Y          transmitter position in metres (default: the terrain's centre)\n"
            "  --mast H          transmitter height above the ground in metres (default 30)\n"
            "  --azimuth DEG     sector start, degrees counter-clockwise from east (default 0)\n"
            "  --width DEG       sector width in degrees, (0, 360] (default 360)\n"
            "  --range M         range in metres (default: the whole terrain)\n"
            "  --grid N          grid cells along the terrain's longer side, 2..4096 (default 100)\n"
            "  --bins N          azimuth bins of the horizon, 1024..1048576 (default 16384)\n"
            "  -o, --output F    write the echo image (PNG) to F\n"
            "  --size WxH        image size in pixels (default 1280x1024)\n"
            "  --table           time a 60-degree sector for grids of 30, 60, 100, 200 and 400 cells (the\n"
            "                    thesis' table 3.3); the sweep above is then not run unless -o is given\n"
            "  --runs N          timed runs per grid for --table; the median is reported (default 5)\n"
            "  --verify N        check N random triangles against an exact line of sight from the\n"
            "                    transmitter: each one in sight must have been reported (default 0)\n"
            "  --json            print the results as JSON on stdout\n"
            "  --quiet           no progress output\n"
            CLI_ALLOW_EXTERNAL_HELP
            "  --help            this text\n\n"
            "examples:\n"
            "  sightline radar -o echo.png\n"
            "  sightline radar --samples 801x701 --tx 12000,9000 --azimuth 30 --width 60 --range 20000 -o sector.png\n"
            "  sightline radar --table --runs 5 --json\n"
            "  sightline radar hills.slscene --mast 50 --verify 2000 -o hills.png\n");
}

static bool parse_pair_u32(cli_args *a, const char *name, const char *text, uint32_t *x, uint32_t *y)
{
    char *end;
    unsigned long p = strtoul(text, &end, 10);
    if (end == text || (*end != 'x' && *end != 'X')) {
        cli_error(a->cmd, "--%s %s: expected NxM (two whole numbers)", name, text);
        a->error = true;
        return false;
    }
    const char *s = end + 1;
    unsigned long q = strtoul(s, &end, 10);
    if (end == s || *end || p > UINT32_MAX || q > UINT32_MAX) {
        cli_error(a->cmd, "--%s %s: expected NxM (two whole numbers)", name, text);
        a->error = true;
        return false;
    }
    *x = (uint32_t)p, *y = (uint32_t)q;
    return true;
}

static bool parse_pair_float(cli_args *a, const char *name, const char *text, double *x, double *y)
{
    char *end;
    double p = strtod(text, &end);
    if (end == text || *end != ',') {
        cli_error(a->cmd, "--%s %s: expected X,Y (two numbers)", name, text);
        a->error = true;
        return false;
    }
    const char *s = end + 1;
    double q = strtod(s, &end);
    if (end == s || *end || !isfinite(p) || !isfinite(q)) {
        cli_error(a->cmd, "--%s %s: expected X,Y (two finite numbers)", name, text);
        a->error = true;
        return false;
    }
    *x = p, *y = q;
    return true;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int sl_cmd_radar(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_import imp = {0};
    const char *input = NULL, *name, *val;
    cli_common com = {0};
    sl_radar_terrain_options to = sl_radar_terrain_defaults();
    sl_radar_options ro = sl_radar_default_options();
    bool have_tx = false, table = false;
    double tx = 0, ty = 0;
    float mast = 30, azimuth = 0, width = 360, range = INFINITY;
    uint32_t iw = 1280, ih = 1024, runs = 5, verify = 0;
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_OUTPUT | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!name && val[0] == '-' && val[1]) {
            cli_error(a.cmd, "unknown option %s (see sightline radar --help)", val);
            a.error = true;
        } else if (!name) {
            if (input) {
                cli_error(a.cmd, "more than one SCENE ('%s' and '%s')", input, val);
                a.error = true;
            }
            input = val;
        } else if (!strcmp(name, "h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(name, "samples")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                parse_pair_u32(&a, name, v, &to.nx, &to.ny);
        } else if (!strcmp(name, "cell")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &to.cell);
        } else if (!strcmp(name, "relief")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &to.relief);
        } else if (!strcmp(name, "seed")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_u64(&a, name, v, &to.seed);
        } else if (!strcmp(name, "tx")) {
            const char *v = cli_value(&a, name, val);
            if (v && parse_pair_float(&a, name, v, &tx, &ty))
                have_tx = true;
        } else if (!strcmp(name, "mast")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &mast);
        } else if (!strcmp(name, "azimuth")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &azimuth);
        } else if (!strcmp(name, "width")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &width);
        } else if (!strcmp(name, "range")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &range);
        } else if (!strcmp(name, "grid")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_u32(&a, name, v, &ro.grid);
        } else if (!strcmp(name, "bins")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_u32(&a, name, v, &ro.bins);
        } else if (!strcmp(name, "size")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                parse_pair_u32(&a, name, v, &iw, &ih);
        } else if (!strcmp(name, "runs")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_u32(&a, name, v, &runs);
        } else if (!strcmp(name, "verify")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_u32(&a, name, v, &verify);
        } else if (!strcmp(name, "table")) {
            table = true;
        } else if (!cli_import_option(&a, name, val, &imp)) {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    const char *output = com.output;
    bool json = com.json, quiet = com.quiet;
    (void)quiet; /* every step reports itself when done; there is no long silent stage to show */
    if (!(width > 0 && width <= 360)) {
        cli_error(a.cmd, "--width %g: must be in (0, 360]", (double)width);
        return 2;
    }
    if (!(mast > 0) || !isfinite(mast) || !(range > 0) || !isfinite(azimuth)) {
        cli_error(a.cmd, "--mast and --range must be > 0 and --azimuth finite");
        return 2;
    }
    if (runs < 1 || runs > 1000) {
        cli_error(a.cmd, "--runs %u: must be 1..1000", runs);
        return 2;
    }
    if (iw < 1 || ih < 1 || iw > 16384 || ih > 16384) {
        cli_error(a.cmd, "--size %ux%u: each side must be 1..16384", iw, ih);
        return 2;
    }
    const char *inputs[] = {input};
    if (!cli_output_not_input(a.cmd, output, inputs, 1))
        return 2;

    /* the terrain */
    sl_error err;
    sl_scene scene = NULL;
    sl_terrain_desc terrain;
    bool generated = !input;
    double t0 = tool_now();
    if (input) {
        sl_import_options io = sl_import_defaults();
        cli_import_apply(&imp, &io);
        if (cli_open_scene(input, NULL, &io, NULL, &scene, NULL, 0, &err) != SL_OK)
            return cli_fail(a.cmd, &err);
        if (!sl_scene_terrain(scene, &terrain)) {
            cli_error(a.cmd, "%s: the scene has no terrain height field", input);
            sl_scene_destroy(scene);
            return 1;
        }
    } else if (sl_radar_terrain_generate(&to, NULL, &terrain, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    double t_terrain = tool_now() - t0;
    int rc = 0;
    sl_radar radar = NULL;
    cli_json j;
    bool json_open = false;
    double ext_x = (terrain.nx - 1.0) * terrain.cell, ext_y = (terrain.ny - 1.0) * terrain.cell;
    if (!have_tx) {
        tx = terrain.origin_x + 0.5 * ext_x;
        ty = terrain.origin_y + 0.5 * ext_y;
    }
    if (tx < terrain.origin_x || ty < terrain.origin_y || tx > terrain.origin_x + ext_x || ty > terrain.origin_y + ext_y) {
        cli_error(a.cmd, "--tx %g,%g is outside the terrain (%g,%g)-(%g,%g)", tx, ty, (double)terrain.origin_x,
                  (double)terrain.origin_y, terrain.origin_x + ext_x, terrain.origin_y + ext_y);
        rc = 2;
        goto done;
    }
    t0 = tool_now();
    if (sl_radar_create(&terrain, &ro, &radar, &err) != SL_OK) {
        rc = cli_fail(a.cmd, &err);
        goto done;
    }
    double t_build = tool_now() - t0;
    sl_radar_sweep sw;
    sw.transmitter = (sl_vec3){(float)tx, (float)ty, sl_radar_height(radar, (float)tx, (float)ty) + mast};
    sw.azimuth = (float)(azimuth * DEG);
    sw.width = width >= 360 ? 6.2832f : (float)(width * DEG);
    sw.range = range;
    uint64_t ntri = sl_radar_triangle_count(radar);
    if (json) {
        cli_json_begin(&j, stdout);
        json_open = true;
        cli_json_string(&j, "terrain", generated ? "generated" : input);
        cli_json_uint(&j, "samples_x", terrain.nx);
        cli_json_uint(&j, "samples_y", terrain.ny);
        cli_json_double(&j, "spacing", terrain.cell);
        cli_json_uint(&j, "triangles", ntri);
        cli_json_double(&j, "terrain_seconds", t_terrain);
        cli_json_array_begin(&j, "transmitter");
        cli_json_double(&j, NULL, sw.transmitter.x), cli_json_double(&j, NULL, sw.transmitter.y);
        cli_json_double(&j, NULL, sw.transmitter.z);
        cli_json_array_end(&j);
    } else {
        printf("terrain: %s, %u x %u samples at %g m (%.1f x %.1f km), %.2fM triangles (%.1f s)\n",
               generated ? "generated" : input, terrain.nx, terrain.ny, (double)terrain.cell, ext_x / 1e3, ext_y / 1e3,
               ntri / 1e6, t_terrain);
        printf("transmitter: (%.0f, %.0f), %.0f m above the ground at %.1f m\n", tx, ty, (double)mast,
               (double)sw.transmitter.z - mast);
    }
    bool sweep = !table || output || verify;
    if (sweep) {
        sl_radar_stats st;
        if (sl_radar_run(radar, &sw, &st, &err) != SL_OK) {
            rc = cli_fail(a.cmd, &err);
            goto done;
        }
        uint32_t gx, gy;
        sl_radar_grid_size(radar, &gx, &gy);
        if (json) {
            cli_json_object_begin(&j, "sweep");
            cli_json_double(&j, "azimuth_deg", azimuth);
            cli_json_double(&j, "width_deg", width);
            if (isfinite(range))
                cli_json_double(&j, "range", range);
            cli_json_uint(&j, "grid_x", gx);
            cli_json_uint(&j, "grid_y", gy);
            cli_json_double(&j, "build_seconds", t_build);
            cli_json_double(&j, "ms", st.ms);
            cli_json_uint(&j, "cells_tested", st.cells_tested);
            cli_json_uint(&j, "cells_culled", st.cells_culled);
            cli_json_uint(&j, "triangles_tested", st.triangles_tested);
            cli_json_uint(&j, "triangles_visible", st.triangles_visible);
            cli_json_object_end(&j);
        } else {
            printf("grid %u x %u (built in %.2f s); sweep of %g degrees from %g: %.1f ms, %llu of %llu cells culled, "
                   "%llu triangles tested, %llu visible (%.1f%%)\n",
                   gx, gy, t_build, (double)width, (double)azimuth, st.ms, (unsigned long long)st.cells_culled,
                   (unsigned long long)st.cells_tested, (unsigned long long)st.triangles_tested,
                   (unsigned long long)st.triangles_visible, 100.0 * st.triangles_visible / (double)ntri);
        }
        if (verify) {
            /* random triangles: a sample point in sight must mean reported */
            sl_rng rng;
            sl_rng_seed(&rng, 12345, 3);
            uint64_t in_sight = 0, missed = 0, reported_hidden = 0;
            for (uint32_t k = 0; k < verify; k++) {
                uint64_t t = ((uint64_t)sl_rng_u32(&rng) << 32 | sl_rng_u32(&rng)) % ntri;
                uint64_t q = t >> 1;
                uint32_t i = (uint32_t)(q % (terrain.nx - 1)), jj = (uint32_t)(q / (terrain.nx - 1));
                double u = i + ((t & 1) ? 0.33 : 0.67), v = jj + ((t & 1) ? 0.67 : 0.33); /* the centroid */
                sl_vec3 p = {(float)(terrain.origin_x + u * terrain.cell), (float)(terrain.origin_y + v * terrain.cell), 0};
                p.z = sl_radar_height(radar, p.x, p.y);
                double az = fmod(atan2(p.y - sw.transmitter.y, p.x - sw.transmitter.x) - sw.azimuth, 2 * M_PI);
                if (az < 0)
                    az += 2 * M_PI;
                bool inside = hypot(p.x - sw.transmitter.x, p.y - sw.transmitter.y) <= range && az <= sw.width;
                bool seen = inside && sl_radar_line_of_sight(radar, sw.transmitter, p, 1e-6);
                bool rep = sl_radar_visible(radar, t);
                in_sight += seen;
                missed += seen && !rep;
                reported_hidden += rep && !seen;
            }
            if (json) {
                cli_json_object_begin(&j, "verify");
                cli_json_uint(&j, "triangles", verify);
                cli_json_uint(&j, "in_sight", in_sight);
                cli_json_uint(&j, "missed", missed);
                cli_json_uint(&j, "reported_not_in_sight_at_centroid", reported_hidden);
                cli_json_object_end(&j);
            } else
                printf("verify: %u random triangles, %llu with the centroid in sight, %llu of them missed; %llu "
                       "reported whose centroid is hidden (partly visible or conservative)\n",
                       verify, (unsigned long long)in_sight, (unsigned long long)missed,
                       (unsigned long long)reported_hidden);
            if (missed)
                rc = 1;
        }
        if (output) {
            if (sl_radar_echo_png(radar, &sw, output, iw, ih, &err) != SL_OK) {
                rc = cli_fail(a.cmd, &err);
                goto done;
            }
            if (json)
                cli_json_string(&j, "image", output);
            else
                printf("echo image: %s (%u x %u)\n", output, iw, ih);
        }
    }
    if (table) {
        static const uint32_t grids[] = {30, 60, 100, 200, 400};
        sl_radar_sweep s60 = sw;
        s60.width = (float)(60 * DEG);
        if (json)
            cli_json_array_begin(&j, "table");
        else
            printf("\n| grid | build s | 60-degree sector ms (median of %u) | 360 degrees ms | visible triangles (60) |\n"
                   "|---|---|---|---|---|\n",
                   runs);
        for (size_t g = 0; g < sizeof grids / sizeof grids[0] && rc == 0; g++) {
            sl_radar_options o = ro;
            o.grid = grids[g];
            sl_radar r2;
            double tb = tool_now();
            if (sl_radar_create(&terrain, &o, &r2, &err) != SL_OK) {
                rc = cli_fail(a.cmd, &err);
                break;
            }
            tb = tool_now() - tb;
            double ms[1000], full = 0;
            sl_radar_stats st;
            for (uint32_t k = 0; k < runs && rc == 0; k++) {
                if (sl_radar_run(r2, &s60, &st, &err) != SL_OK)
                    rc = cli_fail(a.cmd, &err);
                ms[k] = st.ms;
            }
            uint64_t vis60 = st.triangles_visible;
            sl_radar_sweep s360 = sw;
            s360.width = 6.2832f;
            if (rc == 0 && sl_radar_run(r2, &s360, &st, &err) != SL_OK)
                rc = cli_fail(a.cmd, &err);
            full = st.ms;
            sl_radar_destroy(r2);
            if (rc)
                break;
            qsort(ms, runs, sizeof ms[0], cmp_double);
            double med = runs % 2 ? ms[runs / 2] : 0.5 * (ms[runs / 2 - 1] + ms[runs / 2]);
            if (json) {
                cli_json_object_begin(&j, NULL);
                cli_json_uint(&j, "grid", grids[g]);
                cli_json_double(&j, "build_seconds", tb);
                cli_json_double(&j, "sector60_ms_median", med);
                cli_json_double(&j, "full_ms", full);
                cli_json_uint(&j, "visible_triangles_60", vis60);
                cli_json_object_end(&j);
            } else
                printf("| %u x %u | %.2f | %.1f | %.1f | %llu |\n", grids[g], grids[g], tb, med, full,
                       (unsigned long long)vis60);
        }
        if (json)
            cli_json_array_end(&j);
    }
done:
    if (json_open)
        cli_json_end(&j); /* valid JSON on stdout even after an error (reported on stderr) */
    sl_radar_destroy(radar);
    if (generated)
        sl_radar_terrain_free(&terrain, NULL);
    sl_scene_destroy(scene);
    return rc;
}

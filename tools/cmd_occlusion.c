/* `sightline occlusion`: debugging tools of the occlusion methods. `replay` re-runs a frame
 * recorded with a culler's record=FILE option (docs/occlusion.md, "Debugging outputs") through
 * sl_occ_replay (sightline/cull.h), on one instruction-set path or on every available one, and reports
 * whether the rasterizer still gives the recorded answers. */
#include "cli.h"

#include "tool.h"

#include "sightline/cull.h"

#include <string.h>

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline occlusion replay FILE [--isa scalar|sse41|avx2|avx512|auto|all] [--json]\n\n"
            "Replay a frame recorded by an occlusion method's record=FILE option (with debug_frame=N to\n"
            "pick the frame): validate the whole file, render every recorded occluder batch on a fresh\n"
            "single-threaded rasterizer with the chosen instruction set, re-run every recorded query and\n"
            "compare the answers. The rasterizer is bit-identical across paths and thread counts, so a\n"
            "replay matches exactly; the depth hash (XXH3 of the final depth buffer) is the same on\n"
            "every path.\n\n"
            "options:\n"
            "  --isa NAME   scalar, sse41, avx2, avx512, auto (the best the CPU has) or all (default:\n"
            "               every path this CPU supports, one line each)\n"
            "  --json       machine-readable output on stdout\n"
            "  --help       this text\n\n"
            "Exit status: 0 every answer matched, 1 a mismatch or a bad file, 2 usage error.\n\n"
            "examples:\n"
            "  sightline bench city:tiny --walk 5 --methods hzb --method-options hzb:record=/tmp/f.rec,debug_frame=2\n"
            "  sightline occlusion replay /tmp/f.rec\n"
            "  sightline occlusion replay /tmp/f.rec --isa scalar --json\n");
}

static const struct {
    const char *name;
    sl_raster_isa isa;
} g_isas[] = {{"scalar", SL_RASTER_ISA_SCALAR},
              {"sse41", SL_RASTER_ISA_SSE41},
              {"avx2", SL_RASTER_ISA_AVX2},
              {"avx512", SL_RASTER_ISA_AVX512},
              {"auto", SL_RASTER_ISA_AUTO}};

/* One replay per path: the path, its report. */
typedef struct replay_run {
    sl_raster_isa isa;
    sl_occ_replay_report rep;
} replay_run;

static void print_text(const char *file, const replay_run *runs, uint32_t n)
{
    const sl_occ_replay_report *r0 = &runs[0].rep;
    printf("%s: %ux%u, %u batches (%llu triangles), %u queries (%u recorded occluded)\n", file, r0->width,
           r0->height, r0->batches, (unsigned long long)r0->triangles, r0->queries, r0->occluded);
    for (uint32_t i = 0; i < n; i++) {
        const sl_occ_replay_report *r = &runs[i].rep;
        printf("  %-7s %s", runs[i].isa == SL_RASTER_ISA_AUTO ? "auto" : sl_raster_isa_name(runs[i].isa),
               r->mismatches ? "MISMATCH" : "ok");
        if (r->mismatches)
            printf(" (%u queries differ, first #%u)", r->mismatches, r->first_mismatch);
        printf("  depth hash %016llx\n", (unsigned long long)r->depth_hash);
    }
}

static void print_json(const char *file, const replay_run *runs, uint32_t n, bool ok)
{
    const sl_occ_replay_report *r0 = &runs[0].rep;
    cli_json j;
    cli_json_begin(&j, stdout);
    cli_json_string(&j, "file", file);
    cli_json_uint(&j, "width", r0->width);
    cli_json_uint(&j, "height", r0->height);
    cli_json_uint(&j, "batches", r0->batches);
    cli_json_uint(&j, "triangles", r0->triangles);
    cli_json_uint(&j, "queries", r0->queries);
    cli_json_uint(&j, "occluded", r0->occluded);
    cli_json_array_begin(&j, "replays");
    for (uint32_t i = 0; i < n; i++) {
        const sl_occ_replay_report *r = &runs[i].rep;
        char hash[32];
        snprintf(hash, sizeof hash, "%016llx", (unsigned long long)r->depth_hash);
        cli_json_object_begin(&j, NULL);
        cli_json_string(&j, "isa", runs[i].isa == SL_RASTER_ISA_AUTO ? "auto" : sl_raster_isa_name(runs[i].isa));
        cli_json_uint(&j, "mismatches", r->mismatches);
        if (r->mismatches)
            cli_json_uint(&j, "first_mismatch", r->first_mismatch);
        cli_json_string(&j, "depth_hash", hash);
        cli_json_object_end(&j);
    }
    cli_json_array_end(&j);
    cli_json_bool(&j, "ok", ok);
    cli_json_end(&j);
}

static int cmd_replay(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    a.cmd = "occlusion replay";
    const char *name, *val, *file = NULL, *isa_name = "all";
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_JSON, &com)) {
        } else if (!name) {
            if (file) {
                cli_error(a.cmd, "more than one FILE ('%s')", val);
                a.error = true;
                break;
            }
            file = val;
        } else if (!strcmp(name, "isa")) {
            isa_name = cli_value(&a, name, val);
        } else {
            cli_unknown(&a, name);
        }
    }
    if (com.help) {
        usage(stdout);
        return 0;
    }
    if (a.error || !isa_name) {
        if (a.unknown[0])
            cli_suggest_option(a.cmd, a.unknown, usage);
        return 2;
    }
    bool json = com.json;
    if (!file) {
        cli_error(a.cmd, "missing FILE (see sightline occlusion --help)");
        return 2;
    }
    replay_run runs[TOOL_COUNTOF(g_isas)];
    uint32_t n = 0;
    bool all = !strcmp(isa_name, "all"), known = all;
    for (size_t i = 0; i < TOOL_COUNTOF(g_isas); i++) {
        bool pick = all ? g_isas[i].isa != SL_RASTER_ISA_AUTO && sl_raster_isa_available(g_isas[i].isa)
                        : !strcmp(isa_name, g_isas[i].name);
        known = known || pick;
        if (pick && !all && g_isas[i].isa != SL_RASTER_ISA_AUTO && !sl_raster_isa_available(g_isas[i].isa)) {
            cli_error(a.cmd, "--isa %s: this CPU does not support it", isa_name);
            return 1;
        }
        if (pick)
            runs[n++].isa = g_isas[i].isa;
    }
    if (!known) {
        cli_error(a.cmd, "--isa '%s': expected scalar, sse41, avx2, avx512, auto or all", isa_name);
        return 2;
    }
    bool ok = true;
    for (uint32_t i = 0; i < n; i++) {
        sl_error err;
        if (sl_occ_replay(file, runs[i].isa, NULL, &runs[i].rep, &err) != SL_OK)
            return cli_fail(a.cmd, &err);
        ok = ok && runs[i].rep.mismatches == 0 && runs[i].rep.depth_hash == runs[0].rep.depth_hash;
    }
    if (json)
        print_json(file, runs, n, ok);
    else
        print_text(file, runs, n);
    if (!ok) {
        cli_error(a.cmd, "%s: the replay does not match the recording (or the paths disagree on the depth buffer)",
                  file);
        return 1;
    }
    return 0;
}

int sl_cmd_occlusion(int argc, char **argv)
{
    static const char *const actions[] = {"replay"};
    int status, k = cli_action(argc, argv, "occlusion", usage, actions, 1, &status);
    return k < 0 ? status : cmd_replay(argc - 1, argv + 1);
}

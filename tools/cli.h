/* Shared pieces of the `sightline` command: the subcommand table, option parsing, progress bars,
 * JSON output and error reporting. Every subcommand lives in tools/cmd_<name>.c and follows the
 * same shape: parse options (unknown ones are errors), do the work, print a human summary or
 * --json, return an exit status (0 ok, 1 failure, 2 usage error). */
#ifndef SL_TOOLS_CLI_H
#define SL_TOOLS_CLI_H

#include "sightline/bench.h"
#include "sightline/core.h"
#include "sightline/scene.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

typedef int (*sl_cmd_fn)(int argc, char **argv);

typedef struct sl_command {
    const char *name;
    sl_cmd_fn run;
    const char *summary;
} sl_command;

/* Subcommands (each in tools/cmd_<name>.c). argv[0] is the subcommand name. */
int sl_cmd_gen(int argc, char **argv);
int sl_cmd_import(int argc, char **argv);
int sl_cmd_occluders(int argc, char **argv);
int sl_cmd_info(int argc, char **argv);
int sl_cmd_path(int argc, char **argv);
int sl_cmd_export(int argc, char **argv);
int sl_cmd_demo(int argc, char **argv);
int sl_cmd_bench(int argc, char **argv);
int sl_cmd_render(int argc, char **argv);
int sl_cmd_radar(int argc, char **argv);
int sl_cmd_methods(int argc, char **argv);
int sl_cmd_pvs(int argc, char **argv);
int sl_cmd_occlusion(int argc, char **argv);
int sl_cmd_view(int argc, char **argv);
int sl_cmd_vis_server(int argc, char **argv);
int sl_cmd_vis_client(int argc, char **argv);

/* ---- errors ---- */
/* Print "sightline <cmd>: message" to stderr. */
void cli_error(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Print an sl_error and return exit status 1. */
int cli_fail(const char *cmd, const sl_error *err);

/* ---- option parsing ----
 * A small long-option parser: "--name value", "--name=value" and flags "--name". */
typedef struct cli_args {
    int argc;
    char **argv;
    int i;             /* next argument */
    const char *cmd;   /* subcommand, for messages */
    bool error;        /* a parse error was reported */
    char namebuf[128]; /* option name split off "--name=value" */
    char unknown[64];  /* the first unknown option's name (cli_unknown), for cli_parse_done's "did you mean" */
} cli_args;

void cli_args_init(cli_args *a, int argc, char **argv);
/* True while options remain; *name receives the option name without dashes, *inline_value the
 * text after '=' (or NULL). Positional arguments are returned with *name == NULL and the text in
 * *inline_value. */
bool cli_next(cli_args *a, const char **name, const char **inline_value);
/* Value of the current option (inline or the next argument); NULL and an error if missing. */
const char *cli_value(cli_args *a, const char *name, const char *inline_value);
/* Parse numbers with full validation; report an error and return false on bad text. */
bool cli_parse_u32(cli_args *a, const char *name, const char *text, uint32_t *out);
bool cli_parse_u64(cli_args *a, const char *name, const char *text, uint64_t *out);
/* --threads N: 1..sl_thread_limit() (SL_MAX_THREADS, or the OpenMP runtime's lower limit); 0 too
 * when zero_ok (the command's default: all cores). Every command parses thread counts with it. */
bool cli_parse_threads(cli_args *a, const char *name, const char *text, bool zero_ok, uint32_t *out);
bool cli_parse_float(cli_args *a, const char *name, const char *text, float *out);
/* Report an unknown option and mark the parse failed. */
void cli_unknown(cli_args *a, const char *name);

/* The options the subcommands share, parsed in one place: every command's loop starts with
 *     if (cli_common_option(&a, name, val, CLI_INPUT | CLI_JSON, &com)) continue;
 * and after it
 *     int parsed = cli_parse_done(&a, &com, usage);  if (parsed >= 0) return parsed;
 * --help (and -h) is always taken and ends the parse (what follows it is not read, so
 * `CMD --help --bad` still prints the help). The others only when named in `which`
 * (tests/cli/options.sh). */
enum {
    CLI_INPUT = 1u << 0,  /* one positional argument into c->input; a second is an error */
    CLI_OUTPUT = 1u << 1, /* -o FILE, --output FILE */
    CLI_MAP = 1u << 2,    /* --map NAME (a map of a .pk3 archive) */
    CLI_JSON = 1u << 3,   /* --json */
    CLI_QUIET = 1u << 4,  /* --quiet */
};
typedef struct cli_common {
    const char *input, *output, *map;
    bool json, quiet, help;
} cli_common;
/* True when name/value (from cli_next) was one of them (a bad one marks the parse failed). */
bool cli_common_option(cli_args *a, const char *name, const char *value, unsigned which, cli_common *c);

/* The end of a command's parse: -1 to go on, else the exit status to return at once: 0 after
 * printing usage(stdout) for --help, 2 after a parse error (already reported; after an unknown
 * option it adds "did you mean --X?" with the nearest options of usage's text). */
int cli_parse_done(const cli_args *a, const cli_common *c, void (*usage)(FILE *));
/* "did you mean" for an unknown option `name` (without dashes) of command cmd, from the options
 * ("--word") that usage's text names: prints "sightline CMD: did you mean --X?" when one is close. */
void cli_suggest_option(const char *cmd, const char *name, void (*usage)(FILE *));

/* The method grammar of every command that takes methods: --methods NAME[:key=value[:key=value...]],...
 * (a method's options colon-separated, since commas separate the methods). Parses `text` into
 * specs: names and options point into buf, a copy of text (each method's colons turned into
 * commas, the sl_culler_create form). Every name must be registered (a wrong one gets the close
 * matches) and listed once, with no empty option list, at most max methods. Returns the count, or
 * -1 after printing a usage error that names the method. Options are not checked here. */
int cli_method_list(const char *cmd, const char *text, char *buf, size_t buf_size, sl_bench_method_spec *specs,
                    uint32_t max);

/* Take the methods of run[0..*n) that cannot cull more than the frustum on scene
 * (sl_cull_method_applicable) out of it, each said on stderr unless quiet ("not running M on
 * LABEL: not applicable: WHY") and added to skipped (at most max, *nskipped counts them) with the
 * reason "LABEL: not applicable: WHY". A method whose options fail is left in (its culler says why). */
void cli_drop_not_applicable(const char *cmd, sl_scene scene, const char *label, sl_bench_method_spec *run,
                             uint32_t *n, sl_bench_skip *skipped, uint32_t *nskipped, uint32_t max, bool quiet);

/* The action of a command that has actions (`sightline pvs build ...`, argv[1]): its index in
 * names[0..count), or -1 with *status set after printing the usage (to stdout for --help, -h or
 * help: 0; to stderr when there is no action: 2) or "unknown action 'X' (A, B or C; see sightline
 * CMD --help)" (2). */
int cli_action(int argc, char **argv, const char *cmd, void (*usage)(FILE *), const char *const *names, int count,
               int *status);

/* ---- --allow-external PATH (repeatable): commands whose scene argument can be an assimp file ----
 * A model's references (glTF buffers and images, OBJ material libraries ...) resolve only inside
 * the model's folder unless these allow more (sl_import_options.allow_external). */
#define CLI_ALLOW_EXTERNAL_MAX 64
typedef struct cli_import {
    const char *allow[CLI_ALLOW_EXTERNAL_MAX];
    uint32_t count;
    uint32_t timeout_ms; /* --import-timeout S (0: none): assimp's child process is stopped after it */
} cli_import;
/* Handle --allow-external and --import-timeout (true when name was one of them; a missing or bad
 * value or too many paths mark the parse failed). */
bool cli_import_option(cli_args *a, const char *name, const char *inline_value, cli_import *imp);
/* Import options carrying the allowed paths (borrowed from imp, which must outlive the open). */
struct sl_import_options;
void cli_import_apply(const cli_import *imp, struct sl_import_options *opt);
/* The --help line for it. */
#define CLI_ALLOW_EXTERNAL_HELP                                                                         \
    "  --allow-external PATH  let an assimp model's references (buffers, images, material\n"            \
    "                     libraries) resolve inside PATH (a folder, or one file) as well as in the\n"   \
    "                     model's own folder; repeatable (docs/import-export.md)\n"            \
    "  --import-timeout S  stop assimp (which reads a model in a child process) after S seconds\n" \
    "                     and fail; default: no limit\n"

/* ---- occluder synthesis options (`occluders`, `import`; tools/cmd_occluders.c) ---- */
struct sl_synth_options;
struct sl_synth_stats;
struct cli_json;
/* --voxel, --min-box, --weld, --per-object, --max-boxes, --max-voxels, --no-expand (true when
 * name was one of them; a bad value marks the parse failed). */
bool cli_synth_option(cli_args *a, const char *name, const char *val, struct sl_synth_options *o);
/* The statistics as text lines (stdout), or as the JSON object "occluders". */
void cli_synth_print(const struct sl_synth_stats *s);
void cli_synth_json(struct cli_json *j, const struct sl_synth_stats *s);
#define CLI_SYNTH_HELP                                                                             \
    "  --voxel M          voxel edge in metres (default: per object, from its size)\n"             \
    "  --min-box M        smallest box edge kept, metres (default: two voxels)\n"                  \
    "  --weld M           weld vertices closer than M (default: 1e-6 of the scene's size)\n"       \
    "  --per-object N     at most N boxes per object, the largest (default 16)\n"                  \
    "  --max-boxes N      at most N boxes in the scene, the largest (default 65536)\n"             \
    "  --max-voxels N     voxels per object at most (default 2097152; coarser beyond)\n"           \
    "  --no-expand        keep boxes on the voxel grid (no growing towards the surface)\n"

/* ---- progress ----
 * A progress bar on stderr when stderr is a terminal, CI is unset and --quiet/--json were not
 * given; silent otherwise. Pass &cli_progress(...) as the library's sl_progress. The bar shows the
 * stage, done/total, the percentage, the rate per second, the elapsed time and the ETA.
 * cli_progress_json instead writes one JSON object per line to stderr, at most one a second per
 * stage plus the last ({"progress":"STAGE","done":D,"total":T,"elapsed_s":E,"eta_s":S,"rate":R};
 * eta_s null while unknown), for tools reading a --json command (whatever stderr is). */
typedef struct cli_progress_state {
    bool enabled, json;
    double last_draw, stage_start;
    char stage[64];
} cli_progress_state;
sl_progress cli_progress(cli_progress_state *st, bool quiet);
sl_progress cli_progress_json(cli_progress_state *st);
/* End a progress line (clears the bar). */
void cli_progress_done(cli_progress_state *st);

/* ---- JSON output ---- */
typedef struct cli_json {
    FILE *out;
    int depth;
    bool need_comma[32];
} cli_json;
void cli_json_begin(cli_json *j, FILE *out);  /* opens the top-level object */
void cli_json_end(cli_json *j);               /* closes it and prints a newline */
void cli_json_key(cli_json *j, const char *key);
void cli_json_object_begin(cli_json *j, const char *key); /* key may be NULL inside arrays */
void cli_json_object_end(cli_json *j);
void cli_json_array_begin(cli_json *j, const char *key);
void cli_json_array_end(cli_json *j);
void cli_json_string(cli_json *j, const char *key, const char *value);
void cli_json_int(cli_json *j, const char *key, int64_t value);
void cli_json_uint(cli_json *j, const char *key, uint64_t value);
void cli_json_double(cli_json *j, const char *key, double value);
void cli_json_bool(cli_json *j, const char *key, bool value);

/* ---- outputs ----
 * Before a command writes OUTPUT: false (after "sightline CMD: the output OUTPUT is the input
 * file INPUT; give another -o") when OUTPUT names the same file as one of the count inputs (NULL
 * entries skipped). Compared by device and inode, not by name, so "x", "./x", hard links and
 * symbolic links to an input are all caught; an output that does not exist yet is no input. */
bool cli_output_not_input(const char *cmd, const char *output, const char *const *inputs, size_t count);

/* A run that writes a folder of files (bench, demo): every file goes into a new folder, od->stage,
 * and commit moves them into the folder the user named, so that a run that fails midway leaves
 * that folder exactly as it was. A folder that does not exist yet: the stage is made beside it
 * (its parents are created) and renamed to it. An existing folder: the stage is made inside it
 * (".sightline-run.tmp.PID.HEX", on the same file system) and commit moves only the files this
 * run wrote into it, replacing those of the same names; nothing else in it is touched, so
 * `--out .` is safe. Stages left by killed runs (their process gone) are removed by the next run
 * into the same folder. begin and commit print their error and return false. */
typedef struct cli_outdir {
    char target[4096]; /* as given, less trailing slashes */
    char stage[4200];
    bool fresh;        /* target did not exist */
    bool open;
    const char *const *inputs; /* optional: files the run read, which commit refuses to replace */
    size_t input_count;
} cli_outdir;
bool cli_outdir_begin(const char *cmd, const char *dir, cli_outdir *od);
bool cli_outdir_commit(const char *cmd, cli_outdir *od);
/* Remove the stage and what the run wrote into it; the target is left as it was. */
void cli_outdir_abort(cli_outdir *od);
/* Show the bench's method options as they will read once the stage is moved into place: every
 * "STAGE/" in them reads "OUT/" (a pvs file= baked into the stage is named where it ends up),
 * through sl_bench_set_shown_options. stage or out NULL: nothing changes. */
sl_status cli_outdir_show_bench(sl_bench bench, const char *stage, const char *out, sl_error *err);

/* ---- scenes named on a command line ---- */
/* Open the scene a command line names (`bench`, `render`, `demo`): "city:PRESET[:SEED]"
 * generates a city (sl_gen_city with the preset's defaults, tiny|small|vienna|oldtown|oldtown-small,
 * seed 1 by default); anything else is a file read by sl_scene_open_with (opt may be NULL; map: the map inside a
 * .pk3, else NULL). label (label_size bytes, may be NULL) receives a short name for reports made
 * of [A-Za-z0-9._-]: "city-small-1", or the file's base name without its extension (and "-MAP").
 * progress (may be NULL) reports city generation. tools/scene_spec.c. */
sl_status cli_open_scene(const char *spec, const char *map, const struct sl_import_options *opt,
                         const sl_progress *progress, sl_scene *out, char *label, size_t label_size, sl_error *err);

/* ---- misc ---- */
/* Human-readable byte count ("1.23 GiB") into buf. */
const char *cli_bytes(uint64_t bytes, char *buf, size_t size);
/* Peak resident memory of this process in bytes (from /proc/self/status VmHWM). */
uint64_t cli_peak_rss(void);

#endif

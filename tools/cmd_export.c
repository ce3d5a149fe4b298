/* `sightline export`: write a scene through assimp (OBJ, glTF 2.0, GLB, PLY, STL, COLLADA, FBX,
 * ...) so that other tools can open it. */
#include "cli.h"

#include "tool.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <assimp/cexport.h>

#include <ctype.h>
#include <string.h>
#include <sys/stat.h>

/* Export ids that sl_export_assimp refuses (mirrors refused_formats in
 * src/import/export_assimp.c, which gives the reasons). */
static const char *const refused[] = {"3mf", "pbrt"};

static bool is_refused(const char *id)
{
    for (size_t i = 0; i < TOOL_COUNTOF(refused); i++)
        if (!strcmp(refused[i], id))
            return true;
    return false;
}

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sightline export SCENE OUT [--format ID] [--up y|z] [--map NAME]\n"
            "                        [--allow-external PATH] [--json] [--quiet]\n"
            "       sightline export --list-formats [--json]\n\n"
            "Write a scene in a format other tools open, through assimp: one node per object with its\n"
            "transform, one mesh per instanced mesh (shared), one material per colour. The format comes\n"
            "from OUT's extension (.obj, .gltf = glTF 2.0 with a .bin beside it, .glb = binary glTF 2.0,\n"
            ".ply, .stl, .dae, .fbx, ...) unless --format names an assimp export id. Side files (.mtl,\n"
            ".bin) are written next to OUT; nothing is left behind when the export fails. The same\n"
            "scene gives the same bytes: COLLADA and FBX carry the fixed date 1970-01-01 instead of\n"
            "the time of writing.\n\n"
            "SCENE is a .slscene file, a Quake III .bsp, a .pk3 archive (with --map), any file assimp\n"
            "reads, or city:tiny|small|vienna[:SEED] (the generated city, made on the fly).\n\n"
            "options:\n"
            "  --format ID      assimp export id (see --list-formats), e.g. obj, gltf2, glb2, plyb, stlb\n"
            "  --up y|z         up axis written (default y, what most tools expect; glTF is always y)\n"
            "  --map NAME       map inside a .pk3\n"
            CLI_ALLOW_EXTERNAL_HELP
            "  --list-formats   list assimp's export formats and exit\n"
            "  --json           machine-readable summary on stdout\n"
            "  --quiet          no progress output\n"
            "  --help           this text\n\n"
            "examples:\n"
            "  sightline export city-vienna-1.slscene city.glb\n"
            "  sightline export sponza.slscene sponza.obj --up z\n"
            "  sightline export q3dm17.slscene q3dm17.ply --format plyb\n");
}

static int list_formats(bool json)
{
    size_t n = aiGetExportFormatCount();
    cli_json j;
    if (json) {
        cli_json_begin(&j, stdout);
        cli_json_array_begin(&j, "formats");
    }
    for (size_t i = 0; i < n; i++) {
        const struct aiExportFormatDesc *d = aiGetExportFormatDescription(i);
        if (!d)
            continue;
        if (is_refused(d->id)) {
            aiReleaseExportFormatDescription(d);
            continue;
        }
        if (json) {
            cli_json_object_begin(&j, NULL);
            cli_json_string(&j, "id", d->id);
            cli_json_string(&j, "extension", d->fileExtension);
            cli_json_string(&j, "description", d->description);
            cli_json_object_end(&j);
        } else {
            printf("%-10s .%-8s %s\n", d->id, d->fileExtension, d->description);
        }
        aiReleaseExportFormatDescription(d);
    }
    if (json) {
        cli_json_array_end(&j);
        cli_json_end(&j);
    }
    return 0;
}

/* True when the export will be glTF (always Y-up): by id, or by OUT's extension without one. */
static bool is_gltf(const char *out, const char *format)
{
    if (format)
        return !strncmp(format, "gltf", 4) || !strncmp(format, "glb", 3);
    const char *base = strrchr(out, '/');
    base = base ? base + 1 : out;
    const char *dot = strrchr(base, '.');
    if (!dot)
        return false;
    char ext[8];
    size_t k = 0;
    for (const char *p = dot + 1; *p && k + 1 < sizeof ext; p++)
        ext[k++] = (char)tolower((unsigned char)*p);
    ext[k] = 0;
    return !strcmp(ext, "gltf") || !strcmp(ext, "glb");
}

int sl_cmd_export(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_import imp = {0};
    const char *name, *val, *input = NULL, *output = NULL, *format = NULL, *up = NULL;
    bool listing = false;
    cli_common com = {0};
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_MAP | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!name) {
            if (!input) {
                input = val;
            } else if (!output) {
                output = val;
            } else {
                cli_unknown(&a, NULL);
                break;
            }
        } else if (!strcmp(name, "format")) {
            format = cli_value(&a, name, val);
        } else if (!strcmp(name, "up")) {
            up = cli_value(&a, name, val);
            if (up && strcmp(up, "y") && strcmp(up, "z")) {
                cli_error(a.cmd, "--up: '%s' is not y or z", up);
                a.error = true;
            }
        } else if (!strcmp(name, "list-formats")) {
            listing = true;
        } else if (!cli_import_option(&a, name, val, &imp)) {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, usage);
    if (parsed >= 0)
        return parsed;
    const char *map = com.map;
    bool json = com.json, quiet = com.quiet;
    if (listing)
        return list_formats(json);
    if (!input || !output) {
        cli_error(a.cmd, "need SCENE and OUT (see sightline export --help)");
        return 2;
    }
    const char *inputs[] = {input};
    if (!cli_output_not_input(a.cmd, output, inputs, 1))
        return 2;
    if (up && !strcmp(up, "z") && is_gltf(output, format)) {
        cli_error(a.cmd, "glTF is Y-up by definition; --up z cannot apply");
        return 2;
    }
    (void)quiet; /* neither opening nor assimp's exporter reports progress */
    sl_up_axis axis = up && !strcmp(up, "z") ? SL_UP_Z : SL_UP_Y;

    sl_error err;
    sl_scene scene;
    double t0 = tool_now();
    sl_import_options io = sl_import_defaults();
    cli_import_apply(&imp, &io);
    if (cli_open_scene(input, map, &io, NULL, &scene, NULL, 0, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    double t1 = tool_now();
    if (sl_export_assimp(scene, output, format, axis, &err) != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    double t2 = tool_now();
    sl_scene_stats s;
    sl_scene_get_stats(scene, &s);
    struct stat fs;
    uint64_t bytes = stat(output, &fs) == 0 ? (uint64_t)fs.st_size : 0;
    const char *up_name = axis == SL_UP_Z && !is_gltf(output, format) ? "z" : "y";
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "input", input);
        cli_json_string(&j, "output", output);
        cli_json_string(&j, "format", format); /* null: chosen by the extension */
        cli_json_string(&j, "up_axis", up_name);
        cli_json_uint(&j, "objects", s.object_count);
        cli_json_uint(&j, "meshes", s.mesh_count);
        cli_json_uint(&j, "triangles_instanced", s.instanced_triangle_count);
        cli_json_double(&j, "open_seconds", t1 - t0);
        cli_json_double(&j, "export_seconds", t2 - t1);
        cli_json_uint(&j, "output_bytes", bytes);
        cli_json_end(&j);
    } else {
        char b[32];
        printf("%s -> %s (%s, %s-up)\n", input, output, format ? format : "format from extension", up_name);
        printf("  objects        %u (meshes %u), %llu triangles\n", s.object_count, s.mesh_count,
               (unsigned long long)s.instanced_triangle_count);
        printf("  time           %.3f s open, %.3f s export\n", t1 - t0, t2 - t1);
        printf("  output         %s\n", cli_bytes(bytes, b, sizeof b));
    }
    sl_scene_destroy(scene);
    return 0;
}

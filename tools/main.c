/* `sightline`: the command-line front end of the library. One subcommand per file. */
#include "cli.h"

#include <stdio.h>
#include <string.h>

static const sl_command commands[] = {
    {"gen", sl_cmd_gen, "generate a procedural city (gen city --preset tiny|small|vienna|oldtown|oldtown-small) or edit one (gen edit)"},
    {"import", sl_cmd_import, "import OBJ/glTF/PLY/FBX/... (assimp), Quake III .bsp/.pk3 or GIS cities (GeoJSON, Shapefile, OSM, CityGML)"},
    {"occluders", sl_cmd_occluders, "synthesise conservative occluders (boxes inside closed meshes) for a scene"},
    {"info", sl_cmd_info, "counts, bounds, memory and per-kind statistics of a scene"},
    {"path", sl_cmd_path, "generate, inspect or validate a camera path"},
    {"export", sl_cmd_export, "export a scene to OBJ, glTF 2.0 or another assimp format"},
    {"methods", sl_cmd_methods, "list the culling methods, their guarantee and options"},
    {"bench", sl_cmd_bench, "run culling methods over scenes and paths against the oracle; CSV, JSON, plots"},
    {"render", sl_cmd_render, "write id, depth, overdraw (and cull map) images for a camera or a path"},
    {"radar", sl_cmd_radar, "radar echo image of a terrain from a transmitter (occlusion horizon sweep)"},
    {"pvs", sl_cmd_pvs, "from-region visibility: pvs build | update | info | query | verify"},
    {"occlusion", sl_cmd_occlusion, "debugging of the occlusion methods: occlusion replay FILE (a recorded frame)"},
    {"view", sl_cmd_view, "walk or fly through a scene in a window: the renderer, a culler, HUD, freeze, map"},
    {"vis-server", sl_cmd_vis_server, "serve visible sets over TCP to clients sending viewpoints (docs/vis-server.md)"},
    {"vis-client", sl_cmd_vis_client, "walk a path through a vis-server, optionally checking every set it displays"},
    {"demo", sl_cmd_demo, "generate the default city, run the walkthrough and write a report"},
};

static void usage(FILE *out)
{
    fprintf(out, "usage: sightline <command> [options]   (sightline <command> --help for details)\n\n"
                 "Sightline %s: visibility culling for large 3D scenes.\n\ncommands:\n",
            sl_version_string());
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(out, "  %-9s %s\n", commands[i].name, commands[i].summary);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("sightline %s\n", sl_version_string());
        return 0;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (!strcmp(argv[1], commands[i].name))
            return commands[i].run(argc - 1, argv + 1);
    const char *names[sizeof commands / sizeof commands[0]];
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        names[i] = commands[i].name;
    char near[160];
    if (sl_text_suggest(argv[1], names, sizeof names / sizeof names[0], near, sizeof near))
        fprintf(stderr, "sightline: unknown command '%s' (did you mean %s?)\n", argv[1], near);
    else
        fprintf(stderr, "sightline: unknown command '%s'\n", argv[1]);
    usage(stderr);
    return 2;
}

/* An engine's frame loop with Sightline (examples/README.md).
 *
 * The "engine" below owns its entities (a name, a position, a size, a kind) and its camera (a
 * view and a projection matrix, column-major, OpenGL depth, as most engines keep them). Once, it
 * hands its geometry to Sightline: one unit-cube mesh, one object per entity, scaled and moved by
 * the entity's transform; buildings are closed solids that may hide what is behind them. Every
 * frame it builds an sl_view from its own matrices, asks a culler which objects may be visible,
 * and maps the ids back to its entities. A car moves every frame: the engine updates its transform
 * and tells the culler. Links libsightline_runtime only (no Embree, assimp or GEOS).
 *
 *   engine_loop [FRAMES]    (default 60; exit status 0 when every check held) */
#include <sightline/cull.h>
#include <sightline/scene.h>
#include <sightline/view.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef enum { ENT_BUILDING, ENT_CRATE, ENT_CAR } ent_kind;

typedef struct entity {
    char name[32];
    float pos[3];  /* centre of the base */
    float size[3]; /* extent */
    ent_kind kind;
    uint32_t object; /* Sightline's object id */
} entity;

#define GRID 8
#define MAX_ENT (GRID * GRID * 3 + 1)

static int fail(const char *what, const sl_error *err)
{
    fprintf(stderr, "engine_loop: %s: %s\n", what, err ? err->message : "check failed");
    return 1;
}

/* column-major look-at (world -> eye) and OpenGL perspective, as an engine's math library makes them */
static void look_at(const float eye[3], const float at[3], float m[16])
{
    float f[3] = {at[0] - eye[0], at[1] - eye[1], at[2] - eye[2]}, up[3] = {0, 0, 1};
    float fl = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    for (int i = 0; i < 3; i++)
        f[i] /= fl;
    float s[3] = {f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0]};
    float sl = sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    for (int i = 0; i < 3; i++)
        s[i] /= sl;
    float u[3] = {s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2], s[0] * f[1] - s[1] * f[0]};
    memset(m, 0, 16 * sizeof *m);
    for (int i = 0; i < 3; i++) {
        m[i * 4 + 0] = s[i];
        m[i * 4 + 1] = u[i];
        m[i * 4 + 2] = -f[i];
    }
    m[12] = -(s[0] * eye[0] + s[1] * eye[1] + s[2] * eye[2]);
    m[13] = -(u[0] * eye[0] + u[1] * eye[1] + u[2] * eye[2]);
    m[14] = f[0] * eye[0] + f[1] * eye[1] + f[2] * eye[2];
    m[15] = 1;
}

static void perspective(float fovy_deg, float aspect, float n, float f, float m[16])
{
    float t = 1.0f / tanf(fovy_deg * 3.14159265f / 360.0f);
    memset(m, 0, 16 * sizeof *m);
    m[0] = t / aspect;
    m[5] = t;
    m[10] = (f + n) / (n - f);
    m[11] = -1;
    m[14] = 2 * f * n / (n - f);
}

static sl_affine transform_of(const entity *e)
{
    /* the unit cube spans [0,1]^3: scale by the size, put its base centre at pos (3x4, row-major) */
    sl_affine a = {{e->size[0], 0, 0, e->pos[0] - 0.5f * e->size[0],  /* row x */
                    0, e->size[1], 0, e->pos[1] - 0.5f * e->size[1],  /* row y */
                    0, 0, e->size[2], e->pos[2]}};                    /* row z */
    return a;
}

int main(int argc, char **argv)
{
    int frames = argc > 1 ? atoi(argv[1]) : 60;
    if (frames < 1 || frames > 100000) {
        fprintf(stderr, "usage: engine_loop [FRAMES]\n");
        return 2;
    }
    /* the engine's world: a grid of blocks (a building each, a crate behind it, a car on the street) */
    static entity ents[MAX_ENT];
    uint32_t n = 0;
    for (int i = 0; i < GRID; i++)
        for (int j = 0; j < GRID; j++) {
            float x = (float)i * 40.0f, y = (float)j * 40.0f;
            entity *b = &ents[n++];
            snprintf(b->name, sizeof b->name, "building-%d-%d", i, j);
            b->kind = ENT_BUILDING;
            memcpy(b->pos, (float[3]){x, y, 0}, sizeof b->pos);
            memcpy(b->size, (float[3]){30, 30, 12 + (float)((i * 7 + j * 3) % 5) * 4}, sizeof b->size);
            entity *c = &ents[n++];
            snprintf(c->name, sizeof c->name, "crate-%d-%d", i, j);
            c->kind = ENT_CRATE;
            memcpy(c->pos, (float[3]){x + 20, y, 0}, sizeof c->pos); /* in the alley beside the building */
            memcpy(c->size, (float[3]){2, 2, 2}, sizeof c->size);
            entity *car = &ents[n++];
            snprintf(car->name, sizeof car->name, "car-%d-%d", i, j);
            car->kind = ENT_CAR;
            memcpy(car->pos, (float[3]){x, y - 20, 0}, sizeof car->pos); /* on the street in front */
            memcpy(car->size, (float[3]){4.5f, 1.8f, 1.5f}, sizeof car->size);
        }

    sl_error err;
    sl_scene scene;
    if (sl_scene_create(NULL, &scene, &err) != SL_OK)
        return fail("scene", &err);
    static const float cube_v[24] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1};
    static const uint32_t cube_i[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                        2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    sl_mesh_desc md = {.positions = cube_v, .vertex_count = 8, .indices = cube_i, .triangle_count = 12};
    uint32_t cube;
    if (sl_scene_add_mesh(scene, &md, &cube, &err) != SL_OK)
        return fail("mesh", &err);
    for (uint32_t k = 0; k < n; k++) {
        sl_affine xf = transform_of(&ents[k]);
        sl_object_desc od = {.mesh = cube, .transform = &xf, .color = 0x808080ffu,
                             .kind = ents[k].kind == ENT_BUILDING ? SL_KIND_BUILDING : SL_KIND_CAR,
                             .flags = SL_OBJECT_CLOSED_CONVEX | (ents[k].kind == ENT_BUILDING ? SL_OBJECT_OCCLUDER : 0) |
                                      (ents[k].kind == ENT_CAR ? SL_OBJECT_DYNAMIC : 0)};
        if (sl_scene_add_object(scene, &od, &ents[k].object, &err) != SL_OK)
            return fail(ents[k].name, &err);
    }
    /* Sightline's ids back to the engine's entities */
    uint32_t objects = sl_scene_object_count(scene);
    uint32_t *to_entity = malloc(objects * sizeof *to_entity), *ids = malloc(objects * sizeof *ids);
    uint32_t *frustum = malloc(objects * sizeof *frustum);
    if (!to_entity || !ids || !frustum)
        return fail("memory", NULL);
    for (uint32_t k = 0; k < n; k++)
        to_entity[ents[k].object] = k;

    /* hzb: occlusion culling, conservative at any resolution; vfc: the frustum alone, to compare */
    sl_culler culler, vfc;
    if (sl_culler_create("hzb", scene, "all_objects=false", NULL, &culler, &err) != SL_OK)
        return fail("hzb", &err);
    if (sl_culler_create("vfc", scene, NULL, NULL, &vfc, &err) != SL_OK)
        return fail("vfc", &err);

    double sum_vis = 0, sum_frustum = 0;
    int crates_seen = 0;
    for (int f = 0; f < frames; f++) {
        /* the player walks down the street between the first two rows, looking ahead */
        float t = (float)f / (float)frames;
        float eye[3] = {-20 + t * 280.0f, 20, 1.7f}, at[3] = {eye[0] + 10, 20 + 2 * sinf(t * 6.28f), 1.7f};
        float view[16], proj[16];
        look_at(eye, at, view);
        perspective(60, 16.0f / 9.0f, 0.1f, 2000, proj);
        sl_view v;
        if (sl_view_from_matrices(view, proj, SL_CLIP_DEPTH_GL, 1280, 720, &v, &err) != SL_OK)
            return fail("view", &err);
        /* a car drives along the street: the engine moves it and tells the culler */
        entity *car = &ents[2];
        car->pos[0] = 300.0f - t * 300.0f;
        sl_affine xf = transform_of(car);
        if (sl_scene_set_object_transform(scene, car->object, &xf, &err) != SL_OK ||
            sl_culler_scene_changed(culler, &err) != SL_OK || sl_culler_scene_changed(vfc, &err) != SL_OK)
            return fail("moving car", &err);

        uint32_t count, nf;
        if (sl_culler_cull_view(culler, &v, ids, objects, &count, &err) != SL_OK)
            return fail("cull", &err);
        if (sl_culler_cull_view(vfc, &v, frustum, objects, &nf, &err) != SL_OK)
            return fail("vfc cull", &err);
        /* checks: ascending ids, a subset of the frustum set, something seen */
        for (uint32_t k = 0, j = 0; k < count; k++) {
            if (k && ids[k] <= ids[k - 1])
                return fail("ids not ascending", NULL);
            while (j < nf && frustum[j] < ids[k])
                j++;
            if (j == nf || frustum[j] != ids[k])
                return fail("an object outside the frustum", NULL);
        }
        if (!count)
            return fail("nothing visible from the street", NULL);
        for (uint32_t k = 0; k < count; k++)
            crates_seen += ents[to_entity[ids[k]]].kind == ENT_CRATE;
        sum_vis += count;
        sum_frustum += nf;
        if (f % (frames > 4 ? frames / 4 : 1) == 0)
            printf("frame %3d: %3u of %u entities to draw (frustum: %u), first %s\n", f, count, n, nf,
                   ents[to_entity[ids[0]]].name);
    }
    printf("mean %.1f entities drawn per frame against %.1f in the frustum (%.1fx fewer); crates drawn %d times\n",
           sum_vis / frames, sum_frustum / frames, sum_frustum / (sum_vis > 0 ? sum_vis : 1), crates_seen);
    if (sum_vis >= sum_frustum)
        return fail("occlusion culling removed nothing", NULL);
    sl_culler_destroy(culler);
    sl_culler_destroy(vfc);
    sl_scene_destroy(scene);
    free(to_entity);
    free(ids);
    free(frustum);
    return 0;
}

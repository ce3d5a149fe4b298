/* The procedural city: presets, option validation and the driver that runs the stages
 * (layout -> terrain -> buildings -> ground -> props -> street network -> metadata).
 * See include/sightline/gen.h for what the scene contains and docs/city-generator.md for the
 * measured figures. */
#include "gen_city_internal.h"

#include <inttypes.h>

static const char *const preset_names[] = {"tiny", "small", "vienna", "oldtown", "oldtown-small"};
static const char *const style_names[] = {"grid", "oldtown"};

const char *sl_city_style_name(sl_city_style s)
{
    return (unsigned)s < SL_COUNTOF(style_names) ? style_names[s] : "unknown";
}

sl_status sl_city_style_from_name(const char *name, sl_city_style *out, sl_error *err)
{
    if (!name || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_city_style_from_name: NULL argument");
    for (size_t k = 0; k < SL_COUNTOF(style_names); k++)
        if (!strcmp(name, style_names[k])) {
            *out = (sl_city_style)k;
            return SL_OK;
        }
    return sl_fail(err, SL_ERROR_NOT_FOUND, "unknown city style '%s' (expected grid or oldtown)", name);
}

const char *sl_city_preset_name(sl_city_preset p)
{
    return (unsigned)p < SL_COUNTOF(preset_names) ? preset_names[p] : "unknown";
}

sl_status sl_city_preset_from_name(const char *name, sl_city_preset *out, sl_error *err)
{
    if (!name || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_city_preset_from_name: NULL argument");
    for (size_t k = 0; k < SL_COUNTOF(preset_names); k++)
        if (!strcmp(name, preset_names[k])) {
            *out = (sl_city_preset)k;
            return SL_OK;
        }
    return sl_fail(err, SL_ERROR_NOT_FOUND, "unknown city preset '%s' (expected tiny, small, vienna, oldtown or oldtown-small)", name);
}

sl_city_options sl_city_defaults(sl_city_preset p)
{
    sl_city_options o;
    memset(&o, 0, sizeof o);
    o.preset = SL_CITY_TINY;
    o.seed = 1;
    /* tiny: about a dozen cells around a river with one bridge and one avenue */
    o.extent_x = 300, o.extent_y = 260;
    o.block_size_min = 60, o.block_size_max = 80;
    o.jitter = 0.12f;
    o.street_width_min = 10, o.street_width_max = 15;
    o.avenue_width = 24, o.avenue_spacing = 250;
    o.street_removal = 0.08f;
    o.park_fraction = 0.06f, o.square_fraction = 0.04f, o.tower_fraction = 0.05f;
    o.river = true;
    o.river_width = 24, o.bank_width = 8, o.bridge_spacing = 150;
    o.height_min = 12, o.height_max = 24;
    o.tower_height_min = 40, o.tower_height_max = 70;
    o.detail = 2;
    o.cars_per_km = 20, o.trees_per_ha = 60, o.street_tree_spacing = 12, o.lamp_spacing = 30;
    o.traffic_speed = 11;
    o.terrain = false, o.relief = 20;
    o.meander_wavelength = 300, o.district = 6;
    if (p == SL_CITY_SMALL || p == SL_CITY_OLDTOWN_SMALL) {
        o.preset = SL_CITY_SMALL;
        o.extent_x = 800, o.extent_y = 750;
        o.block_size_min = 50, o.block_size_max = 70;
        o.street_width_min = 10, o.street_width_max = 16;
        o.avenue_width = 28, o.avenue_spacing = 450;
        o.park_fraction = 0.05f, o.square_fraction = 0.04f, o.tower_fraction = 0.03f;
        o.river_width = 40, o.bank_width = 14, o.bridge_spacing = 350;
        o.height_min = 12, o.height_max = 27;
        o.tower_height_min = 45, o.tower_height_max = 100;
        o.detail = 3;
        o.cars_per_km = 25, o.trees_per_ha = 80, o.lamp_spacing = 28;
        o.relief = 25;
    } else if (p == SL_CITY_VIENNA) {
        o.preset = SL_CITY_VIENNA;
        o.extent_x = 3000, o.extent_y = 2700;
        o.block_size_min = 50, o.block_size_max = 68;
        o.street_width_min = 10, o.street_width_max = 16;
        o.avenue_width = 30, o.avenue_spacing = 700;
        o.park_fraction = 0.04f, o.square_fraction = 0.03f, o.tower_fraction = 0.02f;
        o.river_width = 60, o.bank_width = 20, o.bridge_spacing = 500;
        o.height_min = 11, o.height_max = 23;
        o.tower_height_min = 50, o.tower_height_max = 120;
        o.detail = 3;
        o.cars_per_km = 25, o.trees_per_ha = 80, o.lamp_spacing = 28;
        o.relief = 40;
    }
    if (p == SL_CITY_OLDTOWN || p == SL_CITY_OLDTOWN_SMALL) {
        /* the vienna (or small) densities, heights and detail on an old-town street layout:
         * no avenues and no river (their long open views are what the style removes), curved
         * streets, a brick pattern of T-junctions per district, more squares */
        if (p == SL_CITY_OLDTOWN) {
            sl_city_options v = sl_city_defaults(SL_CITY_VIENNA);
            o = v;
        }
        o.preset = p;
        o.style = SL_CITY_STYLE_OLDTOWN;
        o.river = false;
        o.avenue_spacing = 0;
        o.jitter = 0.15f;
        o.meander = 12, o.meander_wavelength = 280, o.district = 6;
        o.street_width_min = 11, o.street_width_max = 17, o.avenue_width = 17;
        o.park_fraction = 0.04f, o.square_fraction = 0.10f, o.tower_fraction = 0.02f;
        /* no avenues or banks, so no street trees: denser lamps and cars keep the object count
         * near vienna's (sl_city_measure; test_gen_city checks within 10%) */
        o.street_tree_spacing = 0, o.lamp_spacing = 20, o.cars_per_km = 30;
        if (p == SL_CITY_OLDTOWN_SMALL) {
            /* the small grid's river and avenues take a larger share of its extent */
            o.street_width_min = 12, o.street_width_max = 18, o.avenue_width = 18;
            o.park_fraction = 0.06f, o.square_fraction = 0.12f;
            o.lamp_spacing = 16, o.cars_per_km = 35;
        }
    }
    return o;
}

static bool in_range(float v, double lo, double hi) { return isfinite(v) && v >= lo && v <= hi; }

#define CHECK_RANGE(field, lo, hi)                                                                                   \
    do {                                                                                                             \
        if (!in_range(o->field, (lo), (hi)))                                                                         \
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city option %s = %g: must be between %g and %g", #field, \
                           (double)o->field, (double)(lo), (double)(hi));                                            \
    } while (0)

#define CHECK_ZERO_OR(field, lo, hi)                                                                                 \
    do {                                                                                                             \
        if (o->field != 0 && !in_range(o->field, (lo), (hi)))                                                        \
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city option %s = %g: must be 0 (none) or between %g and %g", \
                           #field, (double)o->field, (double)(lo), (double)(hi));                                    \
    } while (0)

/* Triangles per km² at each detail level with the default densities (measured on the vienna
 * preset, rounded up by about a fifth), for the size guard below: generating more than
 * MAX_TRIANGLES would need well over 10 GB. */
static const double tris_per_km2[5] = {150e3, 200e3, 350e3, 1.3e6, 2.2e6};
#define MAX_TRIANGLES 200e6

sl_status sl_city_options_validate(const sl_city_options *o, sl_error *err)
{
    if (!o)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city options are NULL");
    if ((unsigned)o->preset >= SL_COUNTOF(preset_names))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city option preset = %d: unknown preset", (int)o->preset);
    CHECK_RANGE(extent_x, 100, 20000);
    CHECK_RANGE(extent_y, 100, 20000);
    CHECK_RANGE(block_size_min, 30, 500);
    CHECK_RANGE(block_size_max, o->block_size_min, 500);
    CHECK_RANGE(jitter, 0, 0.25);
    CHECK_RANGE(street_width_min, 4, 60);
    CHECK_RANGE(street_width_max, o->street_width_min, 60);
    CHECK_RANGE(avenue_width, o->street_width_min, 80);
    CHECK_ZERO_OR(avenue_spacing, 100, 20000);
    CHECK_RANGE(street_removal, 0, 0.5);
    if ((unsigned)o->style >= SL_COUNTOF(style_names))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city option style = %d: unknown style", (int)o->style);
    CHECK_RANGE(meander, 0, 0.3 * o->block_size_min);
    if (o->meander > 0)
        CHECK_RANGE(meander_wavelength, 100, 5000);
    if (o->style == SL_CITY_STYLE_OLDTOWN && (o->district < 2 || o->district > 64))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city option district = %u: must be between 2 and 64",
                       o->district);
    CHECK_RANGE(park_fraction, 0, 1);
    CHECK_RANGE(square_fraction, 0, 1);
    CHECK_RANGE(tower_fraction, 0, 1);
    if ((double)o->park_fraction + o->square_fraction + o->tower_fraction > 1.0 + 1e-6)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "city options park_fraction + square_fraction + tower_fraction = %g: must not exceed 1",
                       (double)o->park_fraction + o->square_fraction + o->tower_fraction);
    CHECK_RANGE(river_width, 10, 1000);
    CHECK_RANGE(bank_width, 0, 200);
    CHECK_ZERO_OR(bridge_spacing, 50, 20000);
    CHECK_RANGE(height_min, 4, 300);
    CHECK_RANGE(height_max, o->height_min, 300);
    CHECK_RANGE(tower_height_min, 4, 1000);
    CHECK_RANGE(tower_height_max, o->tower_height_min, 1000);
    if (o->detail > 4)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "city option detail = %u: must be between 0 and 4", o->detail);
    CHECK_RANGE(cars_per_km, 0, 400);
    CHECK_RANGE(traffic_speed, 0, 40);
    CHECK_RANGE(trees_per_ha, 0, 400);
    CHECK_ZERO_OR(street_tree_spacing, 4, 1000);
    CHECK_ZERO_OR(lamp_spacing, 5, 1000);
    CHECK_RANGE(relief, 0, 500);

    /* combinations: two blocks per axis at least, the river row fits, and blocks keep at least
     * 8 m of buildable depth. The layout never spaces lines closer than block_size_min, never
     * puts two avenues side by side, moves a node by at most jitter x the spacing and bends the
     * rows next to the river by at most 0.1 block_size_min; so a block loses at most half an
     * avenue and half the widest street. */
    if (o->extent_x < 2 * o->block_size_min)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "city option extent_x = %g: must be at least twice block_size_min (%g)", (double)o->extent_x,
                       (double)o->block_size_min);
    double river_span = o->river ? (double)o->river_width + 2.0 * o->bank_width + o->avenue_width : 0.0;
    if (o->extent_y - river_span < 2 * o->block_size_min)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "city option extent_y = %g: must be at least twice block_size_min (%g)%s%s", (double)o->extent_y,
                       (double)o->block_size_min, o->river ? " plus the river row of " : "",
                       o->river ? "river_width + 2 bank_width + avenue_width" : "");
    double sides = 0.5 * ((double)SL_MAX(o->street_width_max, o->avenue_width) + o->street_width_max);
    /* the meander's phase drifts by at most GC_MEANDER_DRIFT between neighbouring lines, so they
     * differ by at most 2 sin(drift/2) x meander */
    double buildable = o->block_size_min * (1.0 - 2.0 * o->jitter) - (o->river ? 0.1 * o->block_size_min : 0.0) - sides -
                       2.0 * sin(0.5 * GC_MEANDER_DRIFT) * o->meander;
    if (buildable < 8)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "city options: streets of %g and %g m leave %.1f m of block between lattice lines %g m "
                       "apart with jitter %g (need 8 m): raise block_size_min or lower the widths or the jitter",
                       (double)o->street_width_max, (double)o->avenue_width, buildable, (double)o->block_size_min,
                       (double)o->jitter);
    double km2 = (double)o->extent_x * o->extent_y * 1e-6;
    if (km2 * tris_per_km2[o->detail] > MAX_TRIANGLES)
        return sl_fail(err, SL_ERROR_LIMIT,
                       "city options: %.0f km² at detail %u would make about %.0f million triangles (limit %.0f "
                       "million): lower the extent or the detail",
                       km2, o->detail, km2 * tris_per_km2[o->detail] * 1e-6, MAX_TRIANGLES * 1e-6);
    return SL_OK;
}

bool gc_commit_mesh(gc_city *c, uint32_t *mesh_id)
{
    gc_mesh *m = &c->mesh;
    if (m->oom) {
        sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory building a mesh");
        return false;
    }
    sl_mesh_desc d = {m->pos, m->nrm, m->nv, m->idx, m->nt, NULL};
    return sl_scene_add_mesh(c->scene, &d, mesh_id, c->err) == SL_OK;
}

bool gc_commit_object(gc_city *c, uint32_t kind, uint32_t flags, uint32_t color, uint32_t *object)
{
    uint32_t mesh;
    if (!gc_commit_mesh(c, &mesh))
        return false;
    sl_object_desc d = {mesh, NULL, color, kind, flags, 0};
    return sl_scene_add_object(c->scene, &d, object, c->err) == SL_OK;
}

static sl_status set_meta_u(gc_city *c, const char *key, uint64_t v)
{
    char buf[32];
    snprintf(buf, sizeof buf, "%" PRIu64, v);
    return sl_scene_set_meta(c->scene, key, buf, c->err);
}

static sl_status metadata(gc_city *c)
{
    const sl_city_options *o = c->opt;
    char buf[128];
    sl_status st;
    snprintf(buf, sizeof buf, "%g %g %g %g", c->x0, c->y0, c->x1, c->y1);
    if ((st = sl_scene_set_meta(c->scene, "generator", "sightline city", c->err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "preset", sl_city_preset_name(o->preset), c->err)) != SL_OK ||
        (st = set_meta_u(c, "seed", o->seed)) != SL_OK ||
        (o->style != SL_CITY_STYLE_GRID &&
         (st = sl_scene_set_meta(c->scene, "city.style", sl_city_style_name(o->style), c->err)) != SL_OK) ||
        (st = sl_scene_set_meta(c->scene, "extent", buf, c->err)) != SL_OK ||
        (st = set_meta_u(c, "city.detail", o->detail)) != SL_OK ||
        (st = set_meta_u(c, "city.blocks", c->n_blocks)) != SL_OK ||
        (st = set_meta_u(c, "city.buildings", c->n_buildings)) != SL_OK ||
        (st = set_meta_u(c, "city.towers", c->n_towers)) != SL_OK ||
        (st = set_meta_u(c, "city.parks", c->n_parks)) != SL_OK ||
        (st = set_meta_u(c, "city.squares", c->n_squares)) != SL_OK ||
        (st = set_meta_u(c, "city.plazas", c->n_plazas)) != SL_OK ||
        (st = set_meta_u(c, "city.bridges", c->n_bridges)) != SL_OK ||
        (st = set_meta_u(c, "city.trees", c->n_trees)) != SL_OK ||
        (st = set_meta_u(c, "city.lamps", c->n_lamps)) != SL_OK ||
        (st = set_meta_u(c, "city.cars", c->n_cars)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "city.river", o->river ? "yes" : "no", c->err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "city.terrain", c->has_terrain ? "yes" : "no", c->err)) != SL_OK)
        return st;
    snprintf(buf, sizeof buf, "%d x %d", c->nx, c->ny);
    return sl_scene_set_meta(c->scene, "city.lattice", buf, c->err);
}

static void release(gc_city *c)
{
    const sl_allocator *a = c->alloc;
    size_t nx = (size_t)c->nx, ny = (size_t)c->ny;
    sl_free(a, c->node, (nx + 1) * (ny + 1) * sizeof(sl_dvec2));
    sl_free(a, c->hedge, nx * (ny + 1) * sizeof(gc_edge));
    sl_free(a, c->vedge, (nx + 1) * ny * sizeof(gc_edge));
    sl_free(a, c->cell, nx * ny * sizeof(gc_cell));
    sl_free(a, c->vline_avenue, nx + 1);
    sl_free(a, c->hline_avenue, ny + 1);
    sl_free(a, c->theight, (size_t)c->tnx * c->tny * sizeof(float));
    sl_array_free(a, &c->courts, sizeof(gc_court));
    gc_mesh_free(&c->mesh);
}

sl_status sl_gen_city(const sl_city_options *opt, const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_gen_city: out is NULL");
    *out = NULL;
    sl_status st = sl_city_options_validate(opt, err);
    if (st != SL_OK)
        return st;
    sl_error local;
    sl_error_clear(&local);
    gc_city c;
    memset(&c, 0, sizeof c);
    c.opt = opt;
    c.alloc = sl_alloc_or_default(alloc);
    c.err = err ? err : &local; /* the stages always have somewhere to write */
    c.x0 = -0.5 * opt->extent_x, c.x1 = 0.5 * opt->extent_x;
    c.y0 = -0.5 * opt->extent_y, c.y1 = 0.5 * opt->extent_y;
    c.river_row = -1;
    c.lamp_mesh = SL_NONE;
    for (int k = 0; k < 3; k++)
        c.tree_mesh[k] = c.car_mesh[k] = SL_NONE;
    gc_mesh_init(&c.mesh, c.alloc);
    if ((st = sl_scene_create(alloc, &c.scene, c.err)) != SL_OK)
        return st;
    if (!sl_progress_report(&opt->progress, "city: layout", 0, 0))
        st = sl_fail(c.err, SL_ERROR_CANCELLED, "city: cancelled");
    if (st == SL_OK)
        st = gc_layout(&c);
    if (st == SL_OK)
        st = gc_terrain(&c);
    if (st == SL_OK)
        st = gc_buildings(&c);
    if (st == SL_OK)
        st = gc_groundwork(&c);
    if (st == SL_OK)
        st = gc_props(&c);
    if (st == SL_OK)
        st = gc_streets(&c);
    if (st == SL_OK)
        st = metadata(&c);
    if (st == SL_OK && c.mesh.oom)
        st = sl_fail(c.err, SL_ERROR_OUT_OF_MEMORY, "city: out of memory building meshes");
    release(&c);
    if (st != SL_OK) {
        sl_scene_destroy(c.scene);
        return st;
    }
    *out = c.scene;
    return SL_OK;
}

/* dhorizon: the incremental occlusion horizon, the ΔH method.
 *
 * G. Koldaş, "Efficient Visibility Estimation for Distributed Virtual Urban Environments", PhD
 * thesis, METU 2008, §3.1.3 (also Koldaş, Işler, Lau, ISVC 2007): between two frames the horizon
 * changes little, so the cells in front of the last horizon are kept, the horizon is rebuilt from
 * them, and only the openings (azimuths where the new horizon is lower than the last one) and the
 * cells newly in the frustum are tested; the rest was hidden and stays hidden.
 *
 * That last step is only true for small motion: the thesis itself shows a building missed when the
 * viewer moves more than a building's width in one frame (its Fig. 3.10). Here it is made exact.
 * The sweep is horizon.c's front-to-back sweep; a node that fails the ordinary test may still be
 * skipped when
 *   - none of its cells was processed last frame (all of it was hidden then, or culled with a
 *     hidden ancestor),
 *   - it was inside last frame's azimuth range and far distance (else it was not looked at), and
 *   - the current horizon over its azimuths, built only from occluders nearer than the node, is
 *     above last frame's final horizon over its azimuths widened by the parallax bound, plus the
 *     parallax bound, while its lowest point is above the bottom of the current occluders.
 * Parallax bound: moving the eye by d changes the direction to any point at distance at least D by
 * at most asin(d / D), in azimuth (plan distances) and in elevation alike. A point P of the node
 * was below the old horizon at its old azimuth; so at its new azimuth its elevation is below the
 * old horizon's maximum over the widened range plus asin(d / D), hence below the current horizon:
 * hidden. This holds for any motion shorter than the node's distance, so no frame can drop a
 * visible object. The guard of the thesis stays as a policy: when the viewer moved more than
 * max_move or the view turned more than max_turn since the last frame, the frame is a full sweep
 * (the widened test would skip little anyway). parallax=false drops the bound and reproduces the
 * thesis' plain test, which may miss objects (aggressive), for comparison. */
#include "urban_internal.h"

static const char g_help[] =
    "cell=NUMBER (default 16): scene-grid cell size in metres (0.5..1000)\n"
    "bins=1024..1048576 (default 8192): azimuth bins of the horizon (rounded up to a power of two)\n"
    "max_move=NUMBER (default 4): a frame after a move longer than this (metres) is a full sweep\n"
    "max_turn=NUMBER (default 30): a frame after a turn larger than this (degrees) is a full sweep\n"
    "refresh=0..100000 (default 60): a full sweep at least every this many frames (0: only when the guard asks)\n"
    "parallax=BOOL (default true): widen the reuse test by the parallax bound (false: the thesis' test, aggressive)\n";

typedef struct dhorizon_config {
    float cell;
    uint32_t bins;
    float max_move, max_turn;
    uint32_t refresh;
    bool parallax;
} dhorizon_config;

static sl_status dhorizon_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    dhorizon_config *c = config;
    sl_status st;
    if ((st = sl_opts_float(o, "cell", 16.0f, 0.5f, 1000.0f, &c->cell, err)) != SL_OK ||
        (st = sl_opts_u32(o, "bins", 8192, 1024, 1u << 20, &c->bins, err)) != SL_OK ||
        (st = sl_opts_float(o, "max_move", 4.0f, 0.0f, 10000.0f, &c->max_move, err)) != SL_OK ||
        (st = sl_opts_float(o, "max_turn", 30.0f, 0.0f, 180.0f, &c->max_turn, err)) != SL_OK ||
        (st = sl_opts_u32(o, "refresh", 60, 0, 100000, &c->refresh, err)) != SL_OK ||
        (st = sl_opts_bool(o, "parallax", true, &c->parallax, err)) != SL_OK)
        return st;
    if (!c->parallax)
        *g = SL_AGGRESSIVE;
    return SL_OK;
}

/* Signed difference of two azimuths in (-pi, pi]. */
static double az_diff(double a, double b)
{
    double d = fmod(a - b, SL_URBAN_TWO_PI);
    if (d > M_PI)
        d -= SL_URBAN_TWO_PI;
    if (d <= -M_PI)
        d += SL_URBAN_TWO_PI;
    return d;
}

bool sl_dhorizon_prepare(sl_urban_sweep *s, const sl_urban_view *v)
{
    bool reuse = s->have_prev && !(s->refresh && s->since_full + 1 >= s->refresh);
    if (reuse) {
        const sl_urban_view *p = &s->prev_view;
        double dx = v->eye[0] - p->eye[0], dy = v->eye[1] - p->eye[1], dz = v->eye[2] - p->eye[2];
        reuse = sqrt(dx * dx + dy * dy + dz * dz) <= s->max_move && v->full_az == p->full_az;
        if (reuse && !v->full_az) {
            double turn = s->max_turn * (M_PI / 180.0);
            reuse = fabs(az_diff(v->az0, p->az0)) <= turn &&
                    fabs(az_diff(v->az0 + v->az_span, p->az0 + p->az_span)) <= turn;
        }
    }
    s->since_full = reuse ? s->since_full + 1 : 0;
    return reuse;
}

bool sl_dhorizon_skip(sl_urban_sweep *s, const sl_urban_view *v, uint32_t id, double dmin, double dmax, double a0,
                      double span, double lo)
{
    (void)id;
    const sl_urban_view *p = &s->prev_view;
    double dx = v->eye[0] - p->eye[0], dy = v->eye[1] - p->eye[1], dz = v->eye[2] - p->eye[2];
    double dh = sqrt(dx * dx + dy * dy), d3 = sqrt(dx * dx + dy * dy + dz * dz);
    if (!(dmin > d3))
        return false; /* the motion could have passed next to it: no bound */
    double da = 0, db = 0;
    if (s->parallax) {
        da = asin(dh / dmin) + 1e-9;
        db = asin(d3 / dmin) + 1e-9;
    }
    /* the node's azimuths widened by the parallax bound (true angles for the widening) */
    double ux, uy, wx, wy;
    sl_urban_paz_dir(a0, &ux, &uy);
    sl_urban_paz_dir(a0 + span, &wx, &wy);
    double t0 = atan2(uy, ux), t1 = atan2(wy, wx), tspan = t1 - t0;
    if (tspan < 0)
        tspan += SL_URBAN_TWO_PI;
    if (!(tspan + 2 * da < M_PI - 1e-6))
        return false;
    double ea0 = sl_urban_paz(cos(t0 - da), sin(t0 - da));
    double espan = sl_urban_paz_wrap(sl_urban_paz(cos(t1 + da), sin(t1 + da)) - ea0);
    /* last frame looked at it: inside its azimuth range and its far distance */
    if (!p->full_az && !(sl_urban_paz_wrap(ea0 - p->paz0) + espan <= p->paz_span))
        return false;
    if (!(dmin + dh <= p->far))
        return false;
    const sl_horizon *old = &s->hz[s->cur ^ 1], *cur = &s->hz[s->cur];
    double min_h, max_b;
    sl_horizon_range(cur, a0, span, &min_h, &max_b);
    if (!(max_b <= lo - sl_margin_height_slack(lo)) || !(min_h > -INFINITY))
        return false;
    /* every point of the node was below last frame's horizon as it stood when the sweep reached it,
     * at most dmax + dh away then: bound that horizon over the widened azimuths, then add the
     * elevation change */
    double was = sl_horizon_max(old, ea0, espan);
    double need = was == -INFINITY ? -INFINITY : tan(sl_urban_min(atan(was) + db, M_PI_2));
    if (!(min_h > need + sl_margin_height_slack(need))) {
        was = sl_horizon_max_before(old, ea0, espan, dmax + dh, 512);
        need = was == -INFINITY ? -INFINITY : tan(sl_urban_min(atan(was) + db, M_PI_2));
        if (!(min_h > need + sl_margin_height_slack(need)))
            return false;
    }
    return true;
}

static sl_status dhorizon_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state,
                                 sl_error *err)
{
    const dhorizon_config *c = config;
    sl_urban_sweep *s;
    sl_status st = sl_urban_sweep_create(scene, c->cell, c->bins, true, alloc, &s, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "dhorizon");
        return st;
    }
    s->incremental = true;
    s->parallax = c->parallax;
    s->max_move = c->max_move;
    s->max_turn = c->max_turn;
    s->refresh = c->refresh;
    *state = s;
    return SL_OK;
}

static sl_status dhorizon_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                               sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    return sl_urban_sweep_cull(state, view, out, count, stats, err);
}

const sl_cull_method sl_cull_method_dhorizon = {
    .name = "dhorizon",
    .suits = "cities with building footprints (2.5D), a walk or drive (frame-to-frame coherence)",
    .summary = "incremental occlusion horizon (the Delta-H method): reuses the last frame's horizon, retests only "
               "the openings, exact under any motion (Koldas 2008 ch. 3)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(dhorizon_config),
    .configure = dhorizon_configure,
    .create = dhorizon_create,
    .cull = dhorizon_cull,
    .scene_changed = sl_urban_horizon_scene_changed,
    .destroy = sl_urban_horizon_destroy,
    .applicable = sl_urban_applicable,
};

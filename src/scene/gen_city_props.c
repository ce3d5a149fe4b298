/* City generator, props: the small occludees. A handful of shared meshes (three trees, a street
 * lamp, three cars) instanced by transform, one object each:
 *  - street lamps along every street at lamp_spacing, alternating sides, at the kerb;
 *  - trees along avenues and quays (street_tree_spacing) and river banks, in parks and squares
 *    (trees_per_ha), a few in courtyards;
 *  - cars (DYNAMIC) parked along the kerbs and in the driving lanes, cars_per_km on average.
 * Every prop is flagged SL_OBJECT_OCCLUDER: each is a solid (a car's body and wheels are closed
 * boxes open only underneath; a lamp is closed prisms and boxes standing on
 * the ground; a tree's crown is a closed solid and its trunk tube is closed off by the ground and
 * the crown), and an occlusion method renders an occluder's own triangles two-sided, exactly what
 * the oracle draws, so a nearby car or tree may hide what stands behind it. Cars stay DYNAMIC:
 * their occluder geometry follows their current transform.
 * Every prop stands inside the free space it belongs to, with its crown or body clear of the
 * façades; positions use the bilinear parameterisation of the street quads, so they follow the
 * jittered streets. */
#include "gen_city_internal.h"

static const uint32_t tree_colors[] = {0x4E7D3AFFu, 0x5F8F45FFu, 0x3F6B35FFu, 0x6E9A4EFFu};
static const uint32_t car_colors[] = {0xC0392BFFu, 0x2C3E50FFu, 0xECF0F1FFu, 0x7F8C8DFFu, 0x16A085FFu,
                                      0xF1C40FFFu, 0x1F1F1FFFu, 0x95A5A6FFu, 0x8E44ADFFu, 0x2980B9FFu};
#define COLOR_LAMP 0x3A3D40FFu
#define COLOR_CONIFER 0x2F5530FFu

/* ---- meshes (local: base at z = 0, cars along +x) ---- */

static void ngon(sl_dvec2 *p, int n, double r, double phase)
{
    for (int k = 0; k < n; k++)
        p[k] = sl_d2(r * cos(phase + 2 * GC_PI * k / n), r * sin(phase + 2 * GC_PI * k / n));
}

static void trunk(gc_mesh *m, double r, double h)
{
    sl_dvec2 p[6];
    ngon(p, 6, r, 0);
    gc_prism(m, p, 6, 0, h, false, false);
}

static void icosahedron(gc_mesh *m, double r, double zc)
{
    const double g = 1.6180339887498949;
    static const int f[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                 {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    double v[12][3] = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                       {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    double s = r / sqrt(1 + g * g);
    for (int k = 0; k < 20; k++) {
        sl_dvec3 a = sl_d3(v[f[k][0]][0] * s, v[f[k][0]][1] * s, v[f[k][0]][2] * s + zc);
        sl_dvec3 b = sl_d3(v[f[k][1]][0] * s, v[f[k][1]][1] * s, v[f[k][1]][2] * s + zc);
        sl_dvec3 d = sl_d3(v[f[k][2]][0] * s, v[f[k][2]][1] * s, v[f[k][2]][2] * s + zc);
        sl_dvec3 ctr = sl_d3_scale(sl_d3_add(sl_d3_add(a, b), d), 1.0 / 3);
        gc_tri(m, a, b, d, sl_d3(ctr.x, ctr.y, ctr.z - zc));
    }
}

/* Cone or bicone crown: an n-gon ring of radius r at z0, apex at z1, optional lower apex. */
static void crown(gc_mesh *m, int n, double r, double zring, double ztop, double zbottom, bool cap)
{
    sl_dvec2 p[8];
    ngon(p, n, r, 0.3);
    for (int k = 0; k < n; k++) {
        sl_dvec2 a = p[k], b = p[(k + 1) % n], mid = sl_d2_lerp(a, b, 0.5);
        gc_tri(m, sl_d3_of_d2(a, zring), sl_d3_of_d2(b, zring), sl_d3(0, 0, ztop), sl_d3(mid.x, mid.y, 0.5));
        if (!cap)
            gc_tri(m, sl_d3_of_d2(b, zring), sl_d3_of_d2(a, zring), sl_d3(0, 0, zbottom), sl_d3(mid.x, mid.y, -0.5));
    }
    if (cap)
        gc_cap(m, p, n, zring, false);
}

static void car_body(gc_mesh *m, double len, double wid, double zb, double zt, double cb0, double cb1, double ct0,
                     double ct1, double ztop)
{
    double hl = 0.5 * len, hw = 0.5 * wid;
    gc_box(m, sl_d3(-hl, -hw, zb), sl_d3(hl, hw, zt), false);
    /* cabin: bottom [cb0,cb1] x +-0.95 hw at zt, top [ct0,ct1] x +-0.8 hw at ztop */
    double wb = 0.95 * hw, wt = 0.8 * hw;
    sl_dvec3 b0 = {cb0, -wb, zt}, b1 = {cb1, -wb, zt}, b2 = {cb1, wb, zt}, b3 = {cb0, wb, zt};
    sl_dvec3 t0 = {ct0, -wt, ztop}, t1 = {ct1, -wt, ztop}, t2 = {ct1, wt, ztop}, t3 = {ct0, wt, ztop};
    gc_quad(m, t0, t1, t2, t3, sl_d3(0, 0, 1));
    gc_quad(m, b1, b2, t2, t1, sl_d3(1, 0, 0.5));
    gc_quad(m, b3, b0, t0, t3, sl_d3(-1, 0, 0.5));
    gc_quad(m, b0, b1, t1, t0, sl_d3(0, -1, 0.2));
    gc_quad(m, b2, b3, t3, t2, sl_d3(0, 1, 0.2));
    double wx = hl - 0.75, wy = hw - 0.05;
    for (int sx = -1; sx <= 1; sx += 2)
        for (int sy = -1; sy <= 1; sy += 2) {
            double cx = sx * wx, cy = sy * (wy - 0.11);
            gc_box(m, sl_d3(cx - 0.32, cy - 0.11, 0), sl_d3(cx + 0.32, cy + 0.11, 0.62), false);
        }
}

static bool make_meshes(gc_city *c)
{
    const sl_city_options *o = c->opt;
    gc_mesh *m = &c->mesh;
    if (o->trees_per_ha > 0 || o->street_tree_spacing > 0) {
        gc_mesh_reset(m);
        trunk(m, 0.18, 2.6);
        icosahedron(m, 2.2, 4.4);
        if (!gc_commit_mesh(c, &c->tree_mesh[0]))
            return false;
        gc_mesh_reset(m);
        trunk(m, 0.15, 1.5);
        crown(m, 8, 1.9, 1.5, 8.5, 0, true);
        if (!gc_commit_mesh(c, &c->tree_mesh[1]))
            return false;
        gc_mesh_reset(m);
        trunk(m, 0.14, 1.8);
        crown(m, 8, 1.2, 5.5, 11.0, 1.8, false);
        if (!gc_commit_mesh(c, &c->tree_mesh[2]))
            return false;
    }
    if (o->lamp_spacing > 0) {
        gc_mesh_reset(m);
        sl_dvec2 p[6];
        ngon(p, 6, 0.08, 0);
        gc_prism(m, p, 6, 0, 5.2, true, false);
        gc_box(m, sl_d3(0.05, -0.04, 5.0), sl_d3(1.3, 0.04, 5.1), true);
        gc_box(m, sl_d3(1.0, -0.18, 4.85), sl_d3(1.5, 0.18, 5.05), true);
        if (!gc_commit_mesh(c, &c->lamp_mesh))
            return false;
    }
    if (o->cars_per_km > 0) {
        gc_mesh_reset(m);
        car_body(m, 4.0, 1.75, 0.3, 0.95, -1.7, 0.9, -1.5, 0.3, 1.5);
        if (!gc_commit_mesh(c, &c->car_mesh[0]))
            return false;
        gc_mesh_reset(m);
        car_body(m, 4.6, 1.8, 0.3, 0.9, -1.3, 1.0, -0.9, 0.4, 1.45);
        if (!gc_commit_mesh(c, &c->car_mesh[1]))
            return false;
        gc_mesh_reset(m);
        car_body(m, 5.0, 2.0, 0.35, 1.1, -2.4, 1.5, -2.4, 1.1, 2.3);
        if (!gc_commit_mesh(c, &c->car_mesh[2]))
            return false;
    }
    return true;
}

/* ---- placement ---- */

static sl_status place(gc_city *c, uint32_t mesh, uint32_t kind, uint32_t flags, uint32_t color, sl_dvec2 at, double z,
                       double yaw, double scale)
{
    double cs = cos(yaw) * scale, sn = sin(yaw) * scale;
    sl_affine t = {{(float)cs, (float)-sn, 0, (float)at.x, (float)sn, (float)cs, 0, (float)at.y, 0, 0, (float)scale, (float)z}};
    sl_object_desc d = {mesh, &t, color, kind, flags, 0};
    return sl_scene_add_object(c->scene, &d, NULL, c->err);
}

static sl_status tree(gc_city *c, sl_rng *r, sl_dvec2 at, double scale, bool street)
{
    uint32_t v = 0;
    if (!street) {
        float u = sl_rng_float(r);
        v = u < 0.6f ? 0 : u < 0.85f ? 1 : 2;
    }
    uint32_t color = v == 1 ? COLOR_CONIFER : tree_colors[sl_rng_below(r, (uint32_t)SL_COUNTOF(tree_colors))];
    double yaw = sl_rng_range(r, 0, (float)(2 * GC_PI));
    c->n_trees++;
    return place(c, c->tree_mesh[v], SL_KIND_TREE, SL_OBJECT_OCCLUDER, color, at, gc_ground(c, at.x, at.y), yaw, scale);
}

static sl_dvec2 quad_at(const sl_dvec2 q[4], double s, double f)
{
    return sl_d2_lerp(sl_d2_lerp(q[0], q[1], s), sl_d2_lerp(q[3], q[2], s), f);
}

/* A car's motion record. Parked: it never moves (its region is its box). Driving: its box centre
 * shuttles along its lane between s0 and s1 (metres along the street) at `speed`, starting `phase`
 * metres from s0 where it was placed; its region holds its box along the whole lane (the lane is
 * straight: a line of constant across-fraction in the bilinear street quad), with the ground's rise
 * between the ends, and a margin for rounding (none below a level lane, where the lowest z is exact). */
static sl_status car_motion(gc_city *c, uint32_t id, bool driving, const sl_dvec2 q[4], double len, double f,
                            sl_dvec2 at, double s0, double s1, double phase, double speed, bool on_bridge)
{
    sl_aabb b = sl_scene_object_bounds(c->scene, id);
    const double m = 0.05;
    sl_object_motion mo;
    memset(&mo, 0, sizeof mo);
    if (!driving) {
        mo.region = (sl_aabb){{b.min.x - (float)m, b.min.y - (float)m, b.min.z},
                              {b.max.x + (float)m, b.max.y + (float)m, b.max.z + (float)m}};
        return sl_scene_set_object_motion(c->scene, id, &mo, c->err);
    }
    sl_dvec2 p0 = quad_at(q, s0 / len, f), p1 = quad_at(q, s1 / len, f);
    double zat = on_bridge ? 0.15 : gc_ground(c, at.x, at.y);
    double z0 = on_bridge ? 0.15 : gc_ground(c, p0.x, p0.y), z1 = on_bridge ? 0.15 : gc_ground(c, p1.x, p1.y);
    /* the pose at p0: the placed pose moved there */
    sl_object_view ov = sl_scene_object(c->scene, id);
    sl_affine base = ov.transform;
    base.m[3] = (float)((double)base.m[3] + p0.x - at.x);
    base.m[7] = (float)((double)base.m[7] + p0.y - at.y);
    base.m[11] = (float)((double)base.m[11] + z0 - zat);
    sl_aabb mb = sl_scene_mesh(c->scene, ov.mesh).bounds;
    sl_aabb b0 = sl_aabb_transform(&mb, &base);
    double dx = p1.x - p0.x, dy = p1.y - p0.y, dz = z1 - z0;
    mo.has_path = true;
    mo.path_base = base;
    mo.from = (sl_vec3){base.m[3], base.m[7], base.m[11]};
    mo.to = (sl_vec3){(float)(base.m[3] + dx), (float)(base.m[7] + dy), (float)(base.m[11] + dz)};
    mo.speed = (float)speed;
    mo.max_speed = (float)speed;
    double L = sqrt(dx * dx + dy * dy + dz * dz);
    mo.phase = (float)SL_MIN(L * phase / fabs(s1 - s0), L * (1 - 1e-6)); /* on its way out, from s0 */
    double lo[3] = {b0.min.x, b0.min.y, b0.min.z}, hi[3] = {b0.max.x, b0.max.y, b0.max.z}, d[3] = {dx, dy, dz};
    float rl[3], rh[3];
    for (int k = 0; k < 3; k++) {
        double pad = m + 1e-5 * fmax(fabs(lo[k]), fabs(hi[k]));
        /* on a level lane every pose's box has exactly b0's lowest z (the poses differ by a turn
         * about z and a move in x, y): no margin below, so the region does not reach under the
         * buildings' bases (the bake would test it through a larger stand-in: method_adjustable.c,
         * lower_boxes) */
        rl[k] = (float)(fmin(lo[k], lo[k] + d[k]) - (k == 2 && d[k] == 0 ? 0 : pad));
        rh[k] = (float)(fmax(hi[k], hi[k] + d[k]) + pad);
    }
    mo.region = (sl_aabb){{rl[0], rl[1], rl[2]}, {rh[0], rh[1], rh[2]}};
    c->n_driving++;
    return sl_scene_set_object_motion(c->scene, id, &mo, c->err);
}

static sl_status street_props(gc_city *c, bool horizontal, int i, int j)
{
    const sl_city_options *o = c->opt;
    const gc_edge *e = horizontal ? gc_hedge(c, i, j) : gc_vedge(c, i, j);
    if (!(e->flags & GC_EDGE_STREET))
        return SL_OK;
    sl_dvec2 q[4];
    gc_edge_quad(c, horizontal, i, j, q);
    sl_dvec2 na = gc_node(c, i, j), nb = horizontal ? gc_node(c, i + 1, j) : gc_node(c, i, j + 1);
    double yaw = atan2(nb.y - na.y, nb.x - na.x);
    double w = e->width, len = 0.5 * (sl_d2_len(sl_d2_sub(q[1], q[0])) + sl_d2_len(sl_d2_sub(q[2], q[3])));
    double sw = SL_CLAMP(0.2 * w, 1.5, 5.0), carriage = w - 2 * sw;
    bool on_bridge = (e->flags & GC_EDGE_BRIDGE) != 0;
    uint32_t code = (horizontal ? 0u : 1u) << 31 | (uint32_t)i;
    sl_status st;

    if (o->lamp_spacing > 0 && len > 4) {
        sl_rng r;
        gc_rng(c, GC_RNG_LAMP, code, (uint32_t)j, &r);
        int n = (int)floor(len / o->lamp_spacing + 0.5);
        int side = (int)sl_rng_below(&r, 2);
        double f = SL_MAX(0.4, sw - 0.4) / w;
        for (int k = 0; k < n; k++, side ^= 1) {
            sl_dvec2 at = quad_at(q, (k + 0.5) / n, side ? 1 - f : f);
            /* the arm reaches over the carriageway: left of the direction from the right kerb */
            double ay = yaw + (side ? -0.5 : 0.5) * GC_PI;
            double z = on_bridge ? 0.15 : gc_ground(c, at.x, at.y);
            if ((st = place(c, c->lamp_mesh, SL_KIND_LAMP, SL_OBJECT_OCCLUDER, COLOR_LAMP, at, z, ay, 1.0)) != SL_OK)
                return st;
            c->n_lamps++;
        }
    }
    if (o->street_tree_spacing > 0 && (e->flags & GC_EDGE_AVENUE) && !on_bridge && sw >= 2.5) {
        sl_rng r;
        gc_rng(c, GC_RNG_TREE, code, (uint32_t)j, &r);
        int n = (int)floor(len / o->street_tree_spacing + 0.5);
        double f = 0.5 * sw / w;
        for (int k = 0; k < n; k++)
            for (int side = 0; side < 2; side++) {
                /* half a spacing off the lamps */
                double s = (k + (side ? 0.25 : 0.75)) / n;
                if ((st = tree(c, &r, quad_at(q, s, side ? 1 - f : f), sl_rng_range(&r, 0.7f, 0.9f), true)) != SL_OK)
                    return st;
            }
    }
    if (o->cars_per_km > 0 && len > 8 && carriage >= 3.5) {
        sl_rng r, traffic;
        gc_rng(c, GC_RNG_CAR, code, (uint32_t)j, &r);
        gc_rng(c, GC_RNG_TRAFFIC, code, (uint32_t)j, &traffic); /* its own stream: the city is the same */
        /* parking lanes (2 m) along both kerbs where the carriageway allows, driving lanes
         * between; parked cars are about twice as likely per slot as moving ones, and the slot
         * probability is scaled so that a street carries cars_per_km on average whatever its
         * lanes */
        struct lane {
            double f, weight;
            int dir; /* 1: along a->b, -1: against, 0: either */
        } lanes[4];
        int nl = 0;
        double pk = (sw + 1.0) / w;
        if (carriage >= 10 && !on_bridge) {
            lanes[nl++] = (struct lane){pk, 2.33, 1};
            lanes[nl++] = (struct lane){1 - pk, 2.33, -1};
            lanes[nl++] = (struct lane){0.5 - 1.6 / w, 1, 1};
            lanes[nl++] = (struct lane){0.5 + 1.6 / w, 1, -1};
        } else if (carriage >= 7 && !on_bridge) {
            lanes[nl++] = (struct lane){pk, 2.33, 1};
            lanes[nl++] = (struct lane){1 - pk, 2.33, -1};
            lanes[nl++] = (struct lane){0.5, 1, 0};
        } else if (carriage >= 5 && !on_bridge) {
            lanes[nl++] = (struct lane){pk, 2.33, 1};
            lanes[nl++] = (struct lane){(sw + 2.0 + 0.5 * (carriage - 2.0)) / w, 1, 0};
        } else if (carriage >= 6.5) {
            lanes[nl++] = (struct lane){0.5 - 1.6 / w, 1, 1};
            lanes[nl++] = (struct lane){0.5 + 1.6 / w, 1, -1};
        } else {
            lanes[nl++] = (struct lane){0.5, 1, 0};
        }
        double wsum = 0;
        for (int l = 0; l < nl; l++)
            wsum += lanes[l].weight;
        for (int l = 0; l < nl; l++)
            for (double s = 4.5; s <= len - 4.5; s += 7.0) {
                double p = SL_MIN(1.0, o->cars_per_km * 7.0 / 1000.0 * lanes[l].weight / wsum);
                if (!(sl_rng_float(&r) < p))
                    continue;
                uint32_t v = sl_rng_below(&r, 10) < 6 ? 1 : (sl_rng_below(&r, 3) == 0 ? 2 : 0);
                uint32_t color = car_colors[sl_rng_below(&r, (uint32_t)SL_COUNTOF(car_colors))];
                double jit = sl_rng_range(&r, -0.6f, 0.6f);
                sl_dvec2 at = quad_at(q, (s + jit) / len, lanes[l].f);
                double z = on_bridge ? 0.15 : gc_ground(c, at.x, at.y);
                int dir = lanes[l].dir ? lanes[l].dir : (sl_rng_below(&r, 2) ? 1 : -1);
                uint32_t id = sl_scene_object_count(c->scene);
                if ((st = place(c, c->car_mesh[v], SL_KIND_CAR, SL_OBJECT_DYNAMIC | SL_OBJECT_OCCLUDER, color, at, z,
                                dir > 0 ? yaw : yaw + GC_PI, 1.0)) != SL_OK)
                    return st;
                c->n_cars++;
                /* a driving lane (weight 1) when there is traffic: a path up and down the lane */
                bool driving = lanes[l].weight == 1 && o->traffic_speed > 0;
                double s_at = s + jit;
                double s0 = dir > 0 ? 3.5 : len - 3.5, s1 = dir > 0 ? len - 3.5 : 3.5;
                if ((st = car_motion(c, id, driving, q, len, lanes[l].f, at, s0, s1, fabs(s_at - s0),
                                     o->traffic_speed * sl_rng_range(&traffic, 0.75f, 1.25f), on_bridge)) != SL_OK)
                    return st;
            }
    }
    return SL_OK;
}

/* Trees on a jittered grid inside a convex quad, at least `margin` from its edges. */
static sl_status grove(gc_city *c, sl_rng *r, const sl_dvec2 q[4], double per_ha, double margin)
{
    double g = 100.0 / sqrt(per_ha);
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (int k = 0; k < 4; k++)
        x0 = fmin(x0, q[k].x), x1 = fmax(x1, q[k].x), y0 = fmin(y0, q[k].y), y1 = fmax(y1, q[k].y);
    for (double y = y0 + 0.5 * g; y < y1; y += g)
        for (double x = x0 + 0.5 * g; x < x1; x += g) {
            sl_dvec2 at = sl_d2(x + sl_rng_range(r, -0.4f, 0.4f) * g, y + sl_rng_range(r, -0.4f, 0.4f) * g);
            double scale = sl_rng_range(r, 0.8f, 1.3f);
            if (!gc_inside_convex(q, 4, at, margin))
                continue;
            sl_status st = tree(c, r, at, scale, false);
            if (st != SL_OK)
                return st;
        }
    return SL_OK;
}

sl_status gc_props(gc_city *c)
{
    const sl_city_options *o = c->opt;
    if (!make_meshes(c))
        return c->err->status;
    sl_status st;
    int nx = c->nx, ny = c->ny;
    uint64_t total = (uint64_t)ny + 1;
    for (int j = 0; j <= ny; j++) {
        for (int i = 0; i < nx; i++)
            if ((st = street_props(c, true, i, j)) != SL_OK)
                return st;
        if (j < ny)
            for (int i = 0; i <= nx; i++)
                if ((st = street_props(c, false, i, j)) != SL_OK)
                    return st;
        if (!sl_progress_report(&o->progress, "city: props", (uint64_t)j + 1, total))
            return sl_fail(c->err, SL_ERROR_CANCELLED, "city: cancelled while placing props");
    }
    for (int j = 0; j < ny; j++) {
        for (int i = 0; i < nx; i++) {
            gc_cell *cl = gc_cellp(c, i, j);
            sl_rng r;
            gc_rng(c, GC_RNG_TREE, (uint32_t)(j * nx + i), 0xFFFFFFFFu, &r);
            if (cl->type == GC_CELL_PARK && o->trees_per_ha > 0) {
                if ((st = grove(c, &r, cl->ground, o->trees_per_ha, 4.0)) != SL_OK)
                    return st;
            } else if (cl->type == GC_CELL_SQUARE && o->street_tree_spacing > 0) {
                sl_dvec2 in[4];
                if (!gc_offset_all(cl->ground, 4, 4.0, in))
                    continue;
                for (int k = 0; k < 4; k++) {
                    double len = sl_d2_len(sl_d2_sub(in[(k + 1) & 3], in[k]));
                    int n = (int)floor(len / o->street_tree_spacing);
                    for (int t = 0; t < n; t++)
                        if ((st = tree(c, &r, sl_d2_lerp(in[k], in[(k + 1) & 3], (t + 0.5) / n), 0.8, true)) != SL_OK)
                            return st;
                }
            } else if (cl->type == GC_CELL_RIVER && o->street_tree_spacing > 0 && o->bank_width >= 5) {
                sl_dvec2 lo[4], hi[4], w[4];
                if (!gc_river_quads(c, i, j, lo, hi, w))
                    continue;
                for (int b = 0; b < 2; b++) {
                    const sl_dvec2 *q = b ? hi : lo;
                    double len = 0.5 * (sl_d2_len(sl_d2_sub(q[1], q[0])) + sl_d2_len(sl_d2_sub(q[2], q[3])));
                    int n = (int)floor((len - 4) / o->street_tree_spacing);
                    for (int t = 0; t < n; t++) {
                        sl_dvec2 at = quad_at(q, (2 + (t + 0.5) * o->street_tree_spacing) / len, 0.5);
                        if ((st = tree(c, &r, at, sl_rng_range(&r, 0.75f, 0.95f), true)) != SL_OK)
                            return st;
                    }
                }
            }
        }
    }
    if (o->trees_per_ha > 0) {
        for (size_t k = 0; k < c->courts.count; k++) {
            const gc_court *ct = &SL_AT(c->courts, gc_court, k);
            sl_rng r;
            gc_rng(c, GC_RNG_TREE, ct->cell, 0xFFFFFFFEu, &r);
            if (!(sl_rng_float(&r) < 0.4f))
                continue;
            int n = 1 + (int)sl_rng_below(&r, 3);
            for (int t = 0; t < n; t++)
                for (int attempt = 0; attempt < 8; attempt++) {
                    sl_dvec2 at = quad_at(ct->q, sl_rng_float(&r), sl_rng_float(&r));
                    if (gc_inside_convex(ct->q, 4, at, 3.5)) {
                        if ((st = tree(c, &r, at, sl_rng_range(&r, 0.7f, 1.0f), true)) != SL_OK)
                            return st;
                        break;
                    }
                }
        }
    }
    return SL_OK;
}

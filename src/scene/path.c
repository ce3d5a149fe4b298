/* Camera paths: the pose container, interpolation, the walk/drive/flyover generators, random
 * viewpoints and the plain-text path file. Contract in include/sightline/path.h, file format and
 * conventions in docs/paths.md.
 *
 * Street paths are built on the centre-line graph, not on the street polygons (which need not
 * exist): a route is a random sequence of directed edges, parameterised by the distance s along
 * the centre line. On the straight part of an edge the eye stands lane_offset * width to the right
 * of the centre line. Around each node a window of +-L replaces the corner by a smooth curve
 * (window_eval), so position and heading have no kinks; the eye is kept within half the width of
 * one of the two centre lines meeting there, i.e. inside the streets' capsules. Frames are then
 * taken at equal distances along the eye's own trajectory (not along s), so the speed is exact on
 * curves too. */
#include "sightline/path.h"
#include "core/sl_core.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>

#define DEG (M_PI / 180.0)
#define MAX_LINE 4096       /* longest accepted line of a path file, in bytes */
#define MAX_WIDTH 65536u    /* largest viewport side accepted in a path file */
#define MAX_FRAMES 100000000u

struct sl_path_t {
    sl_allocator alloc;
    sl_camera intr;         /* intrinsics; position and angles are zero */
    sl_array poses;         /* sl_pose */
};

/* ---- small helpers ---- */

static float rad_from_deg(double d) { return (float)(d * DEG); }
static double deg_from_rad(float r) { return (double)r / DEG; }
static double smooth(double u) { return u <= 0 ? 0 : u >= 1 ? 1 : u * u * (3 - 2 * u); }
static bool pitch_ok(float p) { return p >= -(float)M_PI_2 && p <= (float)M_PI_2; }

/* Intrinsics only: the pose fields of a camera cleared. */
static sl_camera intrinsics_of(const sl_camera *c)
{
    sl_camera r = *c;
    r.position = (sl_vec3){0, 0, 0};
    r.yaw = r.pitch = r.roll = 0;
    return r;
}

/* ---- the container ---- */

sl_status sl_path_create(const sl_camera *intr, const sl_allocator *alloc, sl_path *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_create: out is NULL");
    *out = NULL;
    sl_camera d = sl_camera_default();
    sl_camera c = intrinsics_of(intr ? intr : &d);
    sl_status st = sl_camera_validate(&c, err);
    if (st != SL_OK)
        return st;
    alloc = sl_alloc_or_default(alloc);
    struct sl_path_t *p = sl_calloc(alloc, 1, sizeof *p);
    if (!p)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_path_create: out of memory");
    p->alloc = *alloc;
    p->intr = c;
    *out = p;
    return SL_OK;
}

void sl_path_destroy(sl_path p)
{
    if (!p)
        return;
    sl_allocator a = p->alloc;
    sl_array_free(&a, &p->poses, sizeof(sl_pose));
    sl_free(&a, p, sizeof *p);
}

static const sl_pose *poses_of(sl_path p) { return (const sl_pose *)p->poses.data; }

sl_status sl_path_append(sl_path p, const sl_pose *pose, sl_error *err)
{
    if (!p || !pose)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_append: NULL argument");
    size_t n = p->poses.count;
    if (n >= UINT32_MAX - 1)
        return sl_fail(err, SL_ERROR_LIMIT, "pose %zu: a path holds at most %u poses", n, UINT32_MAX - 2);
    if (!isfinite(pose->time) || !sl_finite3(&pose->position.x) || !isfinite(pose->yaw) || !isfinite(pose->pitch) ||
        !isfinite(pose->roll))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pose %zu: a value is not finite", n);
    if (!pitch_ok(pose->pitch))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pose %zu: pitch %g rad is outside [-pi/2, pi/2]", n, pose->pitch);
    if (n && pose->time < poses_of(p)[n - 1].time)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "pose %zu: time %g is before the previous pose's time %g", n,
                       pose->time, poses_of(p)[n - 1].time);
    if (!sl_array_push(&p->alloc, &p->poses, sizeof *pose, pose, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pose %zu: out of memory", n);
    return SL_OK;
}

uint32_t sl_path_count(sl_path p) { return p ? (uint32_t)p->poses.count : 0; }
const sl_pose *sl_path_poses(sl_path p) { return p ? poses_of(p) : NULL; }
sl_camera sl_path_intrinsics(sl_path p) { return p->intr; }

sl_status sl_path_set_intrinsics(sl_path p, const sl_camera *intr, sl_error *err)
{
    if (!p || !intr)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_set_intrinsics: NULL argument");
    sl_camera c = intrinsics_of(intr);
    sl_status st = sl_camera_validate(&c, err);
    if (st == SL_OK)
        p->intr = c;
    return st;
}

static sl_camera camera_at(const sl_path p, const sl_pose *q)
{
    sl_camera c = p->intr;
    c.position = q->position;
    c.yaw = q->yaw, c.pitch = q->pitch, c.roll = q->roll;
    return c;
}

sl_camera sl_path_camera(sl_path p, uint32_t i)
{
    if (!p || i >= p->poses.count)
        return sl_camera_default();
    return camera_at(p, &poses_of(p)[i]);
}

sl_status sl_path_sample(sl_path p, double t, sl_camera *out, sl_error *err)
{
    if (!p || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_sample: NULL argument");
    size_t n = p->poses.count;
    if (n == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_sample: the path has no poses");
    if (!isfinite(t))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_sample: time %g is not finite", t);
    const sl_pose *q = poses_of(p);
    /* i = last pose with time <= t (0 when t is before the path) */
    size_t lo = 0, hi = n;
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if ((double)q[mid].time <= t)
            lo = mid;
        else
            hi = mid;
    }
    size_t i = lo;
    if (t <= (double)q[i].time || i + 1 == n) {
        *out = camera_at(p, &q[i]); /* exact at a pose's time, clamped outside the range */
        return SL_OK;
    }
    const sl_pose *a = &q[i], *b = &q[i + 1];
    double u = (t - a->time) / ((double)b->time - a->time);
    sl_pose r;
    r.time = (float)t;
    r.position.x = (float)(a->position.x + u * ((double)b->position.x - a->position.x));
    r.position.y = (float)(a->position.y + u * ((double)b->position.y - a->position.y));
    r.position.z = (float)(a->position.z + u * ((double)b->position.z - a->position.z));
    r.yaw = (float)(a->yaw + u * remainder((double)b->yaw - a->yaw, 2 * M_PI));
    r.roll = (float)(a->roll + u * remainder((double)b->roll - a->roll, 2 * M_PI));
    r.pitch = (float)(a->pitch + u * ((double)b->pitch - a->pitch));
    r.pitch = SL_CLAMP(r.pitch, -(float)M_PI_2, (float)M_PI_2);
    *out = camera_at(p, &r);
    return SL_OK;
}

void sl_path_get_stats(sl_path p, sl_path_stats *s)
{
    memset(s, 0, sizeof *s);
    s->bounds = sl_aabb_empty();
    size_t n = p ? p->poses.count : 0;
    s->frames = (uint32_t)n;
    if (n == 0)
        return;
    const sl_pose *q = poses_of(p);
    s->duration = (double)q[n - 1].time - q[0].time;
    bool any_speed = false;
    double timed = 0;
    for (size_t i = 0; i < n; i++) {
        sl_aabb_grow(&s->bounds, q[i].position);
        if (i == 0)
            continue;
        double dx = (double)q[i].position.x - q[i - 1].position.x, dy = (double)q[i].position.y - q[i - 1].position.y,
               dz = (double)q[i].position.z - q[i - 1].position.z;
        double d = sqrt(dx * dx + dy * dy + dz * dz), dt = (double)q[i].time - q[i - 1].time;
        s->length += d;
        if (dt <= 0 && d > 0)
            s->jumps++;
        if (dt > 0) {
            timed += d;
            double v = d / dt;
            s->speed_min = any_speed ? fmin(s->speed_min, v) : v;
            s->speed_max = any_speed ? fmax(s->speed_max, v) : v;
            any_speed = true;
        }
    }
    s->speed_mean = s->duration > 0 ? timed / s->duration : 0;
}

/* ---- options ---- */

sl_path_options sl_path_options_default(sl_path_kind kind)
{
    sl_path_options o;
    memset(&o, 0, sizeof o);
    o.kind = kind;
    o.frames = 600;
    o.fps = 30.0f;
    o.speed = kind == SL_PATH_WALK ? 1.4f : kind == SL_PATH_DRIVE ? (float)(50.0 / 3.6) : 0.0f;
    o.eye_height = kind == SL_PATH_DRIVE ? 1.2f : 1.7f;
    o.altitude = 0.0f;
    o.look_down = (float)(30.0 * DEG);
    o.lane_offset = kind == SL_PATH_DRIVE ? 0.25f : 0.4f;
    o.head_bob = false;
    o.seed = 1;
    sl_camera d = sl_camera_default();
    o.intrinsics = intrinsics_of(&d);
    return o;
}

static sl_status check_common_options(const sl_path_options *o, sl_error *err)
{
    if (!(o->eye_height >= 0) || !isfinite(o->eye_height))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: eye height %g must be finite and >= 0", o->eye_height);
    if (!(o->altitude >= 0) || !isfinite(o->altitude))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: altitude %g must be finite and >= 0 (0 = auto)",
                       o->altitude);
    if (!(o->look_down >= 0 && o->look_down <= (float)M_PI_2))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: look-down angle %g rad is outside [0, pi/2]",
                       o->look_down);
    if (!(o->lane_offset >= 0 && o->lane_offset <= 0.5f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: lane offset %g is outside [0, 0.5]", o->lane_offset);
    sl_camera c = intrinsics_of(&o->intrinsics);
    return sl_camera_validate(&c, err);
}

static sl_status check_options(const sl_path_options *o, sl_error *err)
{
    if ((unsigned)o->kind > SL_PATH_FLYOVER)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: unknown kind %d", (int)o->kind);
    if (o->frames == 0 || o->frames > MAX_FRAMES)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: frames %u is outside [1, %u]", o->frames, MAX_FRAMES);
    if (!(o->fps >= 0.001f && o->fps <= 1000.0f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: fps %g is outside [0.001, 1000]", o->fps);
    /* bounded so that the march step stays far above the rounding of the route distance */
    bool loop = o->kind == SL_PATH_FLYOVER && o->speed == 0;
    if (!loop && !(o->speed >= 0.001f && o->speed <= 10000.0f))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "path options: speed %g m/s is outside [0.001, 10000]%s", o->speed,
                       o->kind == SL_PATH_FLYOVER ? " (0: one loop)" : "");
    return check_common_options(o, err);
}

/* ---- the street network ---- */

typedef struct street_net {
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t node_count, edge_count, usable;
    uint32_t *adj_start;        /* node_count + 1 offsets into adj */
    uint32_t *adj;              /* incident usable edges per node */
    double *cum_len;            /* prefix sums of usable edge lengths, edge_count + 1 */
    const sl_allocator *alloc;
} street_net;

static double edge_len(const street_net *net, uint32_t e)
{
    const sl_street_node *a = &net->nodes[net->edges[e].a], *b = &net->nodes[net->edges[e].b];
    return hypot((double)b->x - a->x, (double)b->y - a->y);
}

/* Usable: two distinct ends at least 1 cm apart and a non-negative width. */
static bool edge_usable(const street_net *net, uint32_t e)
{
    const sl_street_edge *ed = &net->edges[e];
    return ed->a != ed->b && ed->a < net->node_count && ed->b < net->node_count && ed->width >= 0 &&
           isfinite(ed->width) && edge_len(net, e) >= 0.01;
}

static void net_free(street_net *net)
{
    sl_free(net->alloc, net->adj_start, ((size_t)net->node_count + 1) * sizeof(uint32_t));
    sl_free(net->alloc, net->adj, 2 * (size_t)net->edge_count * sizeof(uint32_t) + 1);
    sl_free(net->alloc, net->cum_len, ((size_t)net->edge_count + 1) * sizeof(double));
    memset(net, 0, sizeof *net);
}

static const char no_streets_msg[] = "scene has no street network: use flyover, or a path file";

static sl_status net_build(sl_scene scene, const sl_allocator *alloc, street_net *net, sl_error *err)
{
    memset(net, 0, sizeof *net);
    net->alloc = alloc;
    sl_scene_street_graph(scene, &net->nodes, &net->node_count, &net->edges, &net->edge_count);
    if (!net->node_count || !net->edge_count)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s", no_streets_msg);
    net->adj_start = sl_calloc(alloc, (size_t)net->node_count + 1, sizeof(uint32_t));
    net->adj = sl_alloc(alloc, 2 * (size_t)net->edge_count * sizeof(uint32_t) + 1);
    net->cum_len = sl_alloc(alloc, ((size_t)net->edge_count + 1) * sizeof(double));
    if (!net->adj_start || !net->adj || !net->cum_len) {
        net_free(net);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street network: out of memory (%u edges)", net->edge_count);
    }
    /* counting sort of edge ends into a CSR adjacency */
    net->cum_len[0] = 0;
    for (uint32_t e = 0; e < net->edge_count; e++) {
        bool ok = edge_usable(net, e);
        net->cum_len[e + 1] = net->cum_len[e] + (ok ? edge_len(net, e) : 0.0);
        if (!ok)
            continue;
        net->usable++;
        net->adj_start[net->edges[e].a + 1]++;
        net->adj_start[net->edges[e].b + 1]++;
    }
    if (!net->usable) {
        uint32_t n = net->edge_count;
        net_free(net);
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s (its %u edges are all degenerate)", no_streets_msg, n);
    }
    for (uint32_t v = 0; v < net->node_count; v++)
        net->adj_start[v + 1] += net->adj_start[v];
    /* fill in edge order so that the adjacency (and so every random choice) is deterministic */
    uint32_t *fill = sl_calloc(alloc, net->node_count, sizeof(uint32_t));
    if (!fill) {
        net_free(net);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "street network: out of memory");
    }
    for (uint32_t e = 0; e < net->edge_count; e++) {
        if (!edge_usable(net, e))
            continue;
        uint32_t a = net->edges[e].a, b = net->edges[e].b;
        net->adj[net->adj_start[a] + fill[a]++] = e;
        net->adj[net->adj_start[b] + fill[b]++] = e;
    }
    sl_free(alloc, fill, (size_t)net->node_count * sizeof(uint32_t));
    return SL_OK;
}

/* A random usable edge, chosen with probability proportional to its length. */
static uint32_t net_random_edge(const street_net *net, sl_rng *rng)
{
    double total = net->cum_len[net->edge_count], x = sl_rng_double(rng) * total;
    uint32_t lo = 0, hi = net->edge_count; /* first e with cum_len[e+1] > x */
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (net->cum_len[mid + 1] > x)
            hi = mid;
        else
            lo = mid + 1;
    }
    if (lo >= net->edge_count)
        lo = net->edge_count - 1;
    while (!edge_usable(net, lo)) /* x landed on a zero-length prefix step: walk back to a real edge */
        lo = lo ? lo - 1 : net->edge_count - 1;
    return lo;
}

/* How a route passes a node. */
enum { TURN_BLEND = 0, TURN_CURVE = 1, TURN_BACK = 2 };

/* One directed edge of a route, and the turn at its end node. */
typedef struct route_seg {
    uint32_t edge, from, to;
    double ax, ay, dx, dy;      /* start node and unit direction */
    double theta;               /* heading of the direction, in [-pi, pi] */
    double s0, len;             /* start along the route, length */
    double width, off;          /* street width; lateral offset to the right */
    /* the turn at the end node: it spans route distances [-l1, +l2] around the node */
    int turn;
    double l1, l2, delta;       /* window extents; heading change */
    double mx, my, tan_len;     /* TURN_CURVE: corner point of the offset lines, tangent length */
} route_seg;

static route_seg make_seg(const street_net *net, uint32_t e, uint32_t from, double s0, double lane_offset)
{
    route_seg g;
    memset(&g, 0, sizeof g);
    const sl_street_edge *ed = &net->edges[e];
    g.edge = e;
    g.from = from;
    g.to = ed->a == from ? ed->b : ed->a;
    const sl_street_node *a = &net->nodes[g.from], *b = &net->nodes[g.to];
    g.len = edge_len(net, e);
    g.ax = a->x, g.ay = a->y;
    g.dx = ((double)b->x - a->x) / g.len, g.dy = ((double)b->y - a->y) / g.len;
    g.theta = atan2(g.dy, g.dx);
    g.s0 = s0;
    g.width = ed->width;
    g.off = lane_offset * ed->width;
    return g;
}

/* Distance from (px, py) to segment g's centre line. */
static double seg_dist(const route_seg *g, double px, double py)
{
    double t = (px - g->ax) * g->dx + (py - g->ay) * g->dy;
    t = t < 0 ? 0 : t > g->len ? g->len : t;
    return hypot(px - (g->ax + t * g->dx), py - (g->ay + t * g->dy));
}

/* Eye position on a corner curve: the quadratic Bezier from the corner point M back along a by
 * the tangent length to M forward along b. Its tangents at both ends are the edge directions,
 * so it joins the straight offset lines without a kink. */
static void curve_point(const route_seg *a, const route_seg *b, double mx, double my, double t, double u, double *px,
                        double *py)
{
    double w0 = (1 - u) * (1 - u), w2 = u * u;
    *px = mx + t * (w2 * b->dx - w0 * a->dx);
    *py = my + t * (w2 * b->dy - w0 * a->dy);
}

/* True when the corner curve with tangent length t stays within half the width (less a 2 cm
 * margin) of one of the two centre lines, checked at 129 points: at most 0.3 m apart for the
 * longest curves, where the curve bends away by less than the margin between two checks. */
static bool curve_inside(const route_seg *a, const route_seg *b, double mx, double my, double t)
{
    for (int k = 1; k < 128; k++) {
        double px, py;
        curve_point(a, b, mx, my, t, k / 128.0, &px, &py);
        if (seg_dist(a, px, py) > 0.5 * a->width - 0.02 && seg_dist(b, px, py) > 0.5 * b->width - 0.02)
            return false;
    }
    return true;
}

/* Plan the turn from segment a onto segment b at their shared node (fills a's turn fields).
 * A real turn becomes a smooth corner curve between the two offset lines, its tangent length
 * chosen closest to l_base beyond the corner point among those that keep the curve inside the
 * streets (outside corners want long curves, inside corners short ones). A near-straight
 * continuation, or a corner no curve fits, blends heading and offset along the centre lines
 * instead (inside by construction: the eye is never farther from the centre line than the
 * smaller offset). A dead end turns back around a half ellipse. Windows never reach past the
 * middle of an edge, so consecutive turns never overlap. */
static void plan_turn(route_seg *a, const route_seg *b, bool dead_end, double l_base)
{
    double half = 0.5 * fmin(a->len, b->len);
    if (dead_end) {
        a->turn = TURN_BACK;
        a->delta = M_PI; /* to the left: around the outside of a right-hand offset */
        a->l1 = a->l2 = fmin(1.5 * fmax(a->off, 1.0), 0.5 * a->len);
        return;
    }
    double d = remainder(b->theta - a->theta, 2 * M_PI), sd = sin(d), cd = cos(d);
    a->delta = d;
    a->turn = TURN_BLEND;
    a->l1 = a->l2 = fmin(l_base, half);
    if (fabs(d) < 1.0 * DEG)
        return;
    /* corner point M = node + m1*dir_a + off_a*right_a = node + m2*dir_b + off_b*right_b */
    double m1 = (b->off - a->off * cd) / sd, m2 = (b->off * cd - a->off) / sd;
    double vx = a->ax + a->len * a->dx, vy = a->ay + a->len * a->dy;
    double mx = vx + m1 * a->dx + a->off * a->dy, my = vy + m1 * a->dy - a->off * a->dx;
    double tmin = fmax(0.0, fmax(m1, -m2)) + 0.01, tmax = fmin(0.5 * a->len + m1, 0.5 * b->len - m2);
    if (!(tmax >= tmin))
        return;
    double pref = SL_CLAMP(tmin + l_base, tmin, tmax);
    /* candidates: the preferred length, then 48 more ordered by distance from it */
    double best = -1;
    if (curve_inside(a, b, mx, my, pref))
        best = pref;
    for (int k = 1; k <= 48 && best < 0; k++) {
        for (int side = -1; side <= 1 && best < 0; side += 2) {
            double t = pref + side * k * (tmax - tmin) / 48;
            if (t >= tmin && t <= tmax && curve_inside(a, b, mx, my, t))
                best = t;
        }
    }
    if (best < 0)
        return;
    a->turn = TURN_CURVE;
    a->mx = mx, a->my = my, a->tan_len = best;
    a->l1 = best - m1;
    a->l2 = best + m2;
}

/* Choose the edge after `cur` at its end node and plan the turn onto it. Turns sharper than
 * 175 degrees count as reversals: taken only when nothing else leaves the node; a dead end turns
 * back along the same edge. */
static route_seg next_seg(const street_net *net, route_seg *cur, sl_rng *rng, double lane_offset, double l_base)
{
    uint32_t v = cur->to, b = net->adj_start[v], e = net->adj_start[v + 1];
    const double max_turn = 175.0 * DEG;
    uint32_t good = 0, other = 0;
    for (uint32_t k = b; k < e; k++) {
        uint32_t ed = net->adj[k];
        if (ed == cur->edge)
            continue;
        route_seg c = make_seg(net, ed, v, 0, lane_offset);
        if (fabs(remainder(c.theta - cur->theta, 2 * M_PI)) <= max_turn)
            good++;
        else
            other++;
    }
    double end_s = cur->s0 + cur->len;
    route_seg nx = make_seg(net, cur->edge, v, end_s, lane_offset);
    if (good + other > 0) {
        bool want_good = good > 0;
        uint32_t pick = sl_rng_below(rng, want_good ? good : other);
        for (uint32_t k = b; k < e; k++) {
            uint32_t ed = net->adj[k];
            if (ed == cur->edge)
                continue;
            route_seg c = make_seg(net, ed, v, end_s, lane_offset);
            bool is_good = fabs(remainder(c.theta - cur->theta, 2 * M_PI)) <= max_turn;
            if (is_good == want_good && pick-- == 0) {
                nx = c;
                break;
            }
        }
    }
    plan_turn(cur, &nx, good + other == 0, l_base);
    return nx;
}

/* Eye (x, y) and view heading at parameter u in [0, 1] of the turn window between segments a
 * and b. The view heading eases through the turn with a smoothstep. */
static void window_eval(const route_seg *a, const route_seg *b, double u, double *yaw, double *px, double *py)
{
    double vx = a->ax + a->len * a->dx, vy = a->ay + a->len * a->dy, su = smooth(u);
    *yaw = a->theta + a->delta * su;
    if (a->turn == TURN_CURVE) {
        curve_point(a, b, a->mx, a->my, a->tan_len, u, px, py);
    } else if (a->turn == TURN_BACK) {
        /* half ellipse around the point l1 before the node, `off` across; its tip stops short
         * of the node by half the offset, so that it stays inside a street that ends flat there,
         * even cut at a slant of up to 26 degrees */
        double l = a->l1, cx = vx - l * a->dx, cy = vy - l * a->dy, c = cos(M_PI * u), s = sin(M_PI * u);
        double along = l - fmin(0.5 * a->off, 0.5 * l);
        *px = cx + a->off * c * a->dy + along * s * a->dx; /* right of (dx, dy) is (dy, -dx) */
        *py = cy - a->off * c * a->dx + along * s * a->dy;
    } else {
        /* along the centre lines through the node, offset to the right of the eased heading;
         * the offset passes through the smaller of the two at the node */
        double r = u * (a->l1 + a->l2) - a->l1, omin = fmin(a->off, b->off), off, cx, cy;
        if (r < 0) {
            off = a->off + (omin - a->off) * smooth(1 + r / a->l1);
            cx = vx + r * a->dx, cy = vy + r * a->dy;
        } else {
            off = omin + (b->off - omin) * smooth(r / a->l2);
            cx = vx + r * b->dx, cy = vy + r * b->dy;
        }
        *px = cx + off * sin(*yaw);
        *py = cy - off * cos(*yaw);
    }
}

/* View heading and eye position (x, y) at route distance s inside segment cur. */
static void route_eval(const route_seg *prev, const route_seg *cur, const route_seg *nx, double s, double *yaw,
                       double *px, double *py)
{
    double local = s - cur->s0;
    if (prev && local < prev->l2) {
        window_eval(prev, cur, (local + prev->l1) / (prev->l1 + prev->l2), yaw, px, py);
    } else if (local > cur->len - cur->l1) {
        window_eval(cur, nx, (local - (cur->len - cur->l1)) / (cur->l1 + cur->l2), yaw, px, py);
    } else {
        *yaw = cur->theta;
        *px = cur->ax + local * cur->dx + cur->off * cur->dy;
        *py = cur->ay + local * cur->dy - cur->off * cur->dx;
    }
}

/* Pose at a route point; `dist` is the distance walked (for the head bob). */
static sl_pose street_pose(sl_scene scene, const sl_path_options *o, double t, double theta, double x, double y,
                           double dist)
{
    sl_pose q;
    q.time = (float)t;
    q.position.x = (float)x;
    q.position.y = (float)y;
    q.position.z = sl_scene_ground_height(scene, q.position.x, q.position.y) + o->eye_height;
    q.yaw = (float)remainder(theta, 2 * M_PI);
    q.pitch = 0.0f;
    q.roll = 0.0f;
    if (o->head_bob && o->kind == SL_PATH_WALK) {
        double ph = 2 * M_PI * dist / 0.7; /* one cycle per 0.7 m step */
        q.position.z += (float)(0.025 * sin(ph));
        q.pitch = (float)(0.4 * DEG * sin(ph + 0.5 * M_PI));
    }
    return q;
}

static sl_status gen_street(sl_scene scene, const sl_path_options *o, sl_path path, sl_error *err)
{
    street_net net;
    sl_status st = net_build(scene, &path->alloc, &net, err);
    if (st != SL_OK)
        return st;
    sl_rng rng;
    sl_rng_seed(&rng, o->seed, 0x5717ee7 + (uint64_t)o->kind);
    double lane = o->lane_offset, l_base = o->kind == SL_PATH_DRIVE ? 12.0 : 4.0;
    double step = (double)o->speed / o->fps;
    double h = fmin(0.1, 0.25 * step); /* centre-line march step: 4+ samples per frame */

    uint32_t e0 = net_random_edge(&net, &rng);
    bool flip = sl_rng_u32(&rng) & 1;
    route_seg cur = make_seg(&net, e0, flip ? net.edges[e0].b : net.edges[e0].a, 0, lane), prev = cur;
    double s = sl_rng_double(&rng) * cur.len;
    route_seg nx = next_seg(&net, &cur, &rng, lane, l_base);
    bool has_prev = false;

    if (!sl_array_reserve(&path->alloc, &path->poses, sizeof(sl_pose), o->frames)) {
        net_free(&net);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "path: out of memory for %u poses", o->frames);
    }
    double th, x, y;
    route_eval(NULL, &cur, &nx, s, &th, &x, &y);
    sl_pose q0 = street_pose(scene, o, 0.0, th, x, y, 0.0);
    sl_array_push(&path->alloc, &path->poses, sizeof q0, &q0, 1);
    uint32_t emitted = 1;
    double walked = 0, target = step; /* distance along the eye's track so far, and of the next frame */
    double hs = h;                    /* current march step */
    while (emitted < o->frames) {
        double s_end = cur.s0 + cur.len;
        if (s >= s_end) {
            prev = cur, cur = nx, has_prev = true;
            nx = next_seg(&net, &cur, &rng, lane, l_base);
            continue;
        }
        /* never step across a segment end or a turn window's edge: every evaluation below stays
         * inside `cur`, and the eye's track is smooth within a step */
        double w_in = cur.s0 + (has_prev ? prev.l2 : 0), w_out = s_end - cur.l1;
        double lim = s < w_in ? w_in : s < w_out ? w_out : s_end;
        /* where the eye swings fast around a tight corner, halve the step until its chord is
         * under a quarter of a frame's distance */
        double s1, th1, x1, y1, d;
        for (;;) {
            s1 = fmin(s + hs, lim);
            route_eval(has_prev ? &prev : NULL, &cur, &nx, s1, &th1, &x1, &y1);
            d = hypot(x1 - x, y1 - y);
            if (d <= 0.25 * step || hs < 1e-7)
                break;
            hs *= 0.5;
        }
        hs = fmin(h, 2 * hs);
        if (walked + d < target) {
            walked += d;
            s = s1, x = x1, y = y1;
            continue;
        }
        /* the next frame lies in this step: bisect for the point whose distance from the step's
         * start is what is left to walk, emit it, and march on from there. Every frame is then
         * one step of chord sum after the last, so no two frames are ever more than a step apart
         * (a chord never exceeds the path it spans), however fast the eye swings around s */
        double need = target - walked, lo = s, hi = s1, sf = s1, thf = th1, xf = x1, yf = y1;
        for (int it = 0; it < 40 && need < d; it++) {
            sf = 0.5 * (lo + hi);
            route_eval(has_prev ? &prev : NULL, &cur, &nx, sf, &thf, &xf, &yf);
            if (hypot(xf - x, yf - y) < need)
                lo = sf;
            else
                hi = sf;
        }
        sl_pose q = street_pose(scene, o, (double)emitted / o->fps, thf, xf, yf, target);
        sl_array_push(&path->alloc, &path->poses, sizeof q, &q, 1);
        emitted++;
        walked = target;
        target = step * emitted;
        s = sf, x = xf, y = yf;
    }
    net_free(&net);
    return SL_OK;
}

/* ---- flyover ---- */

/* The scene's extent: objects, street nodes and terrain. */
static sl_aabb scene_extent(sl_scene scene)
{
    sl_aabb b = sl_scene_bounds(scene);
    const sl_street_node *nodes;
    uint32_t nn;
    sl_scene_street_graph(scene, &nodes, &nn, NULL, NULL);
    for (uint32_t i = 0; i < nn; i++)
        sl_aabb_grow(&b, (sl_vec3){nodes[i].x, nodes[i].y, sl_scene_ground_height(scene, nodes[i].x, nodes[i].y)});
    sl_terrain_view tv;
    if (sl_scene_terrain(scene, &tv)) {
        float lo = INFINITY, hi = -INFINITY;
        for (size_t i = 0; i < (size_t)tv.nx * tv.ny; i++)
            lo = fminf(lo, tv.heights[i]), hi = fmaxf(hi, tv.heights[i]);
        float x1 = tv.origin_x + (float)(tv.nx - 1) * tv.cell, y1 = tv.origin_y + (float)(tv.ny - 1) * tv.cell;
        sl_aabb_grow(&b, (sl_vec3){tv.origin_x, tv.origin_y, lo});
        sl_aabb_grow(&b, (sl_vec3){x1, y1, hi});
    }
    return b;
}

/* Flight height for a scene extent: above its lowest point by `altitude` (0: auto, following the
 * scene's size: max(min(150, w/2), 1.5 h + min(50, w/2)) for a horizontal size w and height h —
 * max(150, 1.5 h + 50) for any scene 300 m across or more, 14 m over a 10 m house 6 m high). */
static double flight_z(const sl_aabb *b, float altitude)
{
    double base = b->min.z, top = b->max.z;
    double w = fmax(b->max.x - b->min.x, b->max.y - b->min.y), half = 0.5 * fmax(w, 0.0);
    double alt = altitude > 0 ? altitude : fmax(fmin(150.0, half), 1.5 * (top - base) + fmin(50.0, half));
    return base + alt;
}

static sl_status flyover_extent(sl_scene scene, sl_aabb *b, sl_error *err)
{
    *b = scene_extent(scene);
    if (sl_aabb_is_empty(b) || !isfinite(b->min.x) || !isfinite(b->max.x))
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "scene is empty: a flyover needs objects, streets or terrain to fly over");
    return SL_OK;
}

static sl_status gen_flyover(sl_scene scene, const sl_path_options *o, sl_path path, sl_error *err)
{
    sl_aabb b;
    sl_status st = flyover_extent(scene, &b, err);
    if (st != SL_OK)
        return st;
    sl_rng rng;
    sl_rng_seed(&rng, o->seed, 0xf1f1 + (uint64_t)o->kind);
    double cx = 0.5 * ((double)b.min.x + b.max.x), cy = 0.5 * ((double)b.min.y + b.max.y);
    double ra = fmax(0.4 * ((double)b.max.x - b.min.x), 10.0), rb = fmax(0.4 * ((double)b.max.y - b.min.y), 10.0);
    double z = flight_z(&b, o->altitude);
    double phi0 = sl_rng_double(&rng) * 2 * M_PI, dir = (sl_rng_u32(&rng) & 1) ? 1.0 : -1.0;
    enum { STEPS = 4096 };
    const double dphi = 2 * M_PI / STEPS;
    /* perimeter as the same chord sum the march below walks, so a default-speed loop closes */
    double perim = 0;
    for (int i = 0; i < STEPS; i++)
        perim += hypot(ra * (cos((i + 1) * dphi) - cos(i * dphi)), rb * (sin((i + 1) * dphi) - sin(i * dphi)));
    double speed = o->speed > 0 ? o->speed : perim * o->fps / o->frames;
    double step = speed / o->fps;
    if (!sl_array_reserve(&path->alloc, &path->poses, sizeof(sl_pose), o->frames))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "path: out of memory for %u poses", o->frames);
    /* march phi in fixed steps from phi0 (the same chords whatever the frame count) and place
     * frame k where the chord sum reaches k * step, interpolating phi inside the chord */
    uint32_t emitted = 0;
    double walked = 0, target = 0, x = cx + ra * cos(phi0), y = cy + rb * sin(phi0), phi = phi0;
    for (uint64_t i = 1; emitted < o->frames; i++) {
        double phi1 = phi0 + dir * dphi * (double)i;
        double x1 = cx + ra * cos(phi1), y1 = cy + rb * sin(phi1), d = hypot(x1 - x, y1 - y);
        while (emitted < o->frames && walked + d >= target) {
            double u = d > 0 ? (target - walked) / d : 0, pf = phi + u * (phi1 - phi);
            sl_pose q;
            q.time = (float)((double)emitted / o->fps);
            q.position.x = (float)(cx + ra * cos(pf));
            q.position.y = (float)(cy + rb * sin(pf));
            q.position.z = (float)z;
            q.yaw = (float)atan2(cy - q.position.y, cx - q.position.x);
            q.pitch = -o->look_down;
            q.roll = 0.0f;
            sl_array_push(&path->alloc, &path->poses, sizeof q, &q, 1);
            emitted++;
            target = step * emitted;
        }
        walked += d;
        x = x1, y = y1, phi = phi1;
    }
    return SL_OK;
}

sl_status sl_path_generate(sl_scene scene, const sl_path_options *opt, const sl_allocator *alloc, sl_path *out,
                           sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_generate: out is NULL");
    *out = NULL;
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_generate: scene is NULL");
    sl_path_options o = opt ? *opt : sl_path_options_default(SL_PATH_WALK);
    sl_status st = check_options(&o, err);
    if (st != SL_OK)
        return st;
    sl_path p;
    if ((st = sl_path_create(&o.intrinsics, alloc, &p, err)) != SL_OK)
        return st;
    st = o.kind == SL_PATH_FLYOVER ? gen_flyover(scene, &o, p, err) : gen_street(scene, &o, p, err);
    if (st != SL_OK) {
        sl_path_destroy(p);
        return st;
    }
    *out = p;
    return SL_OK;
}

/* ---- random viewpoints ---- */

/* Parse scene metadata "q3.spawns" ("x y z;x y z;...") into an array of points. */
static sl_status parse_spawns(const char *text, const sl_allocator *a, sl_vec3 **out, size_t *count, sl_error *err)
{
    sl_array pts = {0};
    const char *p = text;
    size_t entry = 0;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')
            p++;
        if (*p == ';') {
            p++;
            continue; /* empty entry */
        }
        if (!*p)
            break;
        float v[3];
        for (int k = 0; k < 3; k++) {
            char *end;
            errno = 0;
            v[k] = strtof(p, &end);
            if (end == p || !isfinite(v[k])) {
                sl_array_free(a, &pts, sizeof(sl_vec3));
                return sl_fail(err, SL_ERROR_FORMAT, "scene metadata q3.spawns: entry %zu: coordinate %d is not a finite number",
                               entry, k + 1);
            }
            p = end;
        }
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p && *p != ';') {
            sl_array_free(a, &pts, sizeof(sl_vec3));
            return sl_fail(err, SL_ERROR_FORMAT, "scene metadata q3.spawns: entry %zu: expected ';' after 3 numbers", entry);
        }
        sl_vec3 q = {v[0], v[1], v[2]};
        if (!sl_array_push(a, &pts, sizeof q, &q, 1)) {
            sl_array_free(a, &pts, sizeof(sl_vec3));
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "scene metadata q3.spawns: out of memory");
        }
        entry++;
    }
    *out = pts.data;
    *count = pts.count;
    if (!pts.count) {
        sl_array_free(a, &pts, sizeof(sl_vec3));
        *out = NULL;
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s (q3.spawns lists no spawn point)", no_streets_msg);
    }
    return SL_OK;
}

static sl_status views_street(sl_scene scene, const sl_path_options *o, uint32_t count, sl_rng *rng, sl_path path,
                              sl_error *err)
{
    street_net net;
    sl_error local;
    sl_status st = net_build(scene, &path->alloc, &net, &local);
    if (st == SL_ERROR_UNSUPPORTED && sl_scene_meta(scene, "q3.spawns")) {
        sl_vec3 *sp;
        size_t n;
        if ((st = parse_spawns(sl_scene_meta(scene, "q3.spawns"), &path->alloc, &sp, &n, err)) != SL_OK)
            return st;
        /* spawn points are player origins; Quake III's eye is DEFAULT_VIEWHEIGHT = 26 units above */
        const char *scale_text = sl_scene_meta(scene, "q3.unit_scale");
        double unit = scale_text ? strtod(scale_text, NULL) : 1.0 / 32.0;
        if (!(unit > 0 && unit < 1e3))
            unit = 1.0 / 32.0;
        float view_height = (float)(26.0 * unit);
        for (uint32_t i = 0; i < count && st == SL_OK; i++) {
            sl_pose q = {(float)i, sp[sl_rng_below(rng, (uint32_t)SL_MIN(n, UINT32_MAX))], 0, 0, 0};
            q.position.z += view_height;
            q.yaw = (float)(sl_rng_double(rng) * 2 * M_PI - M_PI);
            st = sl_path_append(path, &q, err);
        }
        sl_free(&path->alloc, sp, n * sizeof *sp);
        return st;
    }
    if (st != SL_OK) {
        if (err)
            *err = local;
        return st;
    }
    for (uint32_t i = 0; i < count && st == SL_OK; i++) {
        uint32_t e = net_random_edge(&net, rng);
        route_seg g = make_seg(&net, e, net.edges[e].a, 0, o->lane_offset);
        /* keep half the lateral range away from the edge's ends: a dead end may be cut at a slant */
        double m = fmin(0.5 * g.off, 0.5 * g.len);
        double t = m + sl_rng_double(rng) * (g.len - 2 * m), lat = (2 * sl_rng_double(rng) - 1) * g.off;
        double x = g.ax + t * g.dx + lat * g.dy, y = g.ay + t * g.dy - lat * g.dx; /* right = (dy, -dx) */
        sl_pose q;
        q.time = (float)i;
        q.position.x = (float)x, q.position.y = (float)y;
        q.position.z = sl_scene_ground_height(scene, q.position.x, q.position.y) + o->eye_height;
        q.yaw = (float)(sl_rng_double(rng) * 2 * M_PI - M_PI);
        q.pitch = 0, q.roll = 0;
        st = sl_path_append(path, &q, err);
    }
    net_free(&net);
    return st;
}

static sl_status views_flyover(sl_scene scene, const sl_path_options *o, uint32_t count, sl_rng *rng, sl_path path,
                               sl_error *err)
{
    sl_aabb b;
    sl_status st = flyover_extent(scene, &b, err);
    if (st != SL_OK)
        return st;
    double z = flight_z(&b, o->altitude);
    for (uint32_t i = 0; i < count && st == SL_OK; i++) {
        sl_pose q;
        q.time = (float)i;
        q.position.x = (float)(b.min.x + sl_rng_double(rng) * ((double)b.max.x - b.min.x));
        q.position.y = (float)(b.min.y + sl_rng_double(rng) * ((double)b.max.y - b.min.y));
        q.position.z = (float)z;
        q.yaw = (float)(sl_rng_double(rng) * 2 * M_PI - M_PI);
        double pitch = -(double)o->look_down + (2 * sl_rng_double(rng) - 1) * 15.0 * DEG;
        q.pitch = (float)SL_CLAMP(pitch, -M_PI_2, 0.0);
        q.roll = 0;
        st = sl_path_append(path, &q, err);
    }
    return st;
}

sl_status sl_path_random_views(sl_scene scene, sl_view_kind kind, uint32_t count, uint64_t seed,
                               const sl_path_options *opt, const sl_allocator *alloc, sl_path *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_random_views: out is NULL");
    *out = NULL;
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_random_views: scene is NULL");
    if (kind != SL_VIEWS_STREET && kind != SL_VIEWS_FLYOVER)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_random_views: unknown kind %d", (int)kind);
    if (count == 0 || count > MAX_FRAMES)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_random_views: count %u is outside [1, %u]", count, MAX_FRAMES);
    sl_path_options o = opt ? *opt : sl_path_options_default(kind == SL_VIEWS_STREET ? SL_PATH_WALK : SL_PATH_FLYOVER);
    sl_status st = check_common_options(&o, err);
    if (st != SL_OK)
        return st;
    sl_path p;
    if ((st = sl_path_create(&o.intrinsics, alloc, &p, err)) != SL_OK)
        return st;
    if (!sl_array_reserve(&p->alloc, &p->poses, sizeof(sl_pose), count)) {
        sl_path_destroy(p);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "random views: out of memory for %u poses", count);
    }
    sl_rng rng;
    sl_rng_seed(&rng, seed, 0x71e3 + (uint64_t)kind);
    st = kind == SL_VIEWS_STREET ? views_street(scene, &o, count, &rng, p, err) : views_flyover(scene, &o, count, &rng, p, err);
    if (st != SL_OK) {
        sl_path_destroy(p);
        return st;
    }
    *out = p;
    return SL_OK;
}

/* ---- the text format ---- */

static const char header_line[] = "# sightline-path 1";

/* Number parsers shared by the reader and by the writer's round-trip check. */
static bool parse_float_tok(const char *s, float *out)
{
    char *end;
    errno = 0;
    float v = strtof(s, &end);
    if (end == s || *end || !isfinite(v))
        return false;
    *out = v;
    return true;
}

static bool parse_angle_tok(const char *s, float *out)
{
    char *end;
    errno = 0;
    double d = strtod(s, &end);
    if (end == s || *end || !isfinite(d))
        return false;
    float r = rad_from_deg(d);
    if (!isfinite(r))
        return false;
    *out = r;
    return true;
}

/* Shortest "%.Ng" text of v that reads back to the same bits (at most 9 digits for a float). */
static void fmt_float(char *buf, size_t size, float v)
{
    for (int prec = 6; prec <= 9; prec++) {
        float back;
        snprintf(buf, size, "%.*g", prec, (double)v);
        if (parse_float_tok(buf, &back) && memcmp(&back, &v, sizeof v) == 0)
            return;
    }
}

/* The same for an angle held in radians and written in degrees. %.9g always suffices: its
 * relative error (5e-9) is below half a float ulp (3e-8) after the exact conversions; %.17g is
 * a belt-and-braces fallback. */
static void fmt_angle(char *buf, size_t size, float rad)
{
    static const int precs[] = {6, 7, 8, 9, 17};
    for (size_t i = 0; i < SL_COUNTOF(precs); i++) {
        float back;
        snprintf(buf, size, "%.*g", precs[i], deg_from_rad(rad));
        if (parse_angle_tok(buf, &back) && memcmp(&back, &rad, sizeof rad) == 0)
            return;
    }
}

sl_status sl_path_save(sl_path p, const char *file, sl_error *err)
{
    if (!p || !file)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_save: NULL argument");
    sl_atomic_file f;
    sl_status st = sl_atomic_open(&p->alloc, file, &f, err);
    if (st != SL_OK)
        return st;
    char line[512], a[6][40];
    int n = snprintf(line, sizeof line, "%s\n", header_line);
    sl_atomic_write(&f, line, (size_t)n);
    const sl_camera *c = &p->intr;
    fmt_angle(a[0], sizeof a[0], c->fov_y);
    fmt_float(a[1], sizeof a[1], c->near_plane);
    fmt_float(a[2], sizeof a[2], c->far_plane);
    fmt_float(a[3], sizeof a[3], c->ortho_height);
    n = snprintf(line, sizeof line, "camera fov=%s near=%s far=%s width=%u height=%u projection=%s ortho_height=%s\n",
                 a[0], a[1], a[2], c->width, c->height, c->projection == SL_ORTHOGRAPHIC ? "orthographic" : "perspective",
                 a[3]);
    sl_atomic_write(&f, line, (size_t)n);
    static const char columns[] = "# t x y z yaw pitch roll   (seconds, metres, degrees)\n";
    sl_atomic_write(&f, columns, sizeof columns - 1);
    const sl_pose *q = poses_of(p);
    for (size_t i = 0; i < p->poses.count; i++) {
        char t[40];
        fmt_float(t, sizeof t, q[i].time);
        fmt_float(a[0], sizeof a[0], q[i].position.x);
        fmt_float(a[1], sizeof a[1], q[i].position.y);
        fmt_float(a[2], sizeof a[2], q[i].position.z);
        fmt_angle(a[3], sizeof a[3], q[i].yaw);
        fmt_angle(a[4], sizeof a[4], q[i].pitch);
        fmt_angle(a[5], sizeof a[5], q[i].roll);
        n = snprintf(line, sizeof line, "%s %s %s %s %s %s %s\n", t, a[0], a[1], a[2], a[3], a[4], a[5]);
        sl_atomic_write(&f, line, (size_t)n);
    }
    return sl_atomic_commit(&f, err);
}

/* Split a NUL-terminated line into at most max whitespace-separated tokens (in place). Returns
 * the number of tokens found, which may exceed max (the extra ones are not stored). */
static int split_tokens(char *s, char **tok, int max)
{
    int n = 0;
    for (;;) {
        while (*s == ' ' || *s == '\t')
            *s++ = 0;
        if (!*s)
            return n;
        if (n < max)
            tok[n] = s;
        n++;
        while (*s && *s != ' ' && *s != '\t')
            s++;
    }
}

typedef struct parse_ctx {
    const char *name;
    size_t line;
    sl_error *err;
} parse_ctx;

static sl_status perr(const parse_ctx *c, sl_status st, const char *fmt, ...) SL_PRINTF(3, 4);
static sl_status perr(const parse_ctx *c, sl_status st, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sl_fail(c->err, st, "%s:%zu: %s", c->name, c->line, msg);
}

static sl_status parse_camera(const parse_ctx *c, char *text, sl_camera *cam)
{
    static const char *keys[] = {"fov", "near", "far", "width", "height", "projection", "ortho_height"};
    char *tok[16];
    int n = split_tokens(text, tok, 16);
    if (n > 16)
        return perr(c, SL_ERROR_FORMAT, "camera line has %d settings, at most %zu are known", n - 1, SL_COUNTOF(keys));
    bool seen[SL_COUNTOF(keys)] = {false};
    *cam = sl_camera_default();
    for (int i = 1; i < n; i++) {
        char *eq = strchr(tok[i], '=');
        if (!eq)
            return perr(c, SL_ERROR_FORMAT, "camera setting '%.40s' is not key=value", tok[i]);
        *eq = 0;
        const char *v = eq + 1;
        size_t k = 0;
        while (k < SL_COUNTOF(keys) && strcmp(keys[k], tok[i]))
            k++;
        if (k == SL_COUNTOF(keys))
            return perr(c, SL_ERROR_FORMAT, "unknown camera setting '%.40s' (known: fov near far width height projection "
                        "ortho_height)", tok[i]);
        if (seen[k])
            return perr(c, SL_ERROR_FORMAT, "camera setting '%s' given twice", keys[k]);
        seen[k] = true;
        bool ok = true;
        switch (k) {
        case 0: ok = parse_angle_tok(v, &cam->fov_y); break;
        case 1: ok = parse_float_tok(v, &cam->near_plane); break;
        case 2: ok = parse_float_tok(v, &cam->far_plane); break;
        case 3:
        case 4: {
            char *end;
            errno = 0;
            unsigned long u = strtoul(v, &end, 10);
            ok = v[0] >= '0' && v[0] <= '9' && !*end && !errno && u >= 1 && u <= MAX_WIDTH;
            if (ok)
                *(k == 3 ? &cam->width : &cam->height) = (uint32_t)u;
            else
                return perr(c, SL_ERROR_FORMAT, "camera %s '%.40s' is not an integer in [1, %u]", keys[k], v, MAX_WIDTH);
            break;
        }
        case 5:
            if (!strcmp(v, "perspective"))
                cam->projection = SL_PERSPECTIVE;
            else if (!strcmp(v, "orthographic"))
                cam->projection = SL_ORTHOGRAPHIC;
            else
                return perr(c, SL_ERROR_FORMAT, "camera projection '%.40s' is neither perspective nor orthographic", v);
            break;
        default: ok = parse_float_tok(v, &cam->ortho_height); break;
        }
        if (!ok)
            return perr(c, SL_ERROR_FORMAT, "camera %s '%.40s' is not a finite number", keys[k], v);
    }
    sl_error e;
    if (sl_camera_validate(cam, &e) != SL_OK)
        return perr(c, SL_ERROR_FORMAT, "%s", e.message);
    return SL_OK;
}

static sl_status parse_pose(const parse_ctx *c, char *text, const sl_pose *last, sl_pose *q)
{
    static const char *fields[] = {"t", "x", "y", "z", "yaw", "pitch", "roll"};
    char *tok[7];
    int n = split_tokens(text, tok, 7);
    if (n != 7)
        return perr(c, SL_ERROR_FORMAT, "expected 7 fields (t x y z yaw pitch roll), found %d", n);
    float v[7];
    for (int k = 0; k < 7; k++) {
        bool ok = k < 4 ? parse_float_tok(tok[k], &v[k]) : parse_angle_tok(tok[k], &v[k]);
        if (!ok)
            return perr(c, SL_ERROR_FORMAT, "field %d (%s) '%.40s' is not a finite number", k + 1, fields[k], tok[k]);
    }
    *q = (sl_pose){v[0], {v[1], v[2], v[3]}, v[4], v[5], v[6]};
    if (!pitch_ok(q->pitch))
        return perr(c, SL_ERROR_FORMAT, "pitch %s degrees is outside [-90, 90]", tok[5]);
    if (last && q->time < last->time)
        return perr(c, SL_ERROR_FORMAT, "time %s is before the previous pose's time %.9g", tok[0], (double)last->time);
    return SL_OK;
}

sl_status sl_path_parse(const void *data, size_t size, const char *name, const sl_allocator *alloc, sl_path *out,
                        sl_error *err)
{
    if (!out || (size && !data))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_parse: NULL argument");
    *out = NULL;
    parse_ctx c = {name ? name : "<memory>", 1, err};
    if (size == 0)
        return perr(&c, SL_ERROR_FORMAT, "empty file (expected '%s')", header_line);
    sl_path p;
    sl_status st = sl_path_create(NULL, alloc, &p, err);
    if (st != SL_OK)
        return st;
    const char *d = data;
    size_t pos = 0;
    bool camera_seen = false;
    char buf[MAX_LINE + 1];
    for (c.line = 1; pos < size && st == SL_OK; c.line++) {
        const char *nl = memchr(d + pos, '\n', size - pos);
        size_t len = nl ? (size_t)(nl - (d + pos)) : size - pos;
        const char *s = d + pos;
        pos += len + (nl ? 1 : 0);
        if (len && s[len - 1] == '\r')
            len--; /* CRLF line endings are accepted */
        if (len > MAX_LINE) {
            st = perr(&c, SL_ERROR_FORMAT, "line is longer than %d bytes", MAX_LINE);
            break;
        }
        memcpy(buf, s, len);
        buf[len] = 0;
        if (strlen(buf) != len) {
            st = perr(&c, SL_ERROR_FORMAT, "NUL byte in line");
            break;
        }
        if (strchr(buf, '\r')) {
            st = perr(&c, SL_ERROR_FORMAT, "stray carriage return (only \\n or \\r\\n line ends are allowed)");
            break;
        }
        while (len && (buf[len - 1] == ' ' || buf[len - 1] == '\t'))
            buf[--len] = 0;
        if (c.line == 1) {
            if (!strcmp(buf, header_line))
                continue;
            if (!strncmp(buf, "# sightline-path ", 17))
                st = perr(&c, SL_ERROR_UNSUPPORTED,
                          "path format version '%.20s' is not supported (this build reads 1; a file of a newer "
                          "version needs the newer Sightline that wrote it)",
                          buf + 17);
            else
                st = perr(&c, SL_ERROR_FORMAT, "not a sightline path file (the first line must be '%s')", header_line);
            break;
        }
        char *t = buf;
        while (*t == ' ' || *t == '\t')
            t++;
        if (!*t || *t == '#')
            continue;
        if (!strncmp(t, "camera", 6) && (t[6] == 0 || t[6] == ' ' || t[6] == '\t')) {
            if (p->poses.count)
                st = perr(&c, SL_ERROR_FORMAT, "the camera line must come before the poses");
            else if (camera_seen)
                st = perr(&c, SL_ERROR_FORMAT, "second camera line");
            else {
                sl_camera cam;
                camera_seen = true;
                if ((st = parse_camera(&c, t, &cam)) == SL_OK)
                    p->intr = intrinsics_of(&cam);
            }
            continue;
        }
        sl_pose q;
        size_t n = p->poses.count;
        if ((st = parse_pose(&c, t, n ? &poses_of(p)[n - 1] : NULL, &q)) != SL_OK)
            break;
        sl_error e;
        if ((st = sl_path_append(p, &q, &e)) != SL_OK)
            st = perr(&c, st, "%s", e.message);
    }
    if (st != SL_OK) {
        sl_path_destroy(p);
        return st;
    }
    *out = p;
    return SL_OK;
}

sl_status sl_path_load(const char *file, const sl_allocator *alloc, sl_path *out, sl_error *err)
{
    if (!file || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_path_load: NULL argument");
    *out = NULL;
    const sl_allocator *a = sl_alloc_or_default(alloc);
    uint8_t *data;
    size_t size;
    sl_status st = sl_file_read_all(a, file, &data, &size, err);
    if (st != SL_OK)
        return st;
    st = sl_path_parse(data, size, file, a, out, err);
    sl_free(a, data, size ? size : 1);
    return st;
}

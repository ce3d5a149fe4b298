/* instant: Instant Visibility — a point method run on occluders shrunk by eps, in a visibility
 * thread beside the renderer, its set valid for every viewpoint within eps of where it was computed.
 *
 * P. Wonka, "Occlusion Culling for Real-Time Rendering of Urban Environments", PhD thesis, TU Wien
 * 2001, chapter 6 (P. Wonka, M. Wimmer, F. Sillion, "Instant Visibility", Eurographics 2001):
 * §6.2 PVS_eps(P), the objects visible from any Q with |P - Q| < eps, is what any point method
 * computes on occluders shrunk by eps (Theorem 3 of §7.2); §6.3 Lemma 1, the validity a result
 * needs, t_eps = 2 t_vis - t_frame, eps = t_eps v_max; §6.3.5 the fallbacks when visibility is late
 * (stall: hold the observer until the new set arrives; incomplete visibility: keep the old set);
 * §6.4.1 the orthographic cull map gives the full 360° panorama, so no turn rate is limited.
 *
 * The shrunk occluders are stored with the scene (sl_scene_occluder_level*, baked by
 * sl_shrink_occluder_levels in src/region with GEOS): the run time needs no GEOS. Per level this
 * culler keeps a proxy scene — every object as a box with its exact bounds (two vertices, no
 * triangles) and the level's footprints — and a culler of the base method (cullmap, horizon or
 * dhorizon: the 2.5D methods, which read only object boxes and footprints) on it. hzb (general
 * scenes) is not supported: it would need 3D occluders shrunk ahead of time, which are not stored.
 *
 * One visibility update from eye P with level eps, for displayed views whose near corners reach at
 * most r from their eye: the base method culls the six faces of a cube around P (90° each, together
 * every direction), with a near plane n = (eps + r) / sqrt(3) (grown slightly), so that its near
 * guard — the footprints it does not use because the eye is inside or next to them, and the façades
 * nearer than it — is at least eps + r: whatever a displayed eye within eps of P has inside its
 * own near region (a wall its near plane cuts open), or stands inside (a building seen from within
 * hides nothing), is never used as an occluder. Every object meeting the cube [P - n, P + n], which
 * no face sees beyond its near plane, is added. The union, ascending, is the update's set.
 *
 * Each displayed frame (the cull call): the newest update that has arrived is the current set;
 * it is valid when the displayed eye lies within its eps of its P and the view's near corners
 * reach no farther than its r. The output is the current set less the objects outside the
 * displayed frustum (the same box test as vfc), ascending. When the set is not valid:
 *  - late=stall (default): the frame waits for the update in flight; if that one is not valid
 *    either, a set is computed at the displayed eye in the caller's thread. The output is always
 *    valid (the culler's guarantee is conservative); the wait counts as a stall;
 *  - late=continue: the old set is kept and the frame is counted at risk (aggressive: misses are
 *    possible at those frames only).
 * An update starts on a frame boundary when none is in flight: from the displayed eye, with the
 * level eps = (2 t_vis - t_frame) v_max rounded up to the next stored level (or eps=E fixed).
 *
 * Moving objects (thesis §8.5; docs/motion.md): a set is displayed for up to W = eps / vmax after
 * the boxes it was computed from were read (the observer leaves the eps-neighbourhood no sooner at
 * vmax), so when the scene has DYNAMIC objects a set also holds only for W after it was posted.
 * Each update reads the current box of every DYNAMIC object in the caller's thread when it is
 * posted, grows it by max_speed * W (its motion record, sl_scene_set_object_motion; the box stays
 * inside the record's region, so the grown box is clipped to it) and tests that box: a moving
 * object visible at some displayed frame has a point visible then from a displayed eye within eps,
 * and that point lies in the grown box, which the shrunk occluders hide from P only if they hide it
 * from that eye. A DYNAMIC object without a record (or whose box has left its region) is in every
 * set. Footprints of DYNAMIC objects (a moving occluder) are not used: the levels were shrunk for
 * static occluders. sl_culler_scene_changed rebuilds the levels only when a static object moved;
 * moving DYNAMIC objects keep the sets (they hold by the bound above).
 *
 * The clock: clock=simulated (default) uses a fixed frame time and visibility time, so an update
 * posted at frame time T arrives at the first frame at or after T + t_vis whatever the real
 * threads do (the caller waits for the thread if it is behind: a simulation wait, not a stall), and
 * the output is byte-identical from run to run and with thread=false; clock=measured uses wall time
 * (frame time: between cull calls; visibility time: the largest of the last 8 updates), for the
 * bench. thread=false runs each update in the caller's thread when it is posted. */
#include "culler_internal.h"

#include "core/frustum_classify.h"
#include "scene/scene_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>

static const char g_help[] =
    "base=cullmap|horizon|dhorizon (default cullmap): the point method run on the shrunk occluders\n"
    "cell=NUMBER (default 0: the base method's): its scene-grid cell size in metres (0 or 0.5..1000)\n"
    "eps=NUMBER (default 0: adaptive): fixed eps in metres (the smallest stored level at least this); 0: "
    "(2 t_vis - t_frame) vmax rounded up to a stored level\n"
    "vmax=NUMBER (default 30): the observer's maximum speed in m/s (0.01..10000)\n"
    "late=stall|continue (default stall): a late result stalls the frame (always correct) or keeps the old set "
    "(frames at risk counted; aggressive)\n"
    "thread=BOOL (default true): compute updates in a visibility thread (false: in the caller's thread)\n"
    "clock=simulated|measured (default simulated): fixed frame and visibility times (byte-identical results) or "
    "wall time\n"
    "t_frame=NUMBER (default 16): simulated frame time in ms (0.1..10000)\n"
    "t_vis=NUMBER (default 32): simulated visibility time in ms (0.1..100000)\n";

enum { BASE_CULLMAP, BASE_HORIZON, BASE_DHORIZON };
static const char *const g_bases[] = {"cullmap", "horizon", "dhorizon"};
enum { LATE_STALL, LATE_CONTINUE };
static const char *const g_late[] = {"stall", "continue"};
enum { CLOCK_SIMULATED, CLOCK_MEASURED };
static const char *const g_clocks[] = {"simulated", "measured"};

typedef struct instant_config {
    uint32_t base, late, clock;
    float cell, eps, vmax, t_frame, t_vis;
    bool thread;
} instant_config;

static sl_status instant_configure(sl_opts *o, void *config, sl_cull_guarantee *g, sl_error *err)
{
    instant_config *c = config;
    sl_status st;
    if ((st = sl_opts_enum(o, "base", g_bases, 3, BASE_CULLMAP, &c->base, err)) != SL_OK ||
        (st = sl_opts_float(o, "cell", 0.0f, 0.0f, 1000.0f, &c->cell, err)) != SL_OK ||
        (st = sl_opts_float(o, "eps", 0.0f, 0.0f, 10000.0f, &c->eps, err)) != SL_OK ||
        (st = sl_opts_float(o, "vmax", 30.0f, 0.01f, 10000.0f, &c->vmax, err)) != SL_OK ||
        (st = sl_opts_enum(o, "late", g_late, 2, LATE_STALL, &c->late, err)) != SL_OK ||
        (st = sl_opts_bool(o, "thread", true, &c->thread, err)) != SL_OK ||
        (st = sl_opts_enum(o, "clock", g_clocks, 2, CLOCK_SIMULATED, &c->clock, err)) != SL_OK ||
        (st = sl_opts_float(o, "t_frame", 16.0f, 0.1f, 10000.0f, &c->t_frame, err)) != SL_OK ||
        (st = sl_opts_float(o, "t_vis", 32.0f, 0.1f, 100000.0f, &c->t_vis, err)) != SL_OK)
        return st;
    if (c->cell != 0 && c->cell < 0.5f)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "instant: cell=%g: expected 0 (the base method's) or 0.5..1000",
                       (double)c->cell);
    if (c->late == LATE_CONTINUE)
        *g = SL_AGGRESSIVE;
    return SL_OK;
}

/* One level: eps, the proxy scene with its footprints, the base culler on it. */
typedef struct instant_level {
    float eps, eps_z;
    sl_scene proxy;
    sl_culler base;
} instant_level;

/* An update: where, with which level, for which near reach; its set. */
typedef struct instant_set {
    double p[3];
    double t_post;              /* ms of the frame clock when its boxes were read */
    float eps, eps_z;
    double reach;               /* the near reach it allows (displayed views' near_corner_dist) */
    uint32_t level;
    uint32_t *ids;
    uint32_t count;
    double ms;                  /* wall time it took */
    bool valid;                 /* holds a set */
} instant_set;

typedef struct instant_state {
    sl_allocator alloc;
    instant_config cfg;
    sl_scene scene;
    uint32_t n;                 /* objects */
    uint32_t level_count;       /* stored levels (0: the scene's own footprints as one level, eps 0) */
    instant_level *levels;
    uint32_t fixed_level;       /* the level of eps=E, or of the simulated clock's adaptive eps */
    bool all_levels;            /* adaptive with the measured clock: any level may be chosen */
    /* the worker's buffers (used by one thread at a time: the worker, or the caller with thread=0
     * or while no update is in flight) */
    uint32_t *face_ids, *stamp, *scratch;
    uint32_t stamp_frame;
    /* moving objects: ids, motion bounds, the boxes read at posting (grown), the proxy's unit box */
    uint32_t dyn_n;
    uint32_t *dyn;              /* ascending ids of the DYNAMIC objects */
    float *dyn_speed;           /* max_speed, or INFINITY: no record (always in the set) */
    sl_aabb *dyn_region;
    sl_aabb *dyn_box;           /* the update's grown boxes (the job's; written while nothing is in flight) */
    uint8_t *dyn_always;        /* per dynamic object: in every set this update */
    sl_aabb *static_box;        /* the static objects' boxes the levels were built from */
    /* the sets: the current one (displayed) and the one being computed */
    instant_set cur, job;
    bool in_flight;             /* job posted and not yet adopted */
    double job_ready_t;         /* simulated: when it arrives (ms of the frame clock) */
    /* the thread */
    bool have_thread;
    pthread_t th;
    pthread_mutex_t mu;
    pthread_cond_t cv_job, cv_done;
    bool posted, done, quit;
    bool job_async;             /* the update in flight runs in the thread */
    sl_status job_status;
    sl_error job_err;
    /* the clock */
    uint64_t frame;
    double t;                   /* ms: simulated frame time, or wall time of this frame */
    double t_prev;              /* measured: the previous frame's wall time */
    double frame_ms;            /* measured: the last frame interval */
    double vis_hist[8];         /* measured: the last updates' times */
    uint32_t vis_hist_n;
    sl_instant_stats st;
} instant_state;

/* ---- moving objects ----------------------------------------------------------------------------- */

/* The display window of a set in ms: W = eps / vmax (0 with eps 0: a set holds at its own frame). */
static double window_ms(const instant_state *s, float eps) { return 1e3 * (double)eps / (double)s->cfg.vmax; }

/* Read the motion records of the DYNAMIC objects (at creation and after scene_changed). */
static void read_motion(instant_state *s)
{
    for (uint32_t k = 0; k < s->dyn_n; k++) {
        sl_object_motion m;
        if (sl_scene_object_motion(s->scene, s->dyn[k], &m)) {
            s->dyn_speed[k] = m.max_speed;
            s->dyn_region[k] = m.region;
        } else {
            s->dyn_speed[k] = INFINITY;
        }
    }
}

/* The job's grown boxes, from the scene's boxes now (caller's thread, nothing in flight): each
 * box grown by max_speed * W plus a rounding margin, clipped to its region; an object without a
 * record or outside its region is marked always-in. */
static void read_moving(instant_state *s, double w_ms)
{
    const sl_aabb *b = sl_scene_object_bounds_array(s->scene);
    for (uint32_t k = 0; k < s->dyn_n; k++) {
        const sl_aabb *o = &b[s->dyn[k]], *r = &s->dyn_region[k];
        bool inside = isfinite(s->dyn_speed[k]) && !sl_aabb_is_empty(o) && o->min.x >= r->min.x &&
                      o->min.y >= r->min.y && o->min.z >= r->min.z && o->max.x <= r->max.x && o->max.y <= r->max.y &&
                      o->max.z <= r->max.z;
        s->dyn_always[k] = !inside;
        if (!inside)
            continue;
        double g = (double)s->dyn_speed[k] * w_ms * 1e-3;
        const float *lo = &o->min.x, *hi = &o->max.x, *rl = &r->min.x, *rh = &r->max.x;
        float out[6];
        for (int a = 0; a < 3; a++) {
            /* the margin covers the float rounding of a pose turned half about its box centre */
            double m = 1e-3 + 1e-6 * fmax(fabs((double)lo[a]), fabs((double)hi[a]));
            out[a] = (float)fmax((double)lo[a] - g - m, (double)rl[a] - m);
            out[3 + a] = (float)fmin((double)hi[a] + g + m, (double)rh[a] + m);
        }
        s->dyn_box[k] = (sl_aabb){{out[0], out[1], out[2]}, {out[3], out[4], out[5]}};
    }
}

/* Move the level's proxy boxes of the moving objects to the job's grown boxes (worker's thread:
 * the proxy is the worker's while an update is in flight). A proxy box is a unit box mesh under
 * a scale-and-translate transform; the box is widened by a few ulps so that the transformed mesh
 * box contains the grown box whatever the rounding. */
static sl_status place_moving(instant_state *s, const instant_level *L, sl_error *err)
{
    for (uint32_t k = 0; k < s->dyn_n; k++) {
        sl_aabb b = s->dyn_box[k];
        if (s->dyn_always[k]) /* tested by the flag, not the box: anywhere is fine */
            b = (sl_aabb){{0, 0, 0}, {0, 0, 0}};
        const float *lo = &b.min.x, *hi = &b.max.x;
        sl_affine t = {{0}};
        for (int a = 0; a < 3; a++) {
            float l = nextafterf(nextafterf(lo[a], -INFINITY), -INFINITY);
            float h = nextafterf(nextafterf(hi[a], INFINITY), INFINITY);
            t.m[a * 4 + a] = h - l;
            t.m[a * 4 + 3] = l;
        }
        sl_status st = sl_scene_set_object_transform(L->proxy, s->dyn[k], &t, err);
        if (st != SL_OK)
            return st;
    }
    return s->dyn_n ? sl_culler_scene_changed(L->base, err) : SL_OK;
}

/* ---- one update ------------------------------------------------------------------------------- */

/* The cube face views around p: forward along +x, -x, +y, -y, +z, -z. */
static sl_status face_view(const double p[3], int face, double near, double far, sl_view *out, sl_error *err)
{
    static const float fwd[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    static const float upv[6][3] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 1, 0}, {0, 1, 0}};
    const float *f = fwd[face], *u = upv[face];
    float r[3] = {f[1] * u[2] - f[2] * u[1], f[2] * u[0] - f[0] * u[2], f[0] * u[1] - f[1] * u[0]};
    /* rows of the world -> eye rotation: right, up, -forward (column-major storage) */
    float v[16] = {0};
    const float *rows[3] = {r, u, f};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            v[j * 4 + i] = i == 2 ? -rows[i][j] : rows[i][j];
    for (int i = 0; i < 3; i++) {
        double d = 0;
        for (int j = 0; j < 3; j++)
            d += (double)v[j * 4 + i] * p[j];
        v[12 + i] = (float)-d;
    }
    v[15] = 1;
    float pr[16] = {0};
    pr[0] = 1, pr[5] = 1; /* 90° both ways */
    pr[10] = (float)((far + near) / (near - far));
    pr[11] = -1;
    pr[14] = (float)(2 * far * near / (near - far));
    return sl_view_from_matrices(v, pr, SL_CLIP_DEPTH_GL, 256, 256, out, err);
}

/* The near plane of the cube faces whose near guard is at least g. The 2.5D methods do not use
 * the footprints whose box is within their near guard of the eye, nor façades nearer than it in
 * plan; their guard is near / c * SL_MARGIN_NEAR_FACTOR + 1e-3 with c the smallest cosine between
 * the forward axis and the frustum's far corners (sl_urban_view_make), 1/sqrt(3) for a 90° square
 * face (the float corners may give a c a few ulps either side: the factor 1.001 covers it). */
static double near_for_guard(double g)
{
    return fmax(g / sqrt(3.0) * 1.001, 1e-3);
}

static sl_status compute_set(instant_state *s, instant_set *set, sl_error *err)
{
    double t0 = sl_now();
    const instant_level *L = &s->levels[set->level];
    if (++s->stamp_frame == 0) {
        memset(s->stamp, 0, (size_t)(s->n ? s->n : 1) * sizeof(uint32_t));
        s->stamp_frame = 1;
    }
    const uint32_t fr = s->stamp_frame;
    if (s->dyn_n) {
        /* first, so that the far plane below reaches the grown boxes too */
        sl_status st = place_moving(s, L, err);
        if (st != SL_OK) {
            sl_error_prefix(err, "instant: moving objects");
            return st;
        }
    }
    const double g = (double)set->eps + set->reach;
    /* the near plane whose near guard (near / cos of the corner angle, 1/sqrt(3) here) is >= g */
    const double near = near_for_guard(g);
    sl_aabb wb = sl_scene_bounds(L->proxy);
    double far2 = 0;
    const double lo[3] = {wb.min.x, wb.min.y, wb.min.z}, hi[3] = {wb.max.x, wb.max.y, wb.max.z};
    for (int a = 0; a < 3; a++) {
        double d = fmax(fabs(lo[a] - set->p[a]), fabs(hi[a] - set->p[a]));
        far2 += isfinite(d) ? d * d : 0;
    }
    const double far = fmax(sqrt(far2) * 1.01 + 1.0, 4.0 * near);
    uint32_t count = 0;
    for (uint32_t k = 0; k < s->dyn_n; k++)
        if (s->dyn_always[k]) {
            s->stamp[s->dyn[k]] = fr;
            set->ids[count++] = s->dyn[k];
        }
    if (s->n) {
        for (int face = 0; face < 6; face++) {
            sl_view fv;
            sl_status st = face_view(set->p, face, near, far, &fv, err);
            uint32_t k = 0;
            if (st == SL_OK)
                st = sl_culler_cull_view(L->base, &fv, s->face_ids, s->n, &k, err);
            if (st != SL_OK) {
                sl_error_prefix(err, "instant: face %d", face);
                return st;
            }
            for (uint32_t i = 0; i < k; i++) {
                uint32_t o = s->face_ids[i];
                if (s->stamp[o] != fr) {
                    s->stamp[o] = fr;
                    set->ids[count++] = o;
                }
            }
        }
        /* what no face sees beyond its near plane: every object meeting the cube of half-side
         * near around p (grown by the float rounding of the boxes) */
        const sl_aabb *b = sl_scene_object_bounds_array(L->proxy); /* the scene's boxes; the worker never
                                                                       reads the scene itself */
        const double h = near * (1 + 1e-5) + 1e-4;
        for (uint32_t o = 0; o < s->n; o++) {
            if (s->stamp[o] == fr)
                continue;
            if (b[o].min.x <= set->p[0] + h && b[o].max.x >= set->p[0] - h && b[o].min.y <= set->p[1] + h &&
                b[o].max.y >= set->p[1] - h && b[o].min.z <= set->p[2] + h && b[o].max.z >= set->p[2] - h) {
                s->stamp[o] = fr;
                set->ids[count++] = o;
            }
        }
        sl_cull_sort_ids(set->ids, count, s->scratch);
    }
    set->count = count;
    set->valid = true;
    set->ms = sl_cull_ms(t0, sl_now());
    return SL_OK;
}

/* ---- the thread ------------------------------------------------------------------------------- */

static void *worker(void *arg)
{
    instant_state *s = arg;
    pthread_mutex_lock(&s->mu);
    for (;;) {
        while (!s->quit && !(s->posted && !s->done))
            pthread_cond_wait(&s->cv_job, &s->mu);
        if (s->quit)
            break;
        pthread_mutex_unlock(&s->mu);
        sl_error e;
        sl_status st = compute_set(s, &s->job, &e);
        pthread_mutex_lock(&s->mu);
        s->job_status = st;
        if (st != SL_OK)
            s->job_err = e;
        s->done = true;
        pthread_cond_broadcast(&s->cv_done);
    }
    pthread_mutex_unlock(&s->mu);
    return NULL;
}

/* The thread's flags, under its mutex (the thread reads them on any wake-up). */
static void set_flags(instant_state *s, bool posted, bool done)
{
    if (s->have_thread)
        pthread_mutex_lock(&s->mu);
    s->posted = posted;
    s->done = done;
    if (s->have_thread)
        pthread_mutex_unlock(&s->mu);
}

/* Post an update (s->job filled but for its ids); thread=false computes it now. */
static sl_status post(instant_state *s, sl_error *err)
{
    s->in_flight = true;
    s->st.updates++;
    s->job_async = s->have_thread;
    if (!s->have_thread) {
        set_flags(s, false, true);
        s->job_status = compute_set(s, &s->job, err);
        return s->job_status;
    }
    pthread_mutex_lock(&s->mu);
    s->posted = true;
    s->done = false;
    pthread_cond_signal(&s->cv_job);
    pthread_mutex_unlock(&s->mu);
    return SL_OK;
}

static bool job_done(instant_state *s)
{
    if (!s->have_thread)
        return true;
    pthread_mutex_lock(&s->mu);
    bool d = s->done;
    pthread_mutex_unlock(&s->mu);
    return d;
}

static void wait_job(instant_state *s)
{
    if (!s->have_thread)
        return;
    pthread_mutex_lock(&s->mu);
    while (s->posted && !s->done)
        pthread_cond_wait(&s->cv_done, &s->mu);
    pthread_mutex_unlock(&s->mu);
}

/* The update in flight (finished) becomes the current set. */
static sl_status adopt(instant_state *s, sl_error *err)
{
    wait_job(s);
    s->in_flight = false;
    set_flags(s, false, true);
    if (s->job_status != SL_OK) {
        if (err && s->job_async)
            *err = s->job_err;
        return s->job_status;
    }
    uint32_t *ids = s->cur.ids;
    s->cur = s->job;
    s->job.ids = ids;
    s->job.valid = false;
    s->st.vis_ms_last = s->cur.ms;
    s->st.vis_ms_total += s->cur.ms;
    s->st.set_size_last = s->cur.count;
    s->st.set_size_total += s->cur.count;
    s->st.adopted++;
    s->st.eps_last = s->cur.eps;
    if (s->vis_hist_n < 8)
        s->vis_hist[s->vis_hist_n++] = s->cur.ms;
    else {
        memmove(s->vis_hist, s->vis_hist + 1, 7 * sizeof(double));
        s->vis_hist[7] = s->cur.ms;
    }
    return SL_OK;
}

/* ---- levels ----------------------------------------------------------------------------------- */

/* The level for an update now: eps=E fixed, else (2 t_vis - t_frame) vmax rounded up. */
static uint32_t choose_level(instant_state *s)
{
    if (!s->all_levels)
        return s->fixed_level;
    double tv = 0, tf = s->frame_ms > 0 ? s->frame_ms : s->cfg.t_frame;
    for (uint32_t i = 0; i < s->vis_hist_n; i++)
        tv = fmax(tv, s->vis_hist[i]);
    if (s->vis_hist_n == 0)
        tv = s->cfg.t_vis;
    tv = ceil(tv / tf - 1e-9) * tf; /* updates start and arrive on frame boundaries */
    double need = (2 * tv - tf) * s->cfg.vmax * 1e-3;
    for (uint32_t l = 0; l < s->level_count; l++)
        if (s->levels[l].eps >= need)
            return l;
    s->st.eps_short++;
    return s->level_count - 1;
}

static void free_levels(instant_state *s)
{
    /* without stored levels there is still level 0: the scene's own footprints */
    for (uint32_t l = 0; s->levels && l < (s->level_count ? s->level_count : 1); l++) {
        sl_culler_destroy(s->levels[l].base);
        sl_scene_destroy(s->levels[l].proxy);
        s->levels[l].base = NULL;
        s->levels[l].proxy = NULL;
    }
}

/* The proxy scene of level l (boxes and the level's footprints) and its base culler. */
static sl_status build_level(instant_state *s, uint32_t l, sl_error *err)
{
    instant_level *L = &s->levels[l];
    sl_status st = sl_scene_create(&s->alloc, &L->proxy, err);
    /* moving objects: a unit box placed by a transform at each update (place_moving) */
    uint32_t unit = 0;
    if (st == SL_OK && s->dyn_n) {
        static const float up[6] = {0, 0, 0, 1, 1, 1};
        sl_mesh_desc md = {.positions = up, .vertex_count = 2};
        st = sl_scene_add_mesh(L->proxy, &md, &unit, err);
    }
    for (uint32_t o = 0; o < s->n && st == SL_OK; o++) {
        sl_object_view ov = sl_scene_object(s->scene, o);
        uint32_t mesh = unit;
        if (!(ov.flags & SL_OBJECT_DYNAMIC)) {
            sl_aabb b = sl_scene_object_bounds(s->scene, o);
            float pos[6] = {b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z};
            bool empty = !(b.min.x <= b.max.x && b.min.y <= b.max.y && b.min.z <= b.max.z);
            sl_mesh_desc md = {.positions = pos, .vertex_count = empty ? 0 : 2};
            st = sl_scene_add_mesh(L->proxy, &md, &mesh, err);
        }
        if (st == SL_OK) {
            sl_object_desc od = {.mesh = mesh, .kind = ov.kind,
                                 .flags = ov.flags & (SL_OBJECT_SEE_THROUGH | SL_OBJECT_DYNAMIC)};
            st = sl_scene_add_object(L->proxy, &od, NULL, err);
        }
    }
    uint32_t nf = s->level_count ? sl_scene_occluder_level(s->scene, l).footprint_count : sl_scene_footprint_count(s->scene);
    for (uint32_t f = 0; f < nf && st == SL_OK; f++) {
        sl_footprint_view v = s->level_count ? sl_scene_occluder_level_footprint(s->scene, l, f)
                                             : sl_scene_footprint(s->scene, f);
        if (v.object < s->n && (sl_scene_object(s->scene, v.object).flags & SL_OBJECT_DYNAMIC))
            continue; /* a moving occluder: not shrunk for its motion, so not used */
        sl_footprint_desc d = {.xy = v.xy, .vertex_count = v.vertex_count, .base_z = v.base_z, .roof_z = v.roof_z,
                               .object = v.object};
        st = sl_scene_add_footprint(L->proxy, &d, NULL, err);
    }
    if (st == SL_OK) {
        char opts[64] = "";
        if (s->cfg.cell > 0)
            snprintf(opts, sizeof opts, "cell=%g", (double)s->cfg.cell);
        st = sl_culler_create(g_bases[s->cfg.base], L->proxy, opts, &s->alloc, &L->base, err);
    }
    if (st != SL_OK)
        sl_error_prefix(err, "instant: level %u", l);
    return st;
}

static sl_status build_levels(instant_state *s, sl_error *err)
{
    for (uint32_t l = 0; l < (s->level_count ? s->level_count : 1); l++) {
        if (!s->all_levels && l != s->fixed_level)
            continue;
        sl_status st = build_level(s, l, err);
        if (st != SL_OK)
            return st;
    }
    return SL_OK;
}

/* ---- the culler ------------------------------------------------------------------------------- */

static void instant_destroy(void *state)
{
    instant_state *s = state;
    if (!s)
        return;
    if (s->have_thread) {
        pthread_mutex_lock(&s->mu);
        s->quit = true;
        pthread_cond_broadcast(&s->cv_job);
        pthread_mutex_unlock(&s->mu);
        pthread_join(s->th, NULL);
        pthread_mutex_destroy(&s->mu);
        pthread_cond_destroy(&s->cv_job);
        pthread_cond_destroy(&s->cv_done);
    }
    free_levels(s);
    const sl_allocator *a = &s->alloc;
    size_t n = s->n ? s->n : 1;
    sl_free(a, s->levels, (size_t)(s->level_count ? s->level_count : 1) * sizeof(instant_level));
    sl_free(a, s->face_ids, n * sizeof(uint32_t));
    sl_free(a, s->stamp, n * sizeof(uint32_t));
    sl_free(a, s->scratch, n * sizeof(uint32_t));
    sl_free(a, s->cur.ids, n * sizeof(uint32_t));
    sl_free(a, s->job.ids, n * sizeof(uint32_t));
    size_t dn = s->dyn_n ? s->dyn_n : 1;
    sl_free(a, s->dyn, dn * sizeof(uint32_t));
    sl_free(a, s->dyn_speed, dn * sizeof(float));
    sl_free(a, s->dyn_region, dn * sizeof(sl_aabb));
    sl_free(a, s->dyn_box, dn * sizeof(sl_aabb));
    sl_free(a, s->dyn_always, dn);
    sl_free(a, s->static_box, n * sizeof(sl_aabb));
    sl_free(a, s, sizeof *s);
}

static sl_status instant_create(sl_scene scene, const void *config, const sl_allocator *alloc, void **state,
                                sl_error *err)
{
    instant_state *s = sl_calloc(alloc, 1, sizeof *s);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "instant: out of memory");
    s->alloc = *alloc;
    s->cfg = *(const instant_config *)config;
    s->scene = scene;
    s->n = sl_scene_object_count(scene);
    s->level_count = sl_scene_occluder_level_count(scene);
    size_t n = s->n ? s->n : 1;
    s->levels = sl_calloc(alloc, s->level_count ? s->level_count : 1, sizeof(instant_level));
    s->face_ids = sl_alloc(alloc, n * sizeof(uint32_t));
    s->stamp = sl_calloc(alloc, n, sizeof(uint32_t));
    s->scratch = sl_alloc(alloc, n * sizeof(uint32_t));
    s->cur.ids = sl_alloc(alloc, n * sizeof(uint32_t));
    s->job.ids = sl_alloc(alloc, n * sizeof(uint32_t));
    for (uint32_t o = 0; o < s->n; o++)
        s->dyn_n += (sl_scene_object(scene, o).flags & SL_OBJECT_DYNAMIC) != 0;
    size_t dn = s->dyn_n ? s->dyn_n : 1;
    s->dyn = sl_alloc(alloc, dn * sizeof(uint32_t));
    s->dyn_speed = sl_alloc(alloc, dn * sizeof(float));
    s->dyn_region = sl_calloc(alloc, dn, sizeof(sl_aabb));
    s->dyn_box = sl_calloc(alloc, dn, sizeof(sl_aabb));
    s->dyn_always = sl_calloc(alloc, dn, 1);
    s->static_box = sl_alloc(alloc, n * sizeof(sl_aabb));
    if (!s->levels || !s->face_ids || !s->stamp || !s->scratch || !s->cur.ids || !s->job.ids || !s->dyn ||
        !s->dyn_speed || !s->dyn_region || !s->dyn_box || !s->dyn_always || !s->static_box) {
        uint32_t nobj = s->n;
        instant_destroy(s);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "instant: out of memory for %u objects", nobj);
    }
    for (uint32_t o = 0, k = 0; o < s->n; o++)
        if (sl_scene_object(scene, o).flags & SL_OBJECT_DYNAMIC)
            s->dyn[k++] = o;
    read_motion(s);
    memcpy(s->static_box, sl_scene_object_bounds_array(scene), (size_t)s->n * sizeof(sl_aabb));
    if (s->level_count == 0) {
        /* no stored levels: the scene's own footprints, valid at the eye itself only (every moving
         * frame waits for a new set); bake levels with `sightline occluders --instant-levels` */
        s->levels[0].eps = 0;
        s->fixed_level = 0;
    } else {
        for (uint32_t l = 0; l < s->level_count; l++)
        {
            s->levels[l].eps = sl_scene_occluder_level(scene, l).eps;
            s->levels[l].eps_z = sl_scene_occluder_level(scene, l).eps_z;
        }
        if (s->cfg.eps > 0) {
            uint32_t l = 0;
            while (l < s->level_count && s->levels[l].eps < s->cfg.eps)
                l++;
            if (l == s->level_count) {
                char list[256] = "";
                size_t k = 0;
                for (uint32_t i = 0; i < s->level_count && k + 16 < sizeof list; i++)
                    k += (size_t)snprintf(list + k, sizeof list - k, "%s%g", i ? "," : "", (double)s->levels[i].eps);
                double want = s->cfg.eps;
                instant_destroy(s);
                return sl_fail(err, SL_ERROR_NOT_FOUND, "instant: eps=%g: no stored occluder level is that large "
                               "(the scene's levels: %s)", want, list);
            }
            s->fixed_level = l;
        } else if (s->cfg.clock == CLOCK_SIMULATED) {
            s->all_levels = true;
            s->fixed_level = choose_level(s); /* the simulated times never change */
            s->st.eps_short = 0;
            s->all_levels = false;
        } else {
            s->all_levels = true;
        }
    }
    sl_status st = build_levels(s, err);
    if (st != SL_OK) {
        instant_destroy(s);
        return st;
    }
    if (s->cfg.thread) {
        if (pthread_mutex_init(&s->mu, NULL) != 0) {
            instant_destroy(s);
            return sl_fail(err, SL_ERROR_INTERNAL, "instant: cannot make a mutex");
        }
        if (pthread_cond_init(&s->cv_job, NULL) != 0 || pthread_cond_init(&s->cv_done, NULL) != 0 ||
            pthread_create(&s->th, NULL, worker, s) != 0) {
            pthread_mutex_destroy(&s->mu);
            instant_destroy(s);
            return sl_fail(err, SL_ERROR_INTERNAL, "instant: cannot start the visibility thread");
        }
        s->have_thread = true;
    }
    *state = s;
    return SL_OK;
}

static sl_status instant_scene_changed(void *state, sl_error *err)
{
    instant_state *s = state;
    read_motion(s); /* the records may have changed: the next update reads them */
    /* moving objects keep the sets (they hold for W by the motion bound); a static object that
     * moved invalidates them and the levels */
    const sl_aabb *now = sl_scene_object_bounds_array(s->scene);
    const sl_object_rec *objs = sl_scene_objects(s->scene);
    bool static_moved = false;
    for (uint32_t o = 0; o < s->n && !static_moved; o++)
        static_moved = !(objs[o].flags & SL_OBJECT_DYNAMIC) && memcmp(&now[o], &s->static_box[o], sizeof now[o]) != 0;
    if (!static_moved)
        return SL_OK;
    if (s->in_flight)
        wait_job(s);
    s->in_flight = false;
    set_flags(s, false, true);
    s->cur.valid = s->job.valid = false; /* the sets were computed for the old boxes */
    memcpy(s->static_box, now, (size_t)s->n * sizeof(sl_aabb));
    free_levels(s);
    return build_levels(s, err);
}

static bool set_holds(const instant_state *s, const instant_set *c, const sl_view *v)
{
    if (!c->valid || v->near_corner_dist > c->reach)
        return false;
    if (s->dyn_n && s->t - c->t_post > window_ms(s, c->eps) + 1e-9)
        return false; /* moving objects may have gone beyond the grown boxes */
    double dx = v->eye.x - c->p[0], dy = v->eye.y - c->p[1], dz = v->eye.z - c->p[2];
    return dx * dx + dy * dy <= (double)c->eps * c->eps && fabs(dz) <= c->eps_z;
}

static void fill_job(instant_state *s, const sl_view *v)
{
    s->job.p[0] = v->eye.x, s->job.p[1] = v->eye.y, s->job.p[2] = v->eye.z;
    s->job.level = choose_level(s);
    s->job.eps = s->levels[s->job.level].eps;
    s->job.eps_z = s->levels[s->job.level].eps_z;
    s->job.reach = v->near_corner_dist;
    s->job.valid = false;
    s->job.t_post = s->t;
    if (s->dyn_n)
        read_moving(s, window_ms(s, s->job.eps));
}

/* A set at the displayed eye, now, in the caller's thread (nothing in flight). */
static sl_status compute_now(instant_state *s, const sl_view *v, sl_error *err)
{
    fill_job(s, v);
    s->st.updates++;
    s->in_flight = true;
    set_flags(s, false, true); /* the thread is idle: nothing is in flight */
    s->job_async = false;
    s->job_status = compute_set(s, &s->job, err);
    return adopt(s, err);
}

static sl_status instant_cull(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                              sl_cull_stats *stats, sl_error *err)
{
    (void)capacity;
    instant_state *s = state;
    const sl_aabb *boxes = sl_scene_object_bounds_array(s->scene);
    double w0 = sl_now();
    double wait_ms = 0, vis_ms = 0;
    bool stalled = false;
    sl_status st = SL_OK;
    /* the frame clock */
    if (s->cfg.clock == CLOCK_SIMULATED) {
        s->t = s->frame ? s->t + s->cfg.t_frame : 0;
    } else {
        s->t = w0 * 1e3;
        s->frame_ms = s->frame ? s->t - s->t_prev : 0;
        s->t_prev = s->t;
    }
    s->frame++;
    s->st.frames++;
    if (view->projection != SL_PERSPECTIVE) {
        /* an orthographic view has no eye point to see from: the frustum set */
        uint32_t k = 0;
        float slack[6];
        sl_frustum_slacks(view->frustum.planes, slack);
        for (uint32_t o = 0; o < s->n; o++)
            if (sl_frustum_classify_box(view->frustum.planes, slack, &boxes[o], 0x3F, false, NULL) >= 0)
                out[k++] = o;
        stats->objects_tested = s->n;
        *count = k;
        return SL_OK;
    }
    /* an update that has arrived becomes the current set */
    if (s->in_flight) {
        bool arrived = s->cfg.clock == CLOCK_SIMULATED ? s->t >= s->job_ready_t - 1e-9 : job_done(s);
        if (arrived) {
            double t0 = sl_now();
            st = adopt(s, err); /* simulated: may wait for a thread that is behind the simulation */
            s->st.sim_wait_ms += s->cfg.clock == CLOCK_SIMULATED ? sl_cull_ms(t0, sl_now()) : 0;
        }
    }
    if (st == SL_OK && !s->cur.valid) { /* the first frame (or after scene_changed) */
        if (s->in_flight) {
            st = adopt(s, err);
        }
        if (st == SL_OK && !set_holds(s, &s->cur, view)) {
            double t0 = sl_now();
            st = compute_now(s, view, err);
            vis_ms += sl_cull_ms(t0, sl_now());
        }
        s->st.startups++;
    } else if (st == SL_OK && !set_holds(s, &s->cur, view)) {
        if (s->cfg.late == LATE_STALL) {
            /* hold the observer: wait for the update in flight, then, if it does not hold either,
             * compute one here */
            stalled = true;
            double t0 = sl_now();
            if (s->in_flight) {
                if (s->cfg.clock == CLOCK_SIMULATED && s->t < s->job_ready_t) {
                    s->st.stall_ms += s->job_ready_t - s->t;
                    s->t = s->job_ready_t;
                }
                st = adopt(s, err);
            }
            if (st == SL_OK && !set_holds(s, &s->cur, view)) {
                /* the frame is held while the set is computed: its clock moves first, so that the
                 * set's time is the displayed frame's */
                if (s->cfg.clock == CLOCK_SIMULATED) {
                    s->st.stall_ms += s->cfg.t_vis;
                    s->t += s->cfg.t_vis;
                }
                double t1 = sl_now();
                st = compute_now(s, view, err);
                vis_ms += sl_cull_ms(t1, sl_now());
            }
            wait_ms = sl_cull_ms(t0, sl_now());
            if (s->cfg.clock == CLOCK_MEASURED)
                s->st.stall_ms += wait_ms;
            s->st.stalls++;
        } else {
            s->st.frames_at_risk++;
        }
    }
    if (st != SL_OK)
        return st;
    /* the next update starts on this frame boundary */
    if (!s->in_flight) {
        fill_job(s, view);
        s->job_ready_t = s->t + s->cfg.t_vis;
        if ((st = post(s, err)) != SL_OK)
            return st;
    }
    /* the displayed frame: the current set within the displayed frustum */
    double t2 = sl_now();
    float slack[6];
    sl_frustum_slacks(view->frustum.planes, slack);
    uint32_t k = 0;
    for (uint32_t i = 0; i < s->cur.count; i++) {
        uint32_t o = s->cur.ids[i];
        if (sl_frustum_classify_box(view->frustum.planes, slack, &boxes[o], 0x3F, false, NULL) >= 0)
            out[k++] = o;
    }
    *count = k;
    s->st.at_risk_now = !set_holds(s, &s->cur, view);
    s->st.stalled_now = stalled;
    s->st.eps_displayed = s->cur.eps;
    s->st.clock_ms = s->t;
    stats->objects_tested = s->cur.count;
    stats->query_stalls = stalled ? 1 : 0;
    stats->query_wait_ms = stalled ? wait_ms : 0;
    sl_cull_phase(stats, "stall", stalled ? wait_ms : 0);
    sl_cull_phase(stats, "vis-sync", vis_ms);
    sl_cull_phase(stats, "display", sl_cull_ms(t2, sl_now()));
    return SL_OK;
}

sl_status sl_instant_get_stats(sl_culler c, sl_instant_stats *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_instant_get_stats: NULL argument");
    memset(out, 0, sizeof *out);
    extern const sl_cull_method sl_cull_method_instant;
    instant_state *s = sl_culler_state_of(c, &sl_cull_method_instant);
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_instant_get_stats: not an instant culler");
    *out = s->st;
    out->levels = s->level_count;
    return SL_OK;
}

/* Culls more than the frustum where there are footprints (without stored levels too: on the
 * scene's own footprints, eps 0, each moving frame computed in place). */
static bool instant_applicable(sl_scene scene, const void *config, char *why, size_t why_size)
{
    (void)config;
    if (sl_scene_footprint_count(scene))
        return true;
    snprintf(why, why_size, "the scene has no building footprints (the 2.5D occluders its base methods shrink)");
    return false;
}

const sl_cull_method sl_cull_method_instant = {
    .name = "instant",
    .suits = "cities with building footprints and shrunk occluder levels (sightline occluders --instant-levels); "
             "walkthroughs and drives at a bounded speed",
    .summary = "Instant Visibility: a 2.5D point method on occluders shrunk by eps in a visibility thread, its 360° set "
               "valid within eps of where it was computed (Wonka 2001 ch. 6)",
    .options_help = g_help,
    .guarantee = SL_CONSERVATIVE,
    .config_size = sizeof(instant_config),
    .configure = instant_configure,
    .create = instant_create,
    .cull = instant_cull,
    .scene_changed = instant_scene_changed,
    .destroy = instant_destroy,
    .applicable = instant_applicable,
};

/* The inside of the culler interface: the table every method fills in, and the option reader
 * every method uses.
 *
 * Adding a method: write src/cull/<name>.c defining `const sl_cull_method sl_cull_method_<name>`
 * and add one line X(<name>) to SL_CULL_METHODS in src/cull/registry.c. The wrapper (culler.c)
 * does the rest: it parses the options, calls configure, rejects keys configure did not read,
 * validates views and capacities, times each frame, fills the visible counts, checks that the
 * output is strictly ascending and in range, and keeps the effective option string.
 *
 * Life of a culler: configure(opts) -> create(scene, config) -> { cull(camera) | scene_changed() }*
 * -> destroy(state). cull gets a validated sl_view (view.h) with a finite far plane (the wrapper bounds
 * an infinite one by the scene's box, sl_view_bound_far) that the method's depth format resolves;
 * a method reads only the view (off-axis and orthographic views included: take the near
 * rectangle, the per-axis focal lengths and the frustum from it, never a field of view). configure must read every option it understands (an option it does not read
 * is an error) and may not touch the scene; create does the heavy work (BVH, buffers) and
 * allocates everything cull will need, through the allocator it is given.
 */
#ifndef SL_CULL_INTERNAL_H
#define SL_CULL_INTERNAL_H

#include "sightline/cull.h"
#include "core/sl_core.h"
#include "core/opts.h" /* sl_opts: the option reader every method uses */

/* ---- methods ---- */

/* What sl_culler_create_with hands a method's create_with besides its options: each member may be
 * NULL (sl_culler_params of cull.h; backend already checked with sl_draw_backend_check). */
typedef struct sl_cull_extras {
    const sl_draw_backend *backend; /* only for a method with `draws` */
    sl_scene_accel accel;           /* the same scene's shared handle */
} sl_cull_extras;

/* The object BVH a method walks: the shared handle's when extras has one (its leaf size must be
 * leaf_size: else SL_ERROR_INVALID_ARGUMENT naming both, *owned false), else a new one built with
 * leaf_size through alloc (*owned true: the method destroys it). A method with a shared tree must
 * not refit it in scene_changed (the handle's owner does, accel.h). extras may be NULL. */
sl_status sl_cull_object_bvh(sl_scene scene, const sl_cull_extras *extras, uint32_t leaf_size, const sl_allocator *alloc,
                             sl_bvh *out, bool *owned, sl_error *err);

typedef struct sl_cull_method {
    const char *name;
    const char *summary;
    const char *options_help;
    const char *suits;            /* the scenes and views it suits, one short line (sl_cull_method_desc) */
    sl_cull_guarantee guarantee;  /* with the default options */
    size_t config_size;           /* bytes of the method's parsed-options struct (may be 0) */
    /* the depth it stores or projects with (SL_DEPTH_NONE: frustum planes only); sl_culler_cull
     * refuses a view that format cannot resolve (sl_view_check_depth) */
    sl_depth_format depth;
    /* takes res=any|culling (sl_occ_common): res=culling is the tighter mode whose guarantee is
     * SL_CONSERVATIVE_AT_RESOLUTION (the default, res=any, keeps `guarantee`) */
    bool res_culling;

    /* Read the options into config (config_size zeroed bytes); may change *guarantee when an
     * option makes the method aggressive. Must not allocate. */
    sl_status (*configure)(sl_opts *opts, void *config, sl_cull_guarantee *guarantee, sl_error *err);
    /* Build the method's state for a scene. alloc is never NULL. */
    sl_status (*create)(sl_scene scene, const void *config, const sl_allocator *alloc, void **state, sl_error *err);
    /* Cull one frame: write ids strictly ascending to out (capacity >= object count) and fill the
     * counters and phases of stats (zeroed by the caller). Must not allocate. */
    sl_status (*cull)(void *state, const sl_view *view, uint32_t *out, uint32_t capacity, uint32_t *count,
                      sl_cull_stats *stats, sl_error *err);
    /* create with extras (sl_culler_create_with): used instead of create when not NULL (create may
     * then be NULL); a method without it ignores the accel and is refused a backend. */
    sl_status (*create_with)(sl_scene scene, const void *config, const sl_cull_extras *extras,
                             const sl_allocator *alloc, void **state, sl_error *err);
    /* the method draws through a backend (sl_cull_extras.backend; NULL: it makes its own) */
    bool draws;
    /* Objects moved: refit. NULL when the method keeps nothing that depends on object boxes. */
    sl_status (*scene_changed)(void *state, sl_error *err);
    void (*destroy)(void *state);
    /* Whether the method culls more than the frustum on this scene (sl_cull_method_applicable):
     * false with a reason (why, why_size bytes) when the scene lacks what it needs. config is the
     * parsed options. NULL: applicable to every scene. */
    bool (*applicable)(sl_scene scene, const void *config, char *why, size_t why_size);
} sl_cull_method;

/* The registry (registry.c). */
uint32_t sl_cull_registry_count(void);
const sl_cull_method *sl_cull_registry_get(uint32_t index);

/* The registry hook for methods defined above this layer (the render layer's GL-only "gpu-hiz"):
 * sl_culler_create_with for a method table that is not in the registry (the caller keeps it
 * alive, e.g. a const table of its own), with every check and the bookkeeping of a registered
 * method. The cull layer never includes the caller's headers: the table is all it sees. Exported
 * (SL_API) for libsightline_render, though not in a public header. */
SL_API sl_status sl_culler_create_from_method(const sl_cull_method *method, sl_scene scene, const char *options,
                                       const sl_culler_params *params, const sl_allocator *alloc, sl_culler *out,
                                       sl_error *err);

/* The state of culler c when its method is m, else NULL (a method's own public calls, such as
 * sl_instant_get_stats, reach their state through it). */
void *sl_culler_state_of(sl_culler c, const sl_cull_method *m);

/* ---- helpers for methods ---- */

/* Milliseconds between two sl_now() readings. */
static inline double sl_cull_ms(double t0, double t1) { return (t1 - t0) * 1000.0; }

/* Record a named phase in stats (ignored beyond SL_CULL_MAX_PHASES). */
static inline void sl_cull_phase(sl_cull_stats *s, const char *name, double ms)
{
    if (s->phase_count < SL_CULL_MAX_PHASES) {
        s->phase_names[s->phase_count] = name;
        s->phase_ms[s->phase_count] = ms;
        s->phase_count++;
    }
}

/* Sort a list of object ids ascending in place (radix sort with a caller-provided scratch buffer
 * of n entries; allocation-free). */
void sl_cull_sort_ids(uint32_t *ids, uint32_t n, uint32_t *scratch);

#endif

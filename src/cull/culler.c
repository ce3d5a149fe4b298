/* The public culler interface: method lookup, option parsing, and the checks and bookkeeping
 * every method gets for free (see culler_internal.h). */
#include "culler_internal.h"

#include "accel/bvh_internal.h"
#include "scene/scene_internal.h"

#include <ctype.h>
#include <strings.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>

struct sl_culler_t {
    sl_allocator alloc;
    const sl_cull_method *method;
    sl_scene scene;
    uint32_t object_count;        /* at creation: the scene must keep it */
    void *state;
    sl_cull_guarantee guarantee;
    sl_cull_stats stats;
    char options[SL_OPTS_MAX_CHARS + 1];
    void *frustum_state;          /* vfc with its defaults, for eyes outside the domain (BSP scenes);
                                     NULL until needed, and for vfc itself (its own state serves) */
    sl_draw_backend backend;      /* the copy extras.backend points to */
    sl_cull_extras extras;        /* what sl_culler_create_with was given (for the fallback too) */
};

extern const sl_cull_method sl_cull_method_vfc;

const char *sl_cull_guarantee_name(sl_cull_guarantee g)
{
    switch (g) {
    case SL_CONSERVATIVE: return "conservative";
    case SL_AGGRESSIVE: return "aggressive";
    case SL_CONSERVATIVE_AT_RESOLUTION: return "conservative-at-resolution";
    }
    return "unknown";
}

bool sl_cull_guarantee_keeps_visible(sl_cull_guarantee g, bool at_culling_resolution)
{
    return g == SL_CONSERVATIVE || (g == SL_CONSERVATIVE_AT_RESOLUTION && at_culling_resolution);
}

/* ---- sorting ---- */

void sl_cull_sort_ids(uint32_t *ids, uint32_t n, uint32_t *scratch)
{
    if (n < 64) {
        for (uint32_t i = 1; i < n; i++) {
            uint32_t v = ids[i], j = i;
            for (; j > 0 && ids[j - 1] > v; j--)
                ids[j] = ids[j - 1];
            ids[j] = v;
        }
        return;
    }
    uint32_t maxv = 0;
    for (uint32_t i = 0; i < n; i++)
        maxv = SL_MAX(maxv, ids[i]);
    /* LSD radix sort on 11-bit digits, only as many passes as the largest id needs; an odd number
     * of passes leaves the result in scratch, copied back at the end */
    uint32_t *src = ids, *dst = scratch;
    for (uint32_t shift = 0; shift < 32 && (maxv >> shift) != 0; shift += 11) {
        uint32_t count[2048] = {0};
        for (uint32_t i = 0; i < n; i++)
            count[(src[i] >> shift) & 2047]++;
        uint32_t sum = 0;
        for (uint32_t d = 0; d < 2048; d++) {
            uint32_t c = count[d];
            count[d] = sum;
            sum += c;
        }
        for (uint32_t i = 0; i < n; i++)
            dst[count[(src[i] >> shift) & 2047]++] = src[i];
        uint32_t *t = src;
        src = dst;
        dst = t;
    }
    if (src != ids)
        memcpy(ids, src, (size_t)n * sizeof *ids);
}

/* ---- registry ---- */

uint32_t sl_cull_method_count(void) { return sl_cull_registry_count(); }

sl_status sl_cull_method_info(uint32_t index, sl_cull_method_desc *out, sl_error *err)
{
    const sl_cull_method *m = sl_cull_registry_get(index);
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_cull_method_info: out is NULL");
    if (!m)
        return sl_fail(err, SL_ERROR_NOT_FOUND, "sl_cull_method_info: no method %u (there are %u)", index,
                       sl_cull_registry_count());
    out->name = m->name;
    out->summary = m->summary;
    out->options_help = m->options_help;
    out->guarantee = m->guarantee;
    out->res_culling = m->res_culling;
    out->suits = m->suits ? m->suits : "";
    return SL_OK;
}

sl_status sl_cull_method_find(const char *name, uint32_t *index, sl_error *err)
{
    uint32_t n = sl_cull_registry_count();
    for (uint32_t i = 0; name && i < n; i++)
        if (strcmp(sl_cull_registry_get(i)->name, name) == 0) {
            if (index)
                *index = i;
            return SL_OK;
        }
    char list[512] = "";
    for (uint32_t i = 0; i < n; i++) {
        size_t k = strlen(list);
        snprintf(list + k, sizeof list - k, "%s%s", i ? ", " : "", sl_cull_registry_get(i)->name);
    }
    const char *names[64];
    uint32_t nn = n < 64 ? n : 64;
    for (uint32_t i = 0; i < nn; i++)
        names[i] = sl_cull_registry_get(i)->name;
    char near[160];
    if (name && sl_text_suggest(name, names, nn, near, sizeof near))
        return sl_fail(err, SL_ERROR_NOT_FOUND, "unknown culling method '%s' (did you mean %s? methods: %s)", name, near,
                       list);
    return sl_fail(err, SL_ERROR_NOT_FOUND, "unknown culling method '%s' (methods: %s)", name ? name : "(null)", list);
}

/* Parse and configure: the part of creation that needs no scene. config must hold config_size bytes. */
static sl_status configure(const sl_cull_method *m, const char *options, void *config, sl_opts *opts,
                           sl_cull_guarantee *guarantee, sl_error *err)
{
    sl_status st = sl_opts_parse(opts, m->name, options, err);
    if (st != SL_OK)
        return st;
    *guarantee = m->guarantee;
    if (m->config_size)
        memset(config, 0, m->config_size);
    if (m->configure && (st = m->configure(opts, config, guarantee, err)) != SL_OK)
        return st;
    return sl_opts_check_unused(opts, err);
}

sl_status sl_cull_method_check_options(const char *method, const char *options, sl_error *err)
{
    uint32_t index;
    sl_status st = sl_cull_method_find(method, &index, err);
    if (st != SL_OK)
        return st;
    const sl_cull_method *m = sl_cull_registry_get(index);
    sl_opts *opts = sl_alloc(NULL, sizeof *opts);
    void *config = m->config_size ? sl_alloc(NULL, m->config_size) : NULL;
    if (!opts || (m->config_size && !config))
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", m->name);
    sl_cull_guarantee g;
    if (st == SL_OK)
        st = configure(m, options, config, opts, &g, err);
    sl_free(NULL, config, m->config_size);
    sl_free(NULL, opts, sizeof *opts);
    return st;
}

sl_status sl_cull_method_applicable(const char *method, const char *options, sl_scene scene, bool *applicable,
                                    char *why, size_t why_size, sl_error *err)
{
    if (!scene || !applicable)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_cull_method_applicable: scene and applicable must not be NULL");
    *applicable = true;
    if (why && why_size)
        why[0] = 0;
    uint32_t index;
    sl_status st = sl_cull_method_find(method, &index, err);
    if (st != SL_OK)
        return st;
    const sl_cull_method *m = sl_cull_registry_get(index);
    sl_opts *opts = sl_alloc(NULL, sizeof *opts);
    void *config = m->config_size ? sl_alloc(NULL, m->config_size) : NULL;
    if (!opts || (m->config_size && !config))
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", m->name);
    sl_cull_guarantee g;
    if (st == SL_OK)
        st = configure(m, options, config, opts, &g, err);
    char local[2];
    if (st == SL_OK && m->applicable)
        *applicable = m->applicable(scene, config, why && why_size ? why : local, why && why_size ? why_size : sizeof local);
    sl_free(NULL, config, m->config_size);
    sl_free(NULL, opts, sizeof *opts);
    return st;
}

/* ---- the culler ---- */

sl_status sl_cull_object_bvh(sl_scene scene, const sl_cull_extras *x, uint32_t leaf_size, const sl_allocator *alloc,
                             sl_bvh *out, bool *owned, sl_error *err)
{
    *out = NULL;
    *owned = false;
    if (x && x->accel) {
        uint32_t have = sl_scene_accel_leaf_size(x->accel);
        if (have != leaf_size)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "leaf_size=%u but the shared acceleration handle's BVH has leaf_size %u (create the "
                           "culler with leaf_size=%u, or give it no handle)", leaf_size, have, have);
        *out = sl_scene_accel_bvh(x->accel);
        return SL_OK;
    }
    sl_bvh_options bo = {0};
    bo.max_leaf_size = leaf_size;
    bo.alloc = alloc;
    sl_status st = sl_bvh_build(scene, &bo, out, err);
    *owned = st == SL_OK;
    return st;
}

/* The method's create, with the extras when it takes them. */
static sl_status create_state(const sl_cull_method *m, sl_scene scene, const void *config, const sl_cull_extras *x,
                              const sl_allocator *alloc, void **state, sl_error *err)
{
    if (m->create_with)
        return m->create_with(scene, config, x, alloc, state, err);
    return m->create(scene, config, alloc, state, err);
}

static void destroy_state(struct sl_culler_t *c)
{
    if (c->state)
        c->method->destroy(c->state);
    if (c->frustum_state)
        sl_cull_method_vfc.destroy(c->frustum_state);
    c->state = c->frustum_state = NULL;
}

/* The domain rule (docs/oracle.md, "One set of rules"): an eye in a BSP leaf without a cluster
 * gets the frustum set, from vfc with its default options, whatever the method. Made once per
 * culler (at creation for a scene with BSP data, else at the first such eye). */
static sl_status frustum_fallback(struct sl_culler_t *c, sl_error *err)
{
    const sl_cull_method *v = &sl_cull_method_vfc;
    if (c->method == v || c->frustum_state)
        return SL_OK;
    sl_opts *opts = sl_alloc(&c->alloc, sizeof *opts);
    void *config = v->config_size ? sl_alloc(&c->alloc, v->config_size) : NULL;
    sl_status st = SL_OK;
    if (!opts || (v->config_size && !config))
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the frustum fallback", c->method->name);
    sl_cull_guarantee g;
    if (st == SL_OK)
        st = configure(v, NULL, config, opts, &g, err);
    if (st == SL_OK)
    {
        /* vfc's default leaf size: the shared tree when it has it */
        sl_cull_extras fx = {NULL, c->extras.accel};
        if (fx.accel && sl_scene_accel_leaf_size(fx.accel) != SL_BVH_DEFAULT_LEAF_SIZE)
            fx.accel = NULL;
        st = create_state(v, c->scene, config, &fx, &c->alloc, &c->frustum_state, err);
    }
    if (st != SL_OK) {
        c->frustum_state = NULL;
        sl_error_prefix(err, "%s: frustum fallback for eyes outside the domain", c->method->name);
    }
    sl_free(&c->alloc, config, v->config_size);
    sl_free(&c->alloc, opts, sizeof *opts);
    return st;
}

sl_status sl_culler_create(const char *method, sl_scene scene, const char *options, const sl_allocator *alloc,
                           sl_culler *out, sl_error *err)
{
    return sl_culler_create_with(method, scene, options, NULL, alloc, out, err);
}

bool sl_cull_method_draws(const char *method)
{
    uint32_t index;
    return sl_cull_method_find(method, &index, NULL) == SL_OK && sl_cull_registry_get(index)->draws;
}

sl_status sl_culler_create_with(const char *method, sl_scene scene, const char *options,
                                const sl_culler_params *params, const sl_allocator *alloc, sl_culler *out,
                                sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_culler_create: out is NULL");
    *out = NULL;
    if (!scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_culler_create: scene is NULL");
    uint32_t index;
    sl_status st = sl_cull_method_find(method, &index, err);
    if (st != SL_OK)
        return st;
    return sl_culler_create_from_method(sl_cull_registry_get(index), scene, options, params, alloc, out, err);
}

sl_status sl_culler_create_from_method(const sl_cull_method *m, sl_scene scene, const char *options,
                                       const sl_culler_params *params, const sl_allocator *alloc, sl_culler *out,
                                       sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_culler_create: out is NULL");
    *out = NULL;
    if (!scene || !m)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_culler_create: scene or method is NULL");
    sl_status st = SL_OK;
    if (params && params->backend) {
        if (!m->draws)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "%s: this method draws nothing and takes no draw backend (methods that draw: gl-stopwait, chc, "
                           "chc++)",
                           m->name);
        if ((st = sl_draw_backend_check(params->backend, err)) != SL_OK) {
            sl_error_prefix(err, "%s", m->name);
            return st;
        }
    }
    if (params && params->accel && sl_scene_accel_scene(params->accel) != scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: the shared acceleration handle is of another scene",
                       m->name);
    alloc = sl_alloc_or_default(alloc);
    struct sl_culler_t *c = sl_calloc(alloc, 1, sizeof *c);
    sl_opts *opts = sl_alloc(alloc, sizeof *opts);
    void *config = m->config_size ? sl_alloc(alloc, m->config_size) : NULL;
    if (!c || !opts || (m->config_size && !config)) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", m->name);
        goto done;
    }
    c->alloc = *alloc;
    c->method = m;
    c->scene = scene;
    c->object_count = sl_scene_object_count(scene);
    if (params && params->backend) {
        c->backend = *params->backend;
        c->extras.backend = &c->backend;
    }
    c->extras.accel = params ? params->accel : NULL;
    st = configure(m, options, config, opts, &c->guarantee, err);
    if (st != SL_OK)
        goto done;
    memcpy(c->options, opts->effective, sizeof c->options);
    st = create_state(m, scene, config, &c->extras, &c->alloc, &c->state, err);
    if (st == SL_OK) {
        sl_bsp_view bsp;
        if (sl_scene_bsp(scene, &bsp) && bsp.node_count > 0)
            st = frustum_fallback(c, err);
    }
done:
    sl_free(alloc, config, m->config_size);
    sl_free(alloc, opts, sizeof *opts);
    if (st != SL_OK) {
        if (c)
            destroy_state(c);
        sl_free(alloc, c, sizeof *c);
        return st;
    }
    *out = c;
    return SL_OK;
}

void sl_culler_destroy(sl_culler c)
{
    if (!c)
        return;
    destroy_state(c);
    sl_allocator a = c->alloc;
    sl_free(&a, c, sizeof *c);
}

sl_status sl_culler_cull(sl_culler c, const sl_camera *cam, uint32_t *out_ids, uint32_t capacity, uint32_t *out_count,
                         sl_error *err)
{
    if (out_count)
        *out_count = 0;
    if (!c || !cam || !out_ids || !out_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_culler_cull: culler, camera, out_ids and out_count must not be NULL");
    memset(&c->stats, 0, sizeof c->stats);
    sl_view view;
    sl_status st = sl_view_from_camera(cam, &view, err);
    if (st != SL_OK)
        return st;
    return sl_culler_cull_view(c, &view, out_ids, capacity, out_count, err);
}

sl_status sl_culler_cull_view(sl_culler c, const sl_view *view_in, uint32_t *out_ids, uint32_t capacity,
                              uint32_t *out_count, sl_error *err)
{
    if (out_count)
        *out_count = 0;
    if (!c || !view_in || !out_ids || !out_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_culler_cull_view: culler, view, out_ids and out_count must not be NULL");
    memset(&c->stats, 0, sizeof c->stats);
    sl_status st = sl_view_validate(view_in, err);
    if (st != SL_OK)
        return st;
    /* the methods never see an infinite far plane: bounded by the scene's box (same visible set) */
    sl_view bounded;
    const sl_view *view;
    if ((st = sl_scene_finite_view(c->scene, view_in, &bounded, &view, err)) != SL_OK)
        return st;
    /* a projection the method's depth format cannot resolve is refused (issue 12 §1) */
    if ((st = sl_view_check_depth(view, c->method->depth, c->method->name, err)) != SL_OK)
        return st;
    uint32_t n = sl_scene_object_count(c->scene);
    if (n != c->object_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: the scene has %u objects but had %u when the culler was created: create a new culler",
                       c->method->name, n, c->object_count);
    if (capacity < n)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: capacity %u is below the scene's object count %u",
                       c->method->name, capacity, n);
    double t0 = sl_now();
    uint32_t count = 0;
    bool outside = !sl_oracle_in_domain(c->scene, view->eye, NULL);
    if (outside) {
        /* no method's guarantee holds there (nor the oracle's truth): the frustum set, flagged */
        st = frustum_fallback(c, err);
        if (st == SL_OK)
            st = sl_cull_method_vfc.cull(c->method == &sl_cull_method_vfc ? c->state : c->frustum_state, view,
                                         out_ids, capacity, &count, &c->stats, err);
    } else {
        st = c->method->cull(c->state, view, out_ids, capacity, &count, &c->stats, err);
    }
    double t1 = sl_now();
    if (st != SL_OK) {
        memset(&c->stats, 0, sizeof c->stats);
        return st;
    }
    /* the contract every consumer relies on, checked here once for every method */
    if (count > n)
        return sl_fail(err, SL_ERROR_INTERNAL, "%s: reported %u objects of %u", c->method->name, count, n);
    const struct sl_scene_t *s = c->scene;
    const sl_object_rec *objects = sl_scene_objects(s);
    const sl_mesh_rec *meshes = sl_scene_meshes(s);
    uint64_t triangles = 0;
    for (uint32_t i = 0; i < count; i++) {
        if (out_ids[i] >= n || (i > 0 && out_ids[i] <= out_ids[i - 1]))
            return sl_fail(err, SL_ERROR_INTERNAL, "%s: output entry %u (object %u) is out of range or out of order",
                           c->method->name, i, out_ids[i]);
        triangles += meshes[objects[out_ids[i]].mesh].triangle_count;
    }
    c->stats.objects_visible = count;
    c->stats.triangles_visible = triangles;
    c->stats.total_ms = sl_cull_ms(t0, t1);
    c->stats.out_of_domain = outside;
    *out_count = count;
    return SL_OK;
}

void *sl_culler_state_of(sl_culler c, const sl_cull_method *m)
{
    return c && c->method == m ? c->state : NULL;
}

void sl_culler_stats(sl_culler c, sl_cull_stats *out)
{
    if (!out)
        return;
    if (!c) {
        memset(out, 0, sizeof *out);
        return;
    }
    *out = c->stats;
}

sl_status sl_culler_scene_changed(sl_culler c, sl_error *err)
{
    if (!c)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_culler_scene_changed: culler is NULL");
    uint32_t n = sl_scene_object_count(c->scene);
    if (n != c->object_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s: the scene has %u objects but had %u when the culler was created: create a new culler",
                       c->method->name, n, c->object_count);
    sl_status st = c->method->scene_changed ? c->method->scene_changed(c->state, err) : SL_OK;
    if (st == SL_OK && c->frustum_state && sl_cull_method_vfc.scene_changed)
        st = sl_cull_method_vfc.scene_changed(c->frustum_state, err);
    return st;
}

sl_cull_guarantee sl_culler_guarantee(sl_culler c) { return c ? c->guarantee : SL_AGGRESSIVE; }

const char *sl_culler_method(sl_culler c) { return c ? c->method->name : ""; }

const char *sl_culler_options(sl_culler c) { return c ? c->options : ""; }

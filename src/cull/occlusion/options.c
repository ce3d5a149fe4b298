/* Reading the options shared by the occlusion methods (options.h). */
#include "options.h"

#include "accel/bvh_internal.h" /* leaf sizes */
#include "object_tests.h"       /* SL_OCC_SAMPLED_MAX_PX */

/* ---- options ---- */

sl_status sl_occ_configure_common(sl_opts *o, uint32_t which, uint32_t def_occluders, uint32_t def_budget,
                                  sl_occ_common *c, sl_error *err)
{
    static const char *const isa_names[] = {"auto", "scalar", "sse41", "avx2", "avx512"};
    sl_status st;
    if (which & SL_OCC_OPT_RASTER) {
        if ((st = sl_opts_u32(o, "threads", 1, 1, 16, &c->threads, err)) != SL_OK ||
            (st = sl_opts_enum(o, "isa", isa_names, 5, 0, &c->isa, err)) != SL_OK)
            return st;
    } else {
        c->threads = 1;
    }
    if (which & SL_OCC_OPT_SELECT) {
        if ((st = sl_opts_u32(o, "occluders", def_occluders, 0, 4096, &c->occluders, err)) != SL_OK ||
            (st = sl_opts_u32(o, "budget", def_budget, 0, 10000000, &c->budget, err)) != SL_OK ||
            (st = sl_opts_float(o, "min_quality", 0.0005f, 0.0f, 100.0f, &c->min_quality, err)) != SL_OK)
            return st;
    }
    c->res_culling = c->res_any = false;
    if (which & SL_OCC_OPT_RES) {
        static const char *const res_names[] = {"any", "culling"};
        uint32_t res = 0;
        if ((st = sl_opts_enum(o, "res", res_names, 2, 0, &res, err)) != SL_OK)
            return st;
        c->res_culling = res == 1;
        c->res_any = res == 0;
        static const char *const inner_names[] = {"hull", "faces"};
        uint32_t inner = 0;
        if ((st = sl_opts_enum(o, "inner", inner_names, 2, 0, &inner, err)) != SL_OK)
            return st;
        c->inner_faces = inner == 1;
    }
    /* the inset of a prism drawn by its eroded silhouette (res=any, inner=hull) need only absorb the
     * float rounding of its vertices (add_prism certifies that); elsewhere it must span
     * SL_OCC_MIN_INSET_PX on screen (sl_occ_usable), and 0.1 m keeps prisms usable far away */
    const bool thin = (which & SL_OCC_OPT_THIN_INSET) && c->res_any && !c->inner_faces;
    if ((st = sl_opts_float(o, "inset", thin ? SL_OCC_THIN_INSET : 0.1f, 0.01f, 10.0f, &c->inset, err)) != SL_OK ||
        (st = sl_opts_bool(o, "all_objects", false, &c->all_objects, err)) != SL_OK ||
        (st = sl_opts_u32(o, "leaf_size", SL_BVH_DEFAULT_LEAF_SIZE, 1, SL_BVH_MAX_LEAF_SIZE, &c->leaf_size, err)) !=
            SL_OK)
        return st;
    if (which & SL_OCC_OPT_DEBUG) {
        const char *d, *r;
        if ((st = sl_opts_string(o, "dump", &d, err)) != SL_OK ||
            (st = sl_opts_string(o, "record", &r, err)) != SL_OK ||
            (st = sl_opts_u32(o, "debug_frame", 0, 0, UINT32_MAX, &c->debug_frame, err)) != SL_OK)
            return st;
        if ((d && strlen(d) >= sizeof c->dump_buf - 16) || (r && strlen(r) >= sizeof c->record_buf))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: option %s is longer than %zu characters", o->method,
                           d && strlen(d) >= sizeof c->dump_buf - 16 ? "dump" : "record", sizeof c->dump_buf - 16);
        if (d)
            snprintf(c->dump_buf, sizeof c->dump_buf, "%s", d);
        if (r)
            snprintf(c->record_buf, sizeof c->record_buf, "%s", r);
        c->dump = d ? c->dump_buf : NULL;
        c->record = r ? c->record_buf : NULL;
    }
    return SL_OK;
}

sl_status sl_occ_require_res_culling(const sl_opts *o, const sl_occ_common *c, const char *key, uint32_t value,
                                     sl_error *err)
{
    if (!c->res_any || value == 0)
        return SL_OK;
    return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                   "%s: %s=%u tests pixel centres of the culling resolution: it needs res=culling (with res=any, "
                   "the default, it is 0)",
                   o->method, key, value);
}

sl_status sl_occ_configure_mesh_tests(sl_opts *o, const sl_occ_common *c, sl_occ_mesh_tests *t, sl_error *err)
{
    sl_status st;
    if ((st = sl_opts_u32(o, "mesh_test", 64, 0, 100000, &t->mesh_test, err)) != SL_OK ||
        (st = sl_opts_u32(o, "sample_tris", c->res_any ? 0 : 64, 0, 1000000, &t->sample_tris, err)) != SL_OK ||
        (st = sl_opts_u32(o, "sample_px", 256, 0, SL_OCC_SAMPLED_MAX_PX, &t->sample_px, err)) != SL_OK ||
        (st = sl_occ_require_res_culling(o, c, "sample_tris", t->sample_tris, err)) != SL_OK)
        return st;
    /* a testing aid: shared=false leaves only the method's own test (tests/test_method_own.c) */
    bool shared;
    if ((st = sl_opts_bool(o, "shared", true, &shared, err)) != SL_OK)
        return st;
    if (!shared)
        t->mesh_test = t->sample_tris = 0;
    return SL_OK;
}

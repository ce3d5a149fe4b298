/* The registry of PVS baking methods: one line per method. A method lives in
 * src/region/method_<name>.c and defines `const sl_pvs_method sl_pvs_method_<name>` (see
 * pvs_internal.h for the table and its contract); listing it here is all it takes for
 * `sightline pvs build --method <name>`, the bake drivers and the tests to offer it. Guided
 * visibility sampling joins as X(gvs) with src/region/method_gvs.c. Order is the listing order;
 * the first is the default. */
#include "pvs_internal.h"

#define SL_PVS_METHODS(X) \
    X(sample)             \
    X(adjustable)         \
    X(mappvs) \
    X(portal) \
    X(gvs) \
    X(volumetric) \
    X(extproj) \
    X(virtual)

#define SL_DECLARE_PVS_METHOD(name) extern const sl_pvs_method sl_pvs_method_##name;
SL_PVS_METHODS(SL_DECLARE_PVS_METHOD)
#undef SL_DECLARE_PVS_METHOD

#define SL_LIST_PVS_METHOD(name) &sl_pvs_method_##name,
static const sl_pvs_method *const g_pvs_methods[] = {SL_PVS_METHODS(SL_LIST_PVS_METHOD)};
#undef SL_LIST_PVS_METHOD

uint32_t sl_pvs_registry_count(void) { return (uint32_t)SL_COUNTOF(g_pvs_methods); }

const sl_pvs_method *sl_pvs_registry_get(uint32_t index)
{
    return index < SL_COUNTOF(g_pvs_methods) ? g_pvs_methods[index] : NULL;
}

sl_status sl_pvs_registry_find(const char *name, const sl_pvs_method **out, sl_error *err)
{
    if (!name)
        name = g_pvs_methods[0]->name;
    for (size_t i = 0; i < SL_COUNTOF(g_pvs_methods); i++)
        if (strcmp(g_pvs_methods[i]->name, name) == 0) {
            *out = g_pvs_methods[i];
            return SL_OK;
        }
    char list[256] = "";
    for (size_t i = 0; i < SL_COUNTOF(g_pvs_methods); i++) {
        size_t n = strlen(list);
        snprintf(list + n, sizeof list - n, "%s%s", i ? ", " : "", g_pvs_methods[i]->name);
    }
    return sl_fail(err, SL_ERROR_NOT_FOUND, "unknown PVS method '%s' (methods: %s)", name, list);
}

sl_status sl_pvs_method_configure(const sl_pvs_method *m, const char *options, const sl_allocator *a, void **config,
                                  char *effective, sl_error *err)
{
    *config = NULL;
    size_t size = m->config_size ? m->config_size : 1;
    sl_opts *opts = sl_alloc(a, sizeof *opts);
    void *cfg = sl_calloc(a, 1, size);
    sl_status st = SL_OK;
    if (!opts || !cfg)
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", m->name);
    if (st == SL_OK)
        st = sl_opts_parse(opts, m->name, options, err);
    if (st == SL_OK && m->configure)
        st = m->configure(opts, cfg, err);
    if (st == SL_OK)
        st = sl_opts_check_unused(opts, err);
    if (st == SL_OK && effective)
        memcpy(effective, opts->effective, sizeof opts->effective);
    sl_free(a, opts, sizeof *opts);
    if (st != SL_OK) {
        sl_free(a, cfg, size);
        return st;
    }
    *config = cfg;
    return SL_OK;
}

uint32_t sl_pvs_method_count(void) { return sl_pvs_registry_count(); }

sl_status sl_pvs_method_info(uint32_t index, sl_pvs_method_desc *out, sl_error *err)
{
    const sl_pvs_method *m = sl_pvs_registry_get(index);
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_method_info: out is NULL");
    if (!m)
        return sl_fail(err, SL_ERROR_NOT_FOUND, "sl_pvs_method_info: no method %u (there are %u)", index,
                       sl_pvs_registry_count());
    out->name = m->name;
    out->summary = m->summary;
    out->options_help = m->options_help;
    out->guarantee = m->guarantee;
    return SL_OK;
}

sl_status sl_pvs_method_check_options(const char *method, const char *options, sl_error *err)
{
    const sl_pvs_method *m;
    sl_status st = sl_pvs_registry_find(method, &m, err);
    if (st != SL_OK)
        return st;
    void *cfg;
    st = sl_pvs_method_configure(m, options, NULL, &cfg, NULL, err);
    if (st == SL_OK)
        sl_free(NULL, cfg, m->config_size ? m->config_size : 1);
    return st;
}

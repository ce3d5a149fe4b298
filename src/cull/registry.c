/* The registry of culling methods: one line per method. A method lives in src/cull/<name>.c and
 * defines `const sl_cull_method sl_cull_method_<name>`; listing it here is all it takes for the
 * command, the viewer, the benchmarks and the tests to offer it. Order is the listing order.
 * The X() argument is a C identifier; the name users type is the table's .name, which may hold
 * '-' and '+' (lazygrid_z is "lazygrid-z", stopwait "gl-stopwait" in hoq.c, chcpp "chc++"). */
#include "culler_internal.h"

#define SL_CULL_METHODS(X) \
    X(vfc)                      \
    X(cullmap)                  \
    X(horizon)                  \
    X(dhorizon)                 \
    X(pvs)                      \
    X(hzb)                      \
    X(lazygrid)                 \
    X(lazygrid_z)               \
    X(busygrid)                 \
    X(hom)                      \
    X(frusta)                   \
    X(plp)                      \
    X(cplp)                     \
    X(stopwait)                 \
    X(chc)                      \
    X(chcpp)                    \
    X(instant)

#define SL_DECLARE_METHOD(name) extern const sl_cull_method sl_cull_method_##name;
SL_CULL_METHODS(SL_DECLARE_METHOD)
#undef SL_DECLARE_METHOD

#define SL_LIST_METHOD(name) &sl_cull_method_##name,
static const sl_cull_method *const g_methods[] = {SL_CULL_METHODS(SL_LIST_METHOD)};
#undef SL_LIST_METHOD

uint32_t sl_cull_registry_count(void) { return (uint32_t)SL_COUNTOF(g_methods); }

const sl_cull_method *sl_cull_registry_get(uint32_t index)
{
    return index < SL_COUNTOF(g_methods) ? g_methods[index] : NULL;
}

/* The library's version (include/sightline/core.h), compiled in: what sl_version reports is the
 * version of the library a program runs with, not of the headers it was built against. */
#include "sightline/core.h"

#define SL_STR2(x) #x
#define SL_STR(x) SL_STR2(x)

const char *sl_version_string(void)
{
    return SL_STR(SL_VERSION_MAJOR) "." SL_STR(SL_VERSION_MINOR) "." SL_STR(SL_VERSION_PATCH);
}

void sl_version(uint32_t *major, uint32_t *minor, uint32_t *patch)
{
    if (major)
        *major = SL_VERSION_MAJOR;
    if (minor)
        *minor = SL_VERSION_MINOR;
    if (patch)
        *patch = SL_VERSION_PATCH;
}

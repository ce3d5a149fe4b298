/* libFuzzer target: the option parsers. The input is a string (NUL-terminated copy, at most
 * 4 KiB) given to
 *  - every registered culling method's configure through sl_cull_method_check_options (the
 *    "key=value,..." reader, the typed getters and each method's own checks: what
 *    sl_culler_create runs before it builds anything);
 *  - every registered PVS bake method's configure (sl_pvs_method_check_options);
 *  - the command line's number lists: --point (3 numbers), --volume (6), --eye (3) through
 *    sl_parse_floats, --camera through sl_parse_camera_spec and --frames through sl_parse_range
 *    (src/core/text_parse.c).
 * What the number readers accept must be finite, as floats (the run aborts otherwise). */
#include "core/sl_core.h"
#include "core/text_parse.h"
#include "sightline/cull.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > 4096)
        return 0;
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0;
    sl_error err;
    for (uint32_t i = 0; i < sl_cull_method_count(); i++) {
        sl_cull_method_desc d;
        if (sl_cull_method_info(i, &d, &err) == SL_OK)
            (void)sl_cull_method_check_options(d.name, text, &err);
    }
    for (uint32_t i = 0; i < sl_pvs_method_count(); i++) {
        sl_pvs_method_desc d;
        if (sl_pvs_method_info(i, &d, &err) == SL_OK)
            (void)sl_pvs_method_check_options(d.name, text, &err);
    }
    float v[6];
    for (int n = 3; n <= 6; n += 3)
        if (sl_parse_floats(text, v, n))
            for (int k = 0; k < n; k++)
                if (!isfinite(v[k]))
                    abort();
    sl_camera cam;
    memset(&cam, 0, sizeof cam);
    if (sl_parse_camera_spec(text, &cam) &&
        (!isfinite(cam.position.x) || !isfinite(cam.position.y) || !isfinite(cam.position.z) || !isfinite(cam.yaw) ||
         !isfinite(cam.pitch) || !isfinite(cam.roll) || !isfinite(cam.fov_y)))
        abort();
    uint32_t first, end;
    if (sl_parse_range(text, &first, &end) && !(first < end && first < UINT32_MAX))
        abort();
    free(text);
    return 0;
}

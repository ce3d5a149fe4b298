/* Internal: the command line's number-list readers (--point, --volume, --eye, --camera), kept in
 * the library so that they are tested and fuzzed (fuzz/fuzz_options.c) as readers of untrusted
 * text. Pure functions: no allocation, no messages (the caller names the option). */
#ifndef SL_CORE_TEXT_PARSE_H
#define SL_CORE_TEXT_PARSE_H

#include "sightline/camera.h"

#include <stdbool.h>

/* Exactly n (1..16) comma-separated finite numbers ("1.5,-2,3e2"), as floats: each must convert
 * to a finite float (3e39 is refused, 1e-50 reads as 0); nothing may follow the last. On failure
 * out is left unchanged. */
bool sl_parse_floats(const char *text, float *out, int n);

/* "x,y,z,yaw,pitch,roll[,fov]" (metres, degrees) into cam's position, yaw, pitch, roll and, with a
 * seventh number, fov_y (radians); every value finite as a float. Other fields are untouched, and
 * so is cam on failure. The camera's own checks (sl_camera_validate) still apply afterwards. */
bool sl_parse_camera_spec(const char *text, sl_camera *cam);

#endif

/* Internal: the command line's number-list readers (--point, --volume, --eye, --camera), kept in
 * the library so that they are tested and fuzzed (fuzz/fuzz_options.c) as readers of untrusted
 * text. Pure functions: no allocation, no messages (the caller names the option). */
#ifndef SL_CORE_TEXT_PARSE_H
#define SL_CORE_TEXT_PARSE_H

#include "sightline/camera.h"

#include <stdbool.h>
#include <stdint.h>

/* Exactly n (1..16) comma-separated finite numbers ("1.5,-2,3e2"), as floats: each must convert
 * to a finite float (3e39 is refused, 1e-50 reads as 0); nothing may follow the last. On failure
 * out is left unchanged. */
bool sl_parse_floats(const char *text, float *out, int n);

/* "x,y,z,yaw,pitch,roll[,fov]" (metres, degrees) into cam's position, yaw, pitch, roll and, with a
 * seventh number, fov_y (radians); every value finite as a float. Other fields are untouched, and
 * so is cam on failure. The camera's own checks (sl_camera_validate) still apply afterwards. */
bool sl_parse_camera_spec(const char *text, sl_camera *cam);

/* A frame range "A:B" (frames A to B-1), "A:" (A to the end), ":B" (0 to B-1), ":" (all) or "A"
 * (frame A alone), decimal digits only (no sign, no white space), into *first and *end (one past
 * the last frame; UINT32_MAX: to the end). A must be below B and below UINT32_MAX (a path holds
 * fewer than 2^32 frames, so frame UINT32_MAX never exists), B at most UINT32_MAX. The `bench` and
 * `render` commands' --frames. *first and *end are untouched on failure. */
bool sl_parse_range(const char *text, uint32_t *first, uint32_t *end);

#endif

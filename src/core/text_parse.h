/* Internal: the command line's number-list readers (--point, --volume, --eye, --camera) are public
 * now: sl_parse_floats and sl_parse_range in sightline/core.h, sl_parse_camera_spec in
 * sightline/camera.h (src/core/text_parse.c). This header stays for the library's own users. */
#ifndef SL_CORE_TEXT_PARSE_H
#define SL_CORE_TEXT_PARSE_H

#include "sightline/camera.h"
#include "sightline/core.h"

#endif

/* Text from files made safe for a terminal or a log: sl_escape_text and sl_utf8_sequence are
 * public (sightline/core.h; src/core/escape.c). This header stays for the library's own users. */
#ifndef SL_CORE_ESCAPE_H
#define SL_CORE_ESCAPE_H

#include "sightline/core.h"

#endif

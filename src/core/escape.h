/* Text from files (names, paths, assimp's messages) made safe for a terminal or a log. */
#ifndef SL_CORE_ESCAPE_H
#define SL_CORE_ESCAPE_H

#include <stddef.h>

/* Copy text into buf (size bytes, always terminated) C-style: control bytes (below 0x20, 0x7f),
 * C1 controls (U+0080..U+009F), bytes that are not well-formed UTF-8 and backslashes are written
 * as \xNN (a backslash as \\); well-formed UTF-8 passes unchanged. At most max_in input bytes are
 * read; when the input is longer (or buf fills), "..." ends the result. Returns buf. */
char *sl_escape_text(const char *text, size_t max_in, char *buf, size_t size);

/* Length of the well-formed UTF-8 sequence at s (1..4, at most n bytes), or 0 when the bytes are
 * not one (overlong, surrogate, beyond U+10FFFF, truncated, or a C1 control). ASCII counts as 1,
 * controls included: the caller decides about those. */
size_t sl_utf8_sequence(const unsigned char *s, size_t n);

#endif

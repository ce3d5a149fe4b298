/* C-style escaping of untrusted text for messages and listings (see escape.h). */
#include "escape.h"

#include <stdbool.h>
#include <stdio.h>
#include <string.h>

size_t sl_utf8_sequence(const unsigned char *s, size_t n)
{
    if (!n)
        return 0;
    unsigned c = s[0];
    if (c < 0x80)
        return 1;
    size_t len;
    unsigned cp;
    if (c >= 0xc2 && c <= 0xdf)
        len = 2, cp = c & 0x1f;
    else if (c >= 0xe0 && c <= 0xef)
        len = 3, cp = c & 0x0f;
    else if (c >= 0xf0 && c <= 0xf4)
        len = 4, cp = c & 0x07;
    else
        return 0;
    if (n < len)
        return 0;
    for (size_t i = 1; i < len; i++) {
        if ((s[i] & 0xc0) != 0x80)
            return 0;
        cp = cp << 6 | (s[i] & 0x3f);
    }
    if ((len == 3 && cp < 0x800) || (len == 4 && (cp < 0x10000 || cp > 0x10ffff)) || (cp >= 0xd800 && cp <= 0xdfff) ||
        (cp >= 0x80 && cp <= 0x9f))
        return 0;
    return len;
}

char *sl_escape_text(const char *text, size_t max_in, char *buf, size_t size)
{
    if (!size)
        return buf;
    buf[0] = 0;
    if (!text)
        return buf;
    const unsigned char *s = (const unsigned char *)text;
    size_t n = strlen(text), k = 0;
    bool cut = n > max_in;
    if (cut)
        n = max_in;
    for (size_t i = 0; i < n;) {
        char piece[8];
        size_t plen, used = 1;
        size_t seq = sl_utf8_sequence(s + i, n - i);
        if (s[i] == '\\') {
            memcpy(piece, "\\\\", 2), plen = 2;
        } else if (seq == 1 && s[i] >= 0x20 && s[i] != 0x7f) {
            piece[0] = (char)s[i], plen = 1;
        } else if (seq > 1) {
            memcpy(piece, s + i, seq), plen = seq, used = seq;
        } else {
            snprintf(piece, sizeof piece, "\\x%02x", s[i]);
            plen = 4;
        }
        if (k + plen + 4 > size) { /* room for "..." and the terminator */
            cut = true;
            break;
        }
        memcpy(buf + k, piece, plen);
        k += plen;
        i += used;
    }
    if (cut && k + 4 <= size)
        memcpy(buf + k, "...", 3), k += 3;
    buf[k] = 0;
    return buf;
}

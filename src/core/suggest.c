/* Nearest names for "did you mean" messages (core.h). */
#include "sightline/core.h"

#include <string.h>

#define SL_SUGGEST_LEN 63

static char fold(char c) { return c >= 'A' && c <= 'Z' ? (char)(c - 'A' + 'a') : c; }

uint32_t sl_text_distance(const char *a, const char *b)
{
    if (!a)
        a = "";
    if (!b)
        b = "";
    size_t la = strlen(a), lb = strlen(b), extra = 0;
    if (la > SL_SUGGEST_LEN) {
        extra += la - SL_SUGGEST_LEN;
        la = SL_SUGGEST_LEN;
    }
    if (lb > SL_SUGGEST_LEN) {
        extra += lb - SL_SUGGEST_LEN;
        lb = SL_SUGGEST_LEN;
    }
    /* three rows of the optimal-string-alignment table */
    uint32_t r0[SL_SUGGEST_LEN + 1], r1[SL_SUGGEST_LEN + 1], r2[SL_SUGGEST_LEN + 1];
    uint32_t *prev2 = r0, *prev = r1, *cur = r2;
    for (size_t j = 0; j <= lb; j++)
        prev[j] = (uint32_t)j;
    for (size_t i = 1; i <= la; i++) {
        cur[0] = (uint32_t)i;
        for (size_t j = 1; j <= lb; j++) {
            uint32_t cost = fold(a[i - 1]) != fold(b[j - 1]);
            uint32_t d = prev[j] + 1;
            if (cur[j - 1] + 1 < d)
                d = cur[j - 1] + 1;
            if (prev[j - 1] + cost < d)
                d = prev[j - 1] + cost;
            if (i > 1 && j > 1 && fold(a[i - 1]) == fold(b[j - 2]) && fold(a[i - 2]) == fold(b[j - 1]) &&
                prev2[j - 2] + 1 < d)
                d = prev2[j - 2] + 1;
            cur[j] = d;
        }
        uint32_t *t = prev2;
        prev2 = prev;
        prev = cur;
        cur = t;
    }
    return prev[lb] + (uint32_t)extra;
}

/* a is a prefix of b, ASCII case folded */
static bool prefix_of(const char *a, const char *b)
{
    for (; *a; a++, b++)
        if (!*b || fold(*a) != fold(*b))
            return false;
    return true;
}

uint32_t sl_text_suggest(const char *word, const char *const *candidates, size_t count, char *out, size_t size)
{
    if (out && size)
        out[0] = 0;
    if (!word || !word[0] || !candidates)
        return 0;
    size_t wl = strlen(word);
    uint32_t limit = wl <= 4 ? 1 : wl <= 8 ? 2 : 3;
    size_t best[3];
    uint32_t bestd[3], n = 0;
    for (size_t i = 0; i < count; i++) {
        const char *c = candidates[i];
        if (!c || !c[0])
            continue;
        uint32_t d = sl_text_distance(word, c);
        size_t cl = strlen(c);
        if (d > limit) {
            bool pre = (wl >= 3 && cl >= 3) && (prefix_of(word, c) || prefix_of(c, word));
            if (!pre)
                continue;
            d = limit; /* a prefix counts as close, behind the nearer ones */
        }
        if (d == 0)
            continue; /* the word itself is not a suggestion */
        bool seen = false;
        for (uint32_t k = 0; k < n; k++)
            if (!strcmp(candidates[best[k]], c))
                seen = true;
        if (seen)
            continue;
        /* insert keeping the order: nearer first, then the candidates' order */
        uint32_t at = n;
        while (at > 0 && bestd[at - 1] > d)
            at--;
        if (at >= 3)
            continue;
        uint32_t last = n < 3 ? n : 2;
        for (uint32_t k = last; k > at; k--) {
            best[k] = best[k - 1];
            bestd[k] = bestd[k - 1];
        }
        best[at] = i;
        bestd[at] = d;
        if (n < 3)
            n++;
    }
    if (out && size) {
        size_t used = 0;
        for (uint32_t k = 0; k < n && used < size; k++) {
            const char *sep = k == 0 ? "" : k + 1 == n ? " or " : ", ";
            int w = snprintf(out + used, size - used, "%s%s", sep, candidates[best[k]]);
            if (w < 0)
                break;
            used += (size_t)w;
        }
    }
    return n;
}

/* The command line's number-list readers (text_parse.h). */
#include "text_parse.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Up to max comma-separated numbers read as doubles, each finite also as a float; *count
 * receives how many. False on anything else (empty items, trailing text, too many). */
static bool parse_list(const char *text, double *v, int max, int *count)
{
    if (!text)
        return false;
    const char *p = text;
    int n = 0;
    for (;;) {
        if (n == max)
            return false;
        char *end;
        double x = strtod(p, &end);
        /* strtod skips leading white space: an item must start with the number itself */
        if (end == p || isspace((unsigned char)*p) || !isfinite(x) || !isfinite((float)x))
            return false;
        v[n++] = x;
        if (*end == 0)
            break;
        if (*end != ',')
            return false;
        p = end + 1;
    }
    *count = n;
    return true;
}

bool sl_parse_floats(const char *text, float *out, int n)
{
    double v[16];
    int got;
    if (n < 1 || n > 16 || !parse_list(text, v, n, &got) || got != n)
        return false;
    for (int i = 0; i < n; i++)
        out[i] = (float)v[i];
    return true;
}

bool sl_parse_camera_spec(const char *text, sl_camera *cam)
{
    const double deg = M_PI / 180.0;
    double v[7];
    int n;
    if (!parse_list(text, v, 7, &n) || n < 6)
        return false;
    cam->position = (sl_vec3){(float)v[0], (float)v[1], (float)v[2]};
    cam->yaw = (float)(v[3] * deg);
    cam->pitch = (float)(v[4] * deg);
    cam->roll = (float)(v[5] * deg);
    if (n == 7)
        cam->fov_y = (float)(v[6] * deg);
    return true;
}

/* A decimal number of digits only from p up to stop (or to the end of the text when stop is NULL),
 * at most UINT32_MAX. */
static bool parse_u32_digits(const char *p, const char *stop, unsigned long long *out)
{
    if (!isdigit((unsigned char)*p))
        return false;
    unsigned long long v = 0;
    for (; stop ? p < stop : *p != 0; p++) {
        if (!isdigit((unsigned char)*p))
            return false;
        v = v * 10 + (unsigned)(*p - '0');
        if (v > UINT32_MAX)
            return false;
    }
    *out = v;
    return true;
}

bool sl_parse_range(const char *text, uint32_t *first, uint32_t *end)
{
    if (!text)
        return false;
    const char *colon = strchr(text, ':');
    unsigned long long a = 0, b = UINT32_MAX;
    if (text != colon && !parse_u32_digits(text, colon, &a))
        return false;
    if (a >= UINT32_MAX)
        return false;
    if (!colon)
        b = a + 1;
    else if (colon[1] && !parse_u32_digits(colon + 1, NULL, &b))
        return false;
    if (b <= a)
        return false;
    *first = (uint32_t)a;
    *end = (uint32_t)b;
    return true;
}

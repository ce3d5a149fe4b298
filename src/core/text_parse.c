/* The command line's number-list readers (text_parse.h). */
#include "text_parse.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>

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

/* The ray-triangle test (dvec3.h). */
#include "dvec3.h"

bool sl_ray_triangle(const double o[3], const double d[3], const double a[3], const double b[3], const double c[3],
                     double det_eps, double *t_out)
{
    double e1[3], e2[3], s[3];
    for (int i = 0; i < 3; i++) {
        e1[i] = b[i] - a[i];
        e2[i] = c[i] - a[i];
        s[i] = o[i] - a[i];
    }
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (!(fabs(det) >= det_eps) || det == 0)
        return false;
    double u = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) / det;
    if (u < 0 || u > 1)
        return false;
    double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
    double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
    if (v < 0 || u + v > 1)
        return false;
    double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    if (!(t > 0))
        return false;
    if (t_out)
        *t_out = t;
    return true;
}

/* sl_import_gis: cities from GIS data through GDAL's OGR (docs/gis-import.md).
 *
 * Two passes over the features. The first reads every feature once (GDALDatasetGetNextFeature,
 * which the OpenStreetMap driver needs), keeps the buildings (polygons) and streets (lines tagged
 * highway) with their attributes and geometry in the source CRS, and records each one's centre in
 * longitude/latitude (or as given, in metric mode). The median of those centres is the origin of
 * the local frame: a transverse Mercator on WGS 84 centred there (x east, y north, metres), so a
 * stray feature far away cannot move the frame. The second pass reprojects each kept feature,
 * checks its coordinates (finite, within max_extent of the origin), cleans its polygons with GEOS
 * (rings closed, duplicate points dropped, made valid, parts united, holes kept) and emits the
 * building (mesh + footprints) or the street (segment polygons + graph edges). Ground tiles and the
 * street graph come last.
 *
 * GDAL's messages reach a handler pushed for this thread only (CPLPushErrorHandlerEx), so that
 * concurrent imports keep their own last message and nothing is printed to stderr. */
#include "core/polygon.h"
#include "core/sl_core.h"
#include "region/geos_util.h"
#include "source_meta.h"
#include "sightline/import.h"
#include "sightline/scene.h"

#include <errno.h>
#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>
#include <math.h>
#include <ogr_api.h>
#include <ogr_srs_api.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#define DEFAULT_HEIGHT_FIELDS "height,building:height,measuredHeight,HEIGHT,Height"
#define DEFAULT_LEVELS_FIELDS "building:levels,levels,storeys"
#define MAX_HEIGHT 2000.0 /* metres: taller is a bad value (the tallest building is 828 m) */
#define MAX_LEVELS 500.0
#define WELD 1e-3         /* metres: consecutive ring points closer than this are one */
#define SIMPLIFY 0.01     /* metres: GEOS topology-preserving simplification after repair */

sl_gis_options sl_gis_defaults(void)
{
    sl_gis_options o;
    memset(&o, 0, sizeof o);
    return o;
}

/* The extension of the last path component without its dot ("" if none). */
static const char *ext_of(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    return dot && dot != base ? dot + 1 : "";
}

/* The one OGR driver a file extension may be opened with, or NULL. */
static const char *driver_for(const char *path)
{
    const char *e = ext_of(path);
    if (!strcasecmp(e, "geojson") || !strcasecmp(e, "json"))
        return "GeoJSON";
    if (!strcasecmp(e, "shp"))
        return "ESRI Shapefile";
    if (!strcasecmp(e, "osm") || !strcasecmp(e, "pbf"))
        return "OSM";
    if (!strcasecmp(e, "gml"))
        return "GML";
    return NULL;
}

bool sl_gis_path(const char *path)
{
    return path && driver_for(path) != NULL;
}

/* ---- GDAL set-up and messages ---- */

static pthread_once_t gdal_once = PTHREAD_ONCE_INIT;
static void gdal_register(void)
{
    GDALAllRegister();
}

typedef struct cpl_capture {
    char last[256];
} cpl_capture;

static void CPL_STDCALL on_cpl_error(CPLErr cls, CPLErrorNum num, const char *msg)
{
    (void)num;
    cpl_capture *c = CPLGetErrorHandlerUserData();
    if (c && cls >= CE_Warning)
        sl_escape_text(msg ? msg : "(no message)", 200, c->last, sizeof c->last);
}

/* ---- the importer's state ---- */

enum { FEAT_BUILDING = 1, FEAT_STREET = 2 };

typedef struct feat {
    OGRGeometryH geom;     /* owned; source CRS, then local after pass 2's transform */
    uint32_t layer;
    uint32_t kind;
    int64_t fid;
    double cx, cy;         /* centre: lon/lat, or the raw coordinates in metric mode */
    double height, min_height, roof_height; /* NAN: not given */
    float width;           /* streets */
    uint32_t street_flags;
    char *name;            /* sl_strdup, or NULL */
} feat;

typedef struct layer_info {
    OGRLayerH layer;
    char name[128];
    bool wanted;
    int f_building, f_building_part, f_highway, f_other_tags, f_name, f_width, f_bridge, f_osm_id, f_osm_way_id;
    OGRSpatialReferenceH srs;         /* borrowed from the layer, or the override (owned by gis) */
    OGRCoordinateTransformationH to_geo, to_local;
    uint32_t kept;
} layer_info;

typedef struct node_key {
    int64_t qx, qy;
    float x, y;
    uint32_t id;
} node_key;

typedef struct gis {
    const char *path;
    const sl_gis_options *o;
    const sl_allocator *a;
    sl_scene scene;
    sl_gis_stats *st;
    sl_error *err;
    sl_geos g;
    GDALDatasetH ds;
    layer_info *layers;
    uint32_t layer_count;
    sl_array feats;        /* feat */
    OGRSpatialReferenceH override, geo, local;
    double ox, oy;         /* metric mode: the origin in file coordinates */
    double max_extent, min_area, default_height, level_height;
    char *height_fields, *levels_fields;
    /* mesh under construction */
    sl_array pos, idx;     /* float x3, uint32 */
    /* streets */
    sl_array seg_info;     /* street_seg: every segment of every street line */
    sl_aabb bounds;        /* of everything emitted */
    double *ring;          /* scratch for GEOS ring coordinates */
    size_t ring_cap;
} gis;

typedef struct street_seg {
    double ax, ay, bx, by;
    float width;
    uint32_t flags;
} street_seg;

static void warn(gis *s, uint32_t *counter, const char *fmt, ...) SL_PRINTF(3, 4);
static void warn(gis *s, uint32_t *counter, const char *fmt, ...)
{
    (*counter)++;
    if (s->st->first_warning[0])
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(s->st->first_warning, sizeof s->st->first_warning, fmt, ap);
    va_end(ap);
}

static const char *layer_name(const gis *s, uint32_t layer)
{
    return s->layers[layer].name;
}

/* ---- attributes ---- */

/* Look key up in an OSM other_tags string ("k"=>"v","k2"=>"v2", backslash escapes). */
static bool hstore_get(const char *h, const char *key, char *buf, size_t size)
{
    size_t klen = strlen(key);
    const char *p = h;
    while (*p) {
        while (*p && *p != '"')
            p++;
        if (!*p)
            return false;
        /* a quoted key */
        char k[256], v[512];
        size_t kn = 0, vn = 0;
        for (p++; *p && *p != '"'; p++) {
            if (*p == '\\' && p[1])
                p++;
            if (kn + 1 < sizeof k)
                k[kn++] = *p;
        }
        k[kn] = 0;
        if (!*p)
            return false;
        p++;
        if (strncmp(p, "=>", 2) != 0)
            return false;
        p += 2;
        if (*p != '"')
            return false;
        for (p++; *p && *p != '"'; p++) {
            if (*p == '\\' && p[1])
                p++;
            if (vn + 1 < sizeof v)
                v[vn++] = *p;
        }
        v[vn] = 0;
        if (!*p)
            return false;
        p++;
        if (kn == klen && !memcmp(k, key, klen)) {
            if (snprintf(buf, size, "%s", v) < 0)
                return false;
            return true;
        }
        while (*p == ',' || *p == ' ')
            p++;
    }
    return false;
}

/* The value of attribute `key` of a feature: a field of that name, else an OSM other_tag. */
static bool get_tag(const layer_info *li, OGRFeatureH f, const char *key, char *buf, size_t size)
{
    int i = OGR_F_GetFieldIndex(f, key);
    if (i >= 0) {
        if (!OGR_F_IsFieldSetAndNotNull(f, i))
            return false;
        snprintf(buf, size, "%s", OGR_F_GetFieldAsString(f, i));
        return true;
    }
    if (li->f_other_tags >= 0 && OGR_F_IsFieldSetAndNotNull(f, li->f_other_tags))
        return hstore_get(OGR_F_GetFieldAsString(f, li->f_other_tags), key, buf, size);
    return false;
}

/* A length: "12", "12.5 m", "12,5", "40 ft", "40'". false for anything else or a non-finite value. */
static bool parse_length(const char *text, double *out)
{
    char buf[64];
    if (snprintf(buf, sizeof buf, "%s", text) < 0)
        return false;
    if (!strchr(buf, '.'))
        for (char *c = buf; *c; c++)
            if (*c == ',')
                *c = '.';
    char *end;
    const char *p = buf;
    while (*p == ' ')
        p++;
    if (!((*p >= '0' && *p <= '9') || *p == '.' || *p == '-' || *p == '+'))
        return false;
    double v = strtod(p, &end);
    if (end == p || !isfinite(v))
        return false;
    while (*end == ' ')
        end++;
    double scale = 1;
    if (!*end || !strcasecmp(end, "m") || !strcasecmp(end, "meters") || !strcasecmp(end, "metres"))
        scale = 1;
    else if (!strcasecmp(end, "ft") || !strcmp(end, "'"))
        scale = 0.3048;
    else
        return false;
    *out = v * scale;
    return true;
}

/* The first of a comma-separated list of attribute names the feature has: 1 and the value when
 * usable, 0 when none is present, -1 (with the offending text) when present but unusable. */
static int tag_number(const layer_info *li, OGRFeatureH f, const char *names, double lo, double hi, double *out,
                      char *bad, size_t bad_size)
{
    char name[128], val[128];
    const char *p = names;
    while (*p) {
        size_t n = strcspn(p, ",");
        snprintf(name, sizeof name, "%.*s", (int)SL_MIN(n, sizeof name - 1), p);
        p += n;
        if (*p == ',')
            p++;
        if (!name[0] || !get_tag(li, f, name, val, sizeof val))
            continue;
        double v;
        if (parse_length(val, &v) && v >= lo && v <= hi) {
            *out = v;
            return 1;
        }
        char esc[64];
        if (snprintf(bad, bad_size, "%s=\"%s\"", name, sl_escape_text(val, 40, esc, sizeof esc)) < 0)
            bad[0] = 0;
        return -1;
    }
    return 0;
}

static bool tag_is(const layer_info *li, OGRFeatureH f, const char *key, const char *value)
{
    char v[64];
    return get_tag(li, f, key, v, sizeof v) && !strcmp(v, value);
}

/* ---- geometry helpers ---- */

static bool is_polygonal(OGRwkbGeometryType t)
{
    t = wkbFlatten(t);
    return t == wkbPolygon || t == wkbMultiPolygon || t == wkbCurvePolygon || t == wkbMultiSurface ||
           t == wkbPolyhedralSurface || t == wkbTIN || t == wkbTriangle;
}

static bool is_linear(OGRwkbGeometryType t)
{
    t = wkbFlatten(t);
    return t == wkbLineString || t == wkbMultiLineString || t == wkbCircularString || t == wkbCompoundCurve ||
           t == wkbMultiCurve;
}

/* z range of every point of g (recursively); false when it has no finite z. */
static void z_range(OGRGeometryH g, double *lo, double *hi)
{
    int n = OGR_G_GetGeometryCount(g);
    if (n > 0) {
        for (int i = 0; i < n; i++)
            z_range(OGR_G_GetGeometryRef(g, i), lo, hi);
        return;
    }
    int np = OGR_G_GetPointCount(g);
    for (int i = 0; i < np; i++) {
        double z = OGR_G_GetZ(g, i);
        if (isfinite(z)) {
            *lo = fmin(*lo, z);
            *hi = fmax(*hi, z);
        }
    }
}

/* ---- pass 1: classify and keep ---- */

static void layer_fields(layer_info *li)
{
    OGRFeatureDefnH d = OGR_L_GetLayerDefn(li->layer);
    li->f_building = OGR_FD_GetFieldIndex(d, "building");
    li->f_building_part = OGR_FD_GetFieldIndex(d, "building:part");
    li->f_highway = OGR_FD_GetFieldIndex(d, "highway");
    li->f_other_tags = OGR_FD_GetFieldIndex(d, "other_tags");
    li->f_name = OGR_FD_GetFieldIndex(d, "name");
    li->f_width = OGR_FD_GetFieldIndex(d, "width");
    li->f_bridge = OGR_FD_GetFieldIndex(d, "bridge");
    li->f_osm_id = OGR_FD_GetFieldIndex(d, "osm_id");
    li->f_osm_way_id = OGR_FD_GetFieldIndex(d, "osm_way_id");
}

/* Whether a polygon feature is a building: tagged building (or building:part) other than "no";
 * a layer that has neither such a field nor OSM other_tags holds only buildings. */
static bool is_building(const layer_info *li, OGRFeatureH f)
{
    char v[64];
    bool tagged = li->f_building >= 0 || li->f_building_part >= 0 || li->f_other_tags >= 0;
    if (!tagged)
        return true;
    if (get_tag(li, f, "building", v, sizeof v) && strcmp(v, "no") && v[0])
        return true;
    if (get_tag(li, f, "building:part", v, sizeof v) && strcmp(v, "no") && v[0])
        return true;
    return false;
}

/* Street class: default width (metres) and flags; 0 when the highway value is not a way one can
 * see along (proposed, under construction, a platform, ...). */
static float highway_width(const char *v, uint32_t *flags)
{
    static const struct {
        const char *k;
        float w;
        bool avenue;
    } t[] = {{"motorway", 16, true},     {"trunk", 14, true},       {"primary", 12, true},
             {"secondary", 10, false},   {"tertiary", 8, false},    {"motorway_link", 7, false},
             {"trunk_link", 7, false},   {"primary_link", 7, false}, {"secondary_link", 7, false},
             {"tertiary_link", 7, false}, {"residential", 7, false}, {"unclassified", 7, false},
             {"living_street", 6, false}, {"service", 5, false},     {"pedestrian", 6, false},
             {"road", 6, false},         {"track", 4, false},       {"busway", 7, false},
             {"footway", 3, false},      {"path", 3, false},        {"cycleway", 3, false},
             {"steps", 3, false},        {"bridleway", 3, false}};
    static const char *skip[] = {"proposed", "construction", "abandoned", "platform", "elevator", "bus_stop",
                                 "corridor", "raceway", "razed", "disused"};
    for (size_t i = 0; i < sizeof skip / sizeof skip[0]; i++)
        if (!strcmp(v, skip[i]))
            return 0;
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (!strcmp(v, t[i].k)) {
            *flags = t[i].avenue ? SL_STREET_AVENUE : 0;
            return t[i].w;
        }
    *flags = 0;
    return 6;
}

static void feat_free(gis *s, feat *f)
{
    if (f->geom)
        OGR_G_DestroyGeometry(f->geom);
    sl_strfree(s->a, f->name);
    f->geom = NULL;
    f->name = NULL;
}

/* The object name: the feature's name tag, else its OSM id, else "LAYER/FID". */
static char *feature_name(gis *s, const layer_info *li, OGRFeatureH f, int64_t fid)
{
    char buf[512];
    buf[0] = 0;
    if (li->f_name >= 0 && OGR_F_IsFieldSetAndNotNull(f, li->f_name))
        snprintf(buf, sizeof buf, "%s", OGR_F_GetFieldAsString(f, li->f_name));
    else if (li->f_osm_way_id >= 0 && OGR_F_IsFieldSetAndNotNull(f, li->f_osm_way_id))
        snprintf(buf, sizeof buf, "osm way %s", OGR_F_GetFieldAsString(f, li->f_osm_way_id));
    else if (li->f_osm_id >= 0 && OGR_F_IsFieldSetAndNotNull(f, li->f_osm_id))
        snprintf(buf, sizeof buf, "osm %s", OGR_F_GetFieldAsString(f, li->f_osm_id));
    if (!buf[0])
        snprintf(buf, sizeof buf, "%s/%lld", li->name, (long long)fid);
    return sl_strdup(s->a, buf);
}

static sl_status read_features(gis *s)
{
    GDALDatasetResetReading(s->ds);
    uint32_t max_features = s->o->max_features ? s->o->max_features : 10000000u;
    for (;;) {
        OGRLayerH lh = NULL;
        OGRFeatureH f = GDALDatasetGetNextFeature(s->ds, &lh, NULL, NULL, NULL);
        if (!f)
            break;
        uint32_t li_i = SL_NONE;
        for (uint32_t i = 0; i < s->layer_count; i++)
            if (s->layers[i].layer == lh)
                li_i = i;
        if (li_i == SL_NONE || !s->layers[li_i].wanted) {
            OGR_F_Destroy(f);
            continue;
        }
        layer_info *li = &s->layers[li_i];
        if (++s->st->features > max_features) {
            OGR_F_Destroy(f);
            return sl_fail(s->err, SL_ERROR_LIMIT, "%s: more than %u features (raise max_features)", s->path, max_features);
        }
        if (s->o->progress.fn && (s->st->features & 1023) == 0 &&
            !s->o->progress.fn(s->o->progress.user, "gis: reading", s->st->features, 0)) {
            OGR_F_Destroy(f);
            return sl_fail(s->err, SL_ERROR_CANCELLED, "%s: cancelled", s->path);
        }
        OGRGeometryH gref = OGR_F_GetGeometryRef(f);
        int64_t fid = (int64_t)OGR_F_GetFID(f);
        feat ft;
        memset(&ft, 0, sizeof ft);
        ft.layer = li_i;
        ft.fid = fid;
        ft.height = ft.min_height = ft.roof_height = NAN;
        bool keep = false;
        if (gref && !OGR_G_IsEmpty(gref) && is_polygonal(OGR_G_GetGeometryType(gref)) && is_building(li, f)) {
            keep = true;
            ft.kind = FEAT_BUILDING;
            char bad[128];
            double v;
            int r = tag_number(li, f, s->height_fields, 0.01, MAX_HEIGHT, &v, bad, sizeof bad);
            if (r > 0)
                ft.height = v;
            if (r < 0)
                warn(s, &s->st->bad_height, "%s: layer '%s', feature %lld: unusable height %s", s->path, li->name,
                     (long long)fid, bad);
            if (r <= 0) {
                int rl = tag_number(li, f, s->levels_fields, 0.01, MAX_LEVELS, &v, bad, sizeof bad);
                if (rl > 0)
                    ft.height = v * s->level_height;
                if (rl < 0)
                    warn(s, &s->st->bad_height, "%s: layer '%s', feature %lld: unusable levels %s", s->path, li->name,
                         (long long)fid, bad);
            }
            if (tag_number(li, f, "min_height", 0, MAX_HEIGHT, &v, bad, sizeof bad) > 0)
                ft.min_height = v;
            else if (tag_number(li, f, "building:min_level", 0, MAX_LEVELS, &v, bad, sizeof bad) > 0)
                ft.min_height = v * s->level_height;
            if (tag_number(li, f, "roof:height", 0.01, MAX_HEIGHT, &v, bad, sizeof bad) > 0)
                ft.roof_height = v;
        } else if (!s->o->no_streets && gref && !OGR_G_IsEmpty(gref) && is_linear(OGR_G_GetGeometryType(gref))) {
            char hw[64];
            bool tagged = li->f_highway >= 0 || li->f_other_tags >= 0;
            bool has = get_tag(li, f, "highway", hw, sizeof hw);
            if (has || !tagged) {
                uint32_t flags = 0;
                float w = has ? highway_width(hw, &flags) : 6.0f;
                double wv;
                char bad[128];
                if (w > 0 && tag_number(li, f, "width", 1, 200, &wv, bad, sizeof bad) > 0)
                    w = (float)wv;
                if (w > 0) {
                    keep = true;
                    ft.kind = FEAT_STREET;
                    ft.width = w;
                    ft.street_flags = flags | (tag_is(li, f, "bridge", "yes") ? SL_STREET_BRIDGE : 0u);
                }
            }
        }
        if (!keep) {
            s->st->other++;
            OGR_F_Destroy(f);
            continue;
        }
        ft.geom = OGR_F_StealGeometry(f);
        ft.name = ft.kind == FEAT_BUILDING ? feature_name(s, li, f, fid) : NULL;
        OGR_F_Destroy(f);
        if (!ft.geom || (ft.kind == FEAT_BUILDING && !ft.name)) {
            feat_free(s, &ft);
            return sl_fail(s->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", s->path);
        }
        OGREnvelope env;
        OGR_G_GetEnvelope(ft.geom, &env);
        ft.cx = 0.5 * (env.MinX + env.MaxX);
        ft.cy = 0.5 * (env.MinY + env.MaxY);
        if (!isfinite(ft.cx) || !isfinite(ft.cy) || !isfinite(env.MinX) || !isfinite(env.MaxX) || !isfinite(env.MinY) ||
            !isfinite(env.MaxY)) {
            warn(s, &s->st->dropped_invalid, "%s: layer '%s', feature %lld: coordinates are not finite (NaN or infinite)",
                 s->path, li->name, (long long)fid);
            feat_free(s, &ft);
            continue;
        }
        if (!sl_array_push(s->a, &s->feats, sizeof ft, &ft, 1)) {
            feat_free(s, &ft);
            return sl_fail(s->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory after %u features", s->path, s->st->features);
        }
        li->kept++;
    }
    return SL_OK;
}

/* ---- the local frame ---- */

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static OGRSpatialReferenceH new_srs(void)
{
    OGRSpatialReferenceH h = OSRNewSpatialReference(NULL);
    if (h)
        OSRSetAxisMappingStrategy(h, OAMS_TRADITIONAL_GIS_ORDER);
    return h;
}

static sl_status make_frame(gis *s)
{
    feat *fs = s->feats.data;
    size_t n = s->feats.count;
    if (!s->o->metric) {
        /* every layer that contributes needs a CRS */
        for (uint32_t i = 0; i < s->layer_count; i++) {
            layer_info *li = &s->layers[i];
            if (!li->kept)
                continue;
            if (!li->srs)
                return sl_fail(s->err, SL_ERROR_UNSUPPORTED,
                               "%s: layer '%s' has no coordinate reference system (a shapefile without its .prj?): "
                               "give one (--crs EPSG:NNNN) or say the coordinates are metres (--metric)",
                               s->path, li->name);
            li->to_geo = OCTNewCoordinateTransformation(li->srs, s->geo);
            if (!li->to_geo)
                return sl_fail(s->err, SL_ERROR_UNSUPPORTED, "%s: layer '%s': no transformation from its CRS to WGS 84", s->path,
                               li->name);
        }
        /* centres to longitude/latitude; a geographic CRS with coordinates out of range is a
         * projected file mislabelled (GeoJSON without a crs member is WGS 84 by its rule) */
        size_t kept = 0, out_of_range = 0;
        for (size_t i = 0; i < n; i++) {
            layer_info *li = &s->layers[fs[i].layer];
            double x = fs[i].cx, y = fs[i].cy, z = 0;
            bool geographic = OSRIsGeographic(li->srs) != 0;
            int ok = 0;
            if (geographic && !(fabs(x) <= 180 && fabs(y) <= 90)) {
                out_of_range++;
                warn(s, &s->st->dropped_transform,
                     "%s: layer '%s', feature %lld: coordinates (%g, %g) are outside longitude/latitude range", s->path,
                     li->name, (long long)fs[i].fid, x, y);
            } else {
                ok = OCTTransform(li->to_geo, 1, &x, &y, &z);
                if (!ok || !isfinite(x) || !isfinite(y))
                    warn(s, &s->st->dropped_transform, "%s: layer '%s', feature %lld: its coordinates do not reproject to WGS 84",
                         s->path, li->name, (long long)fs[i].fid);
            }
            if (!ok || !isfinite(x) || !isfinite(y)) {
                feat_free(s, &fs[i]);
                continue;
            }
            fs[i].cx = x, fs[i].cy = y;
            fs[kept++] = fs[i];
        }
        s->feats.count = n = kept;
        if (!n && out_of_range)
            return sl_fail(s->err, SL_ERROR_FORMAT,
                           "%s: every feature lies outside longitude/latitude range, but its CRS is geographic: the "
                           "coordinates look projected (give --crs EPSG:NNNN, or --metric for local metres)",
                           s->path);
    }
    if (!n)
        return SL_OK;
    double *v = sl_alloc(s->a, n * sizeof(double));
    if (!v)
        return sl_fail(s->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", s->path);
    double c[2];
    for (int k = 0; k < 2; k++) {
        for (size_t i = 0; i < n; i++)
            v[i] = k ? fs[i].cy : fs[i].cx;
        qsort(v, n, sizeof(double), cmp_double);
        c[k] = v[n / 2];
    }
    sl_free(s->a, v, n * sizeof(double));
    if (s->o->metric) {
        s->ox = c[0], s->oy = c[1];
        s->st->origin_lon = s->st->origin_lat = NAN;
        snprintf(s->st->crs, sizeof s->st->crs, "metric (local)");
        return SL_OK;
    }
    s->st->origin_lon = c[0], s->st->origin_lat = c[1];
    s->local = new_srs();
    if (!s->local || OSRSetWellKnownGeogCS(s->local, "WGS84") != OGRERR_NONE ||
        OSRSetTM(s->local, c[1], c[0], 1.0, 0.0, 0.0) != OGRERR_NONE)
        return sl_fail(s->err, SL_ERROR_INTERNAL, "%s: could not set up the local transverse Mercator at %.6f, %.6f", s->path,
                       c[0], c[1]);
    const char *crs_name = NULL;
    for (uint32_t i = 0; i < s->layer_count; i++) {
        layer_info *li = &s->layers[i];
        if (!li->kept)
            continue;
        if (!crs_name)
            crs_name = OSRGetName(li->srs);
        li->to_local = OCTNewCoordinateTransformation(li->srs, s->local);
        if (!li->to_local)
            return sl_fail(s->err, SL_ERROR_UNSUPPORTED, "%s: layer '%s': no transformation to the local frame", s->path,
                           li->name);
    }
    snprintf(s->st->crs, sizeof s->st->crs, "%s", crs_name ? crs_name : "unnamed");
    return SL_OK;
}

/* ---- meshes ---- */

static bool mesh_vertex(gis *s, double x, double y, double z)
{
    float p[3] = {(float)x, (float)y, (float)z};
    sl_aabb_grow(&s->bounds, (sl_vec3){p[0], p[1], p[2]});
    return sl_array_push(s->a, &s->pos, 3 * sizeof(float), p, 1) != NULL;
}

static bool mesh_tri(gis *s, uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t t[3] = {a, b, c};
    return sl_array_push(s->a, &s->idx, 3 * sizeof(uint32_t), t, 1) != NULL;
}

/* A quad p0 p1 p2 p3 (counter-clockwise seen from its front). */
static bool mesh_quad(gis *s, double q[4][3])
{
    uint32_t b = (uint32_t)s->pos.count;
    for (int k = 0; k < 4; k++)
        if (!mesh_vertex(s, q[k][0], q[k][1], q[k][2]))
            return false;
    return mesh_tri(s, b, b + 1, b + 2) && mesh_tri(s, b, b + 2, b + 3);
}

static double ring_area(const double *xy, int n)
{
    double a = 0;
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        a += xy[2 * i] * xy[2 * j + 1] - xy[2 * j] * xy[2 * i + 1];
    }
    return 0.5 * a;
}

static void ring_reverse(double *xy, int n)
{
    for (int i = 0, j = n - 1; i < j; i++, j--) {
        double tx = xy[2 * i], ty = xy[2 * i + 1];
        xy[2 * i] = xy[2 * j], xy[2 * i + 1] = xy[2 * j + 1];
        xy[2 * j] = tx, xy[2 * j + 1] = ty;
    }
}

/* Walls of one ring from z0 to z1: the exterior counter-clockwise, holes clockwise, so the solid
 * is on the left and every wall faces out. */
static bool ring_walls(gis *s, const double *xy, int n, double z0, double z1)
{
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        double q[4][3] = {{xy[2 * i], xy[2 * i + 1], z0},
                          {xy[2 * j], xy[2 * j + 1], z0},
                          {xy[2 * j], xy[2 * j + 1], z1},
                          {xy[2 * i], xy[2 * i + 1], z1}};
        if (!mesh_quad(s, q))
            return false;
    }
    return true;
}

typedef struct tri_sink {
    gis *s;
    double z;
    bool up;       /* counter-clockwise seen from +z */
    bool footprint; /* add each triangle as a footprint instead of as mesh */
    double base, roof;
    uint32_t object;
    bool ok;
    uint32_t added;
} tri_sink;

static bool on_triangle(void *user, const GEOSGeometry *poly)
{
    tri_sink *t = user;
    gis *s = t->s;
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(s->g.h, poly);
    int n = ring ? sl_geos_ring_coords(&s->g, ring, s->a, &s->ring, &s->ring_cap) : -1;
    if (n != 3) {
        t->ok = n >= 0 || !ring;
        return true; /* not a triangle: nothing to add */
    }
    double *xy = s->ring;
    double area = ring_area(xy, 3);
    if (!(fabs(area) > 1e-9))
        return true;
    if ((area > 0) != t->up)
        ring_reverse(xy, 3);
    if (t->footprint) {
        float f[6];
        for (int k = 0; k < 6; k++)
            f[k] = (float)xy[k];
        sl_footprint_desc fd = {f, 3, (float)t->base, (float)t->roof, t->object};
        sl_error e;
        if (sl_scene_add_footprint(s->scene, &fd, NULL, &e) == SL_OK)
            t->added++;
        return true; /* a triangle that rounds to nothing in floats is left out: the footprint
                        only needs to lie inside the building */
    }
    uint32_t b = (uint32_t)s->pos.count;
    for (int k = 0; k < 3; k++)
        if (!mesh_vertex(s, xy[2 * k], xy[2 * k + 1], t->z)) {
            t->ok = false;
            return false;
        }
    if (!mesh_tri(s, b, b + 1, b + 2)) {
        t->ok = false;
        return false;
    }
    return true;
}

/* Triangulate polygon (holes allowed) into the mesh at height z, or as footprints. */
static bool triangles(gis *s, const GEOSGeometry *poly, tri_sink *t)
{
    GEOSGeometry *tris = GEOSConstrainedDelaunayTriangulation_r(s->g.h, poly);
    if (!tris)
        return false;
    t->ok = true;
    bool ok = sl_geos_each_polygon(&s->g, tris, on_triangle, t) && t->ok;
    GEOSGeom_destroy_r(s->g.h, tris);
    return ok;
}

/* ---- buildings ---- */

/* One footprint from a hole-free polygon's exterior ring; its triangles when the ring does not
 * pass the scene's simple-polygon check in floats. */
static bool footprint_of(gis *s, const GEOSGeometry *poly, double base, double roof, uint32_t object)
{
    const GEOSGeometry *ring = GEOSGetExteriorRing_r(s->g.h, poly);
    int n = ring ? sl_geos_ring_coords(&s->g, ring, s->a, &s->ring, &s->ring_cap) : -1;
    if (n < 3)
        return n >= 0 || !ring;
    float *f = sl_alloc(s->a, 2 * (size_t)n * sizeof(float));
    if (!f)
        return false;
    for (int k = 0; k < 2 * n; k++)
        f[k] = (float)s->ring[k];
    sl_footprint_desc fd = {f, (uint32_t)n, (float)base, (float)roof, object};
    sl_error e;
    sl_status stt = sl_scene_add_footprint(s->scene, &fd, NULL, &e);
    sl_free(s->a, f, 2 * (size_t)n * sizeof(float));
    if (stt == SL_OK) {
        s->st->footprints++;
        return true;
    }
    if (stt == SL_ERROR_OUT_OF_MEMORY)
        return false;
    tri_sink t = {.s = s, .up = true, .footprint = true, .base = base, .roof = roof, .object = object};
    bool ok = triangles(s, poly, &t);
    s->st->footprints += t.added;
    return ok;
}

/* The footprints of one cleaned polygon: itself without holes; with holes, cut by a 2 cm strip
 * through each hole (every hole then opens onto the outside) into hole-free pieces. */
static bool footprints(gis *s, const GEOSGeometry *poly, double base, double roof, uint32_t object)
{
    GEOSContextHandle_t h = s->g.h;
    int holes = GEOSGetNumInteriorRings_r(h, poly);
    if (holes <= 0)
        return footprint_of(s, poly, base, roof, object);
    double ymin, ymax, xmin, xmax;
    if (!GEOSGeom_getYMin_r(h, poly, &ymin) || !GEOSGeom_getYMax_r(h, poly, &ymax))
        return false;
    GEOSGeometry **strips = sl_calloc(s->a, (size_t)holes, sizeof(GEOSGeometry *));
    if (!strips)
        return false;
    bool ok = true;
    for (int k = 0; k < holes && ok; k++) {
        const GEOSGeometry *hr = GEOSGetInteriorRingN_r(h, poly, k);
        ok = hr && GEOSGeom_getXMin_r(h, hr, &xmin) && GEOSGeom_getXMax_r(h, hr, &xmax);
        if (ok) {
            double cx = 0.5 * (xmin + xmax);
            float r[8] = {(float)(cx - 0.01), (float)(ymin - 1), (float)(cx + 0.01), (float)(ymin - 1),
                          (float)(cx + 0.01), (float)(ymax + 1), (float)(cx - 0.01), (float)(ymax + 1)};
            strips[k] = sl_geos_polygon(&s->g, r, 4);
            ok = strips[k] != NULL;
        }
    }
    if (!ok) {
        for (int k = 0; k < holes; k++)
            if (strips[k])
                GEOSGeom_destroy_r(h, strips[k]);
        sl_free(s->a, strips, (size_t)holes * sizeof(GEOSGeometry *));
        return false;
    }
    GEOSGeometry *coll = sl_geos_collection(&s->g, strips, (uint32_t)holes);
    sl_free(s->a, strips, (size_t)holes * sizeof(GEOSGeometry *));
    GEOSGeometry *cut = NULL;
    if (coll) {
        GEOSGeometry *u = GEOSUnaryUnion_r(h, coll);
        GEOSGeom_destroy_r(h, coll);
        if (u) {
            cut = GEOSDifference_r(h, poly, u);
            GEOSGeom_destroy_r(h, u);
        }
    }
    if (!cut) { /* GEOS could not cut: the triangles are footprints too */
        tri_sink t = {.s = s, .up = true, .footprint = true, .base = base, .roof = roof, .object = object};
        ok = triangles(s, poly, &t);
        s->st->footprints += t.added;
        return ok;
    }
    int np = GEOSGetNumGeometries_r(h, cut);
    for (int i = 0; i < np && ok; i++) {
        const GEOSGeometry *piece = GEOSGetGeometryN_r(h, cut, i);
        if (!piece || GEOSGeomTypeId_r(h, piece) != GEOS_POLYGON || GEOSisEmpty_r(h, piece))
            continue;
        double area = 0;
        if (!GEOSArea_r(h, piece, &area) || area < 0.05)
            continue;
        if (GEOSGetNumInteriorRings_r(h, piece) == 0) {
            ok = footprint_of(s, piece, base, roof, object);
        } else {
            tri_sink t = {.s = s, .up = true, .footprint = true, .base = base, .roof = roof, .object = object};
            ok = triangles(s, piece, &t);
            s->st->footprints += t.added;
        }
    }
    GEOSGeom_destroy_r(h, cut);
    return ok;
}

/* Mesh of one cleaned polygon: walls of every ring, roof and floor. With a roof height and no
 * holes: walls to the eave, a band sloping inward by the roof height to a flat top (the roof's
 * outline inset by that much; less, down to a flat roof, where the polygon is too thin). */
static bool polygon_mesh(gis *s, const GEOSGeometry *poly, double base, double eave, double top)
{
    GEOSContextHandle_t h = s->g.h;
    int holes = GEOSGetNumInteriorRings_r(h, poly);
    if (holes < 0)
        return false;
    bool sloped = false;
    for (int k = -1; k < holes; k++) {
        const GEOSGeometry *ring = k < 0 ? GEOSGetExteriorRing_r(h, poly) : GEOSGetInteriorRingN_r(h, poly, k);
        int n = ring ? sl_geos_ring_coords(&s->g, ring, s->a, &s->ring, &s->ring_cap) : -1;
        if (n < 3)
            continue;
        double a = ring_area(s->ring, n);
        if ((k < 0) != (a > 0))
            ring_reverse(s->ring, n);
        if (k < 0 && holes == 0 && top > eave) {
            /* the sloped roof, when the outline can be inset */
            size_t bytes = 2 * (size_t)n * sizeof(sl_dvec2);
            sl_dvec2 *p = sl_alloc(s->a, bytes);
            if (!p)
                return false;
            sl_dvec2 *q = p + n;
            for (int i = 0; i < n; i++)
                p[i].x = s->ring[2 * i], p[i].y = s->ring[2 * i + 1];
            double d = top - eave;
            bool inset = false;
            for (int tries = 0; tries < 4 && !inset; tries++, d *= 0.5)
                inset = sl_inset_polygon(p, (uint32_t)n, d, q);
            uint32_t *work = inset ? sl_alloc(s->a, (size_t)n * sizeof(uint32_t) * 4) : NULL;
            if (inset && !work) {
                sl_free(s->a, p, bytes);
                return false;
            }
            /* the flat top must triangulate; if it does not, the roof is flat */
            if (inset && !sl_ear_clip(q, (uint32_t)n, work, work + n)) {
                sl_free(s->a, work, (size_t)n * sizeof(uint32_t) * 4);
                work = NULL;
                inset = false;
            }
            if (inset) {
                bool ok = ring_walls(s, s->ring, n, base, eave);
                for (int i = 0; i < n && ok; i++) {
                    int j = (i + 1) % n;
                    double quad[4][3] = {{p[i].x, p[i].y, eave}, {p[j].x, p[j].y, eave}, {q[j].x, q[j].y, top},
                                         {q[i].x, q[i].y, top}};
                    ok = mesh_quad(s, quad);
                }
                if (ok) {
                    uint32_t b = (uint32_t)s->pos.count;
                    for (int i = 0; i < n && ok; i++)
                        ok = mesh_vertex(s, q[i].x, q[i].y, top);
                    for (int t = 0; t < n - 2 && ok; t++)
                        ok = mesh_tri(s, b + work[n + 3 * t], b + work[n + 3 * t + 1], b + work[n + 3 * t + 2]);
                }
                if (work)
                    sl_free(s->a, work, (size_t)n * sizeof(uint32_t) * 4);
                sl_free(s->a, p, bytes);
                if (!ok)
                    return false;
                sloped = true;
                continue;
            }
            sl_free(s->a, p, bytes);
        }
        if (!ring_walls(s, s->ring, n, base, top))
            return false;
    }
    tri_sink floor = {.s = s, .z = base, .up = false};
    if (!triangles(s, poly, &floor))
        return false;
    if (!sloped) {
        tri_sink roof = {.s = s, .z = top, .up = true};
        if (!triangles(s, poly, &roof))
            return false;
    }
    return true;
}

/* Append ring k of OGR polygon `poly` (local coordinates) to a GEOS ring: duplicate points
 * dropped, closed. NULL (with *bad set) when it has fewer than three distinct points. */
static GEOSGeometry *ogr_ring(gis *s, const feat *f, OGRGeometryH r, bool *bad)
{
    int np = OGR_G_GetPointCount(r);
    *bad = false;
    if (np < 3) {
        *bad = true;
        return NULL;
    }
    double *xy = sl_alloc(s->a, 2 * ((size_t)np + 1) * sizeof(double));
    if (!xy)
        return NULL;
    int n = 0;
    for (int i = 0; i < np; i++) {
        double x = OGR_G_GetX(r, i), y = OGR_G_GetY(r, i);
        if (n > 0 && fabs(x - xy[2 * (n - 1)]) < WELD && fabs(y - xy[2 * (n - 1) + 1]) < WELD)
            continue;
        xy[2 * n] = x, xy[2 * n + 1] = y;
        n++;
    }
    if (n >= 2 && !(fabs(xy[0] - xy[2 * (n - 1)]) < WELD && fabs(xy[1] - xy[2 * (n - 1) + 1]) < WELD)) {
        if (OGR_G_GetX(r, 0) != OGR_G_GetX(r, np - 1) || OGR_G_GetY(r, 0) != OGR_G_GetY(r, np - 1))
            warn(s, &s->st->unclosed_rings, "%s: layer '%s', feature %lld: a ring does not end where it begins (closed)",
                 s->path, layer_name(s, f->layer), (long long)f->fid);
    } else if (n >= 2) {
        n--; /* drop the closing point: added back below */
    }
    GEOSGeometry *ring = NULL;
    if (n >= 3) {
        GEOSCoordSequence *cs = GEOSCoordSeq_create_r(s->g.h, (unsigned)n + 1, 2);
        bool ok = cs != NULL;
        for (int i = 0; i <= n && ok; i++)
            ok = GEOSCoordSeq_setXY_r(s->g.h, cs, (unsigned)i, xy[2 * (i % n)], xy[2 * (i % n) + 1]) != 0;
        if (ok)
            ring = GEOSGeom_createLinearRing_r(s->g.h, cs);
        else if (cs)
            GEOSCoordSeq_destroy_r(s->g.h, cs);
    } else {
        *bad = true;
    }
    sl_free(s->a, xy, 2 * ((size_t)np + 1) * sizeof(double));
    return ring;
}

typedef struct part_list {
    GEOSGeometry **g;
    size_t n, cap;
} part_list;

static bool parts_push(gis *s, part_list *p, GEOSGeometry *g)
{
    if (p->n == p->cap) {
        size_t cap = p->cap ? 2 * p->cap : 8;
        GEOSGeometry **ng = sl_realloc(s->a, p->g, p->cap * sizeof *ng, cap * sizeof *ng);
        if (!ng)
            return false;
        p->g = ng, p->cap = cap;
    }
    p->g[p->n++] = g;
    return true;
}

/* Every polygon of OGR geometry g (recursively through collections, surfaces and TINs) as a valid
 * GEOS geometry appended to parts. false only for out-of-memory/GEOS failures. */
static bool collect_polygons(gis *s, const feat *f, OGRGeometryH g, part_list *parts, uint32_t *bad_rings)
{
    OGRwkbGeometryType t = wkbFlatten(OGR_G_GetGeometryType(g));
    if (t == wkbPolygon || t == wkbTriangle) {
        int nr = OGR_G_GetGeometryCount(g);
        if (nr <= 0)
            return true;
        bool bad;
        GEOSGeometry *shell = ogr_ring(s, f, OGR_G_GetGeometryRef(g, 0), &bad);
        if (!shell) {
            *bad_rings += 1;
            return bad;
        }
        GEOSGeometry **holes = nr > 1 ? sl_calloc(s->a, (size_t)nr - 1, sizeof(GEOSGeometry *)) : NULL;
        if (nr > 1 && !holes) {
            GEOSGeom_destroy_r(s->g.h, shell);
            return false;
        }
        unsigned nh = 0;
        for (int k = 1; k < nr; k++) {
            GEOSGeometry *hr = ogr_ring(s, f, OGR_G_GetGeometryRef(g, k), &bad);
            if (hr)
                holes[nh++] = hr;
            else if (bad)
                *bad_rings += 1;
        }
        GEOSGeometry *poly = GEOSGeom_createPolygon_r(s->g.h, shell, holes, nh);
        if (holes)
            sl_free(s->a, holes, ((size_t)nr - 1) * sizeof(GEOSGeometry *));
        if (!poly)
            return false;
        char valid = GEOSisValid_r(s->g.h, poly);
        if (valid != 1) {
            char *why = GEOSisValidReason_r(s->g.h, poly);
            warn(s, &s->st->repaired, "%s: layer '%s', feature %lld: polygon not valid (%s): made valid", s->path,
                 layer_name(s, f->layer), (long long)f->fid, why ? why : "self-intersection");
            if (why)
                GEOSFree_r(s->g.h, why);
            GEOSGeometry *v = GEOSMakeValid_r(s->g.h, poly);
            GEOSGeom_destroy_r(s->g.h, poly);
            if (!v)
                return false;
            poly = v;
        }
        if (!parts_push(s, parts, poly)) {
            GEOSGeom_destroy_r(s->g.h, poly);
            return false;
        }
        return true;
    }
    int n = OGR_G_GetGeometryCount(g);
    for (int i = 0; i < n; i++)
        if (!collect_polygons(s, f, OGR_G_GetGeometryRef(g, i), parts, bad_rings))
            return false;
    return true;
}

/* Every point of g finite and within max_extent of the origin. */
static bool coords_ok(gis *s, OGRGeometryH g, bool *nonfinite)
{
    int n = OGR_G_GetGeometryCount(g);
    if (n > 0) {
        for (int i = 0; i < n; i++)
            if (!coords_ok(s, OGR_G_GetGeometryRef(g, i), nonfinite))
                return false;
        return true;
    }
    int np = OGR_G_GetPointCount(g);
    for (int i = 0; i < np; i++) {
        double x = OGR_G_GetX(g, i), y = OGR_G_GetY(g, i);
        if (!isfinite(x) || !isfinite(y)) {
            *nonfinite = true;
            return false;
        }
        if (!(fabs(x) <= s->max_extent && fabs(y) <= s->max_extent))
            return false;
    }
    return true;
}

typedef struct poly_sink {
    gis *s;
    const feat *f;
    part_list keep;
    bool oom;
} poly_sink;

static bool on_clean_polygon(void *user, const GEOSGeometry *poly)
{
    poly_sink *p = user;
    gis *s = p->s;
    double area = 0;
    if (!GEOSArea_r(s->g.h, poly, &area) || !(area >= s->min_area)) {
        warn(s, &s->st->dropped_small, "%s: layer '%s', feature %lld: a polygon of %.3g m^2 (under %g m^2) left out", s->path,
             layer_name(s, p->f->layer), (long long)p->f->fid, area, s->min_area);
        return true;
    }
    GEOSGeometry *c = GEOSGeom_clone_r(s->g.h, poly);
    if (!c || !parts_push(s, &p->keep, c)) {
        if (c)
            GEOSGeom_destroy_r(s->g.h, c);
        p->oom = true;
        return false;
    }
    return true;
}

static sl_status oom(gis *s)
{
    return sl_fail(s->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", s->path);
}

static uint32_t building_color(double height, int64_t fid)
{
    uint32_t h = (uint32_t)(fid * 2654435761u);
    int base = 150 + (int)SL_MIN(80.0, height);
    int r = base + (int)(h & 15), g = base - 6 + (int)((h >> 4) & 15), b = base - 16 + (int)((h >> 8) & 15);
    r = SL_MIN(r, 255), g = SL_MIN(g, 255), b = SL_MIN(b, 255);
    return (uint32_t)r << 24 | (uint32_t)g << 16 | (uint32_t)b << 8 | 0xffu;
}

static sl_status emit_building(gis *s, feat *f)
{
    GEOSContextHandle_t h = s->g.h;
    const char *ln = layer_name(s, f->layer);
    double zlo = INFINITY, zhi = -INFINITY;
    if (OGR_G_Is3D(f->geom))
        z_range(f->geom, &zlo, &zhi);
    part_list parts = {0};
    uint32_t bad_rings = 0;
    s->g.message[0] = 0;
    if (!collect_polygons(s, f, f->geom, &parts, &bad_rings)) {
        for (size_t i = 0; i < parts.n; i++)
            GEOSGeom_destroy_r(h, parts.g[i]);
        sl_free(s->a, parts.g, parts.cap * sizeof(GEOSGeometry *));
        return sl_fail(s->err, SL_ERROR_INTERNAL, "%s: layer '%s', feature %lld: GEOS failed: %s", s->path, ln,
                       (long long)f->fid, s->g.message[0] ? s->g.message : "out of memory");
    }
    if (!parts.n) {
        warn(s, &s->st->dropped_invalid, "%s: layer '%s', feature %lld: no ring with three distinct points", s->path, ln,
             (long long)f->fid);
        sl_free(s->a, parts.g, parts.cap * sizeof(GEOSGeometry *));
        return SL_OK;
    }
    /* one geometry: the union of the parts (overlapping parts of a multipolygon, the faces of a
     * CityGML solid seen from above), simplified by a centimetre */
    GEOSGeometry *all = parts.n == 1 ? parts.g[0] : GEOSGeom_createCollection_r(h, GEOS_GEOMETRYCOLLECTION, parts.g, (unsigned)parts.n);
    if (!all) {
        for (size_t i = 0; i < parts.n; i++)
            GEOSGeom_destroy_r(h, parts.g[i]);
    }
    sl_free(s->a, parts.g, parts.cap * sizeof(GEOSGeometry *));
    if (!all)
        return oom(s);
    GEOSGeometry *u = GEOSUnaryUnion_r(h, all);
    GEOSGeom_destroy_r(h, all);
    GEOSGeometry *clean = u ? GEOSTopologyPreserveSimplify_r(h, u, SIMPLIFY) : NULL;
    if (u)
        GEOSGeom_destroy_r(h, u);
    if (!clean)
        return sl_fail(s->err, SL_ERROR_INTERNAL, "%s: layer '%s', feature %lld: GEOS could not clean the polygon: %s", s->path,
                       ln, (long long)f->fid, s->g.message);
    poly_sink ps = {.s = s, .f = f};
    sl_geos_each_polygon(&s->g, clean, on_clean_polygon, &ps);
    GEOSGeom_destroy_r(h, clean);
    sl_status st = SL_OK;
    if (ps.oom) {
        st = oom(s);
        goto done;
    }
    if (!ps.keep.n) {
        s->st->dropped_invalid++;
        goto done;
    }
    /* heights */
    double height = f->height, base = isfinite(f->min_height) ? f->min_height : 0;
    if (!isfinite(height) && zhi > zlo + 0.5)
        height = zhi - zlo; /* CityGML and other 3D solids: their own height */
    if (!isfinite(height)) {
        warn(s, &s->st->default_height, "%s: layer '%s', feature %lld: no height or levels: %g m used", s->path, ln,
             (long long)f->fid, s->default_height);
        height = s->default_height;
    }
    if (!(base < height - 0.1))
        base = 0;
    double eave = height;
    if (isfinite(f->roof_height) && f->roof_height < 0.8 * (height - base))
        eave = height - f->roof_height;
    s->pos.count = s->idx.count = 0;
    for (size_t i = 0; i < ps.keep.n; i++)
        if (!polygon_mesh(s, ps.keep.g[i], base, ps.keep.n == 1 ? eave : height, height)) {
            st = sl_fail(s->err, SL_ERROR_INTERNAL, "%s: layer '%s', feature %lld: could not build its mesh: %s", s->path, ln,
                         (long long)f->fid, s->g.message[0] ? s->g.message : "out of memory");
            goto done;
        }
    if (!s->idx.count) {
        s->st->dropped_invalid++;
        goto done;
    }
    sl_mesh_desc md = {.positions = s->pos.data, .vertex_count = (uint32_t)s->pos.count, .indices = s->idx.data,
                       .triangle_count = (uint32_t)s->idx.count};
    uint32_t mesh, object;
    if ((st = sl_scene_add_mesh(s->scene, &md, &mesh, s->err)) != SL_OK)
        goto done;
    sl_object_desc od = {.mesh = mesh, .color = building_color(height, f->fid), .kind = SL_KIND_BUILDING,
                         .flags = SL_OBJECT_OCCLUDER};
    if ((st = sl_scene_add_object(s->scene, &od, &object, s->err)) != SL_OK)
        goto done;
    if (sl_scene_set_object_name(s->scene, object, f->name, NULL) != SL_OK) {
        char fallback[160];
        snprintf(fallback, sizeof fallback, "%s/%lld", ln, (long long)f->fid);
        sl_scene_set_object_name(s->scene, object, fallback, NULL);
    }
    s->st->buildings++;
    s->st->building_parts += (uint32_t)ps.keep.n;
    for (size_t i = 0; i < ps.keep.n; i++)
        if (!footprints(s, ps.keep.g[i], base, ps.keep.n == 1 ? eave : height, object)) {
            st = sl_fail(s->err, SL_ERROR_INTERNAL, "%s: layer '%s', feature %lld: could not make its footprint: %s", s->path,
                         ln, (long long)f->fid, s->g.message[0] ? s->g.message : "out of memory");
            goto done;
        }
done:
    for (size_t i = 0; i < ps.keep.n; i++)
        GEOSGeom_destroy_r(h, ps.keep.g[i]);
    sl_free(s->a, ps.keep.g, ps.keep.cap * sizeof(GEOSGeometry *));
    return st;
}

/* ---- streets ---- */

static bool street_line(gis *s, const feat *f, OGRGeometryH g)
{
    int n = OGR_G_GetGeometryCount(g);
    if (n > 0) {
        for (int i = 0; i < n; i++)
            if (!street_line(s, f, OGR_G_GetGeometryRef(g, i)))
                return false;
        return true;
    }
    int np = OGR_G_GetPointCount(g);
    double w = f->width;
    for (int i = 0; i + 1 < np; i++) {
        double ax = OGR_G_GetX(g, i), ay = OGR_G_GetY(g, i), bx = OGR_G_GetX(g, i + 1), by = OGR_G_GetY(g, i + 1);
        double dx = bx - ax, dy = by - ay, len = hypot(dx, dy);
        if (!(len >= 0.05))
            continue;
        double ux = dx / len, uy = dy / len, h = 0.5 * w;
        /* the segment's rectangle, carried on by half the width at both ends so that the corners
         * of a bend are covered */
        double sx = ax - ux * h, sy = ay - uy * h, ex = bx + ux * h, ey = by + uy * h;
        float q[8] = {(float)(sx + uy * h), (float)(sy - ux * h), (float)(ex + uy * h), (float)(ey - ux * h),
                      (float)(ex - uy * h), (float)(ey + ux * h), (float)(sx - uy * h), (float)(sy + ux * h)};
        sl_error e;
        if (sl_scene_add_street_polygon(s->scene, q, 4, &e) != SL_OK) {
            if (e.status == SL_ERROR_OUT_OF_MEMORY)
                return false;
            continue;
        }
        for (int k = 0; k < 4; k++)
            sl_aabb_grow(&s->bounds, (sl_vec3){q[2 * k], q[2 * k + 1], 0});
        street_seg sg = {ax, ay, bx, by, (float)w, f->street_flags};
        if (!sl_array_push(s->a, &s->seg_info, sizeof sg, &sg, 1))
            return false;
        s->st->street_segments++;
    }
    return true;
}

static int cmp_node(const void *a, const void *b)
{
    const node_key *x = a, *y = b;
    if (x->qx != y->qx)
        return x->qx < y->qx ? -1 : 1;
    if (x->qy != y->qy)
        return x->qy < y->qy ? -1 : 1;
    return 0;
}

/* Noding: street lines that cross without a shared vertex (common outside OpenStreetMap) are
 * split where they cross (GEOSNode), so that the graph joins them there; each piece takes the
 * width and flags of the segment it lies on (found through an STR tree). */
typedef struct seg_query {
    const street_seg *in;
    double mx, my, best;
    size_t best_i;
} seg_query;

static void on_seg_candidate(void *item, void *user)
{
    seg_query *q = user;
    size_t i = (size_t)(uintptr_t)item - 1;
    const street_seg *g = &q->in[i];
    double dx = g->bx - g->ax, dy = g->by - g->ay, l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((q->mx - g->ax) * dx + (q->my - g->ay) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double d = hypot(g->ax + t * dx - q->mx, g->ay + t * dy - q->my);
    if (d < q->best || (d == q->best && i < q->best_i))
        q->best = d, q->best_i = i;
}

static bool node_streets(gis *s, sl_array *out)
{
    GEOSContextHandle_t h = s->g.h;
    size_t ns = s->seg_info.count;
    const street_seg *in = s->seg_info.data;
    GEOSGeometry **lines = sl_calloc(s->a, ns, sizeof(GEOSGeometry *));
    if (!lines)
        return false;
    bool ok = true;
    for (size_t i = 0; i < ns && ok; i++) {
        GEOSCoordSequence *cs = GEOSCoordSeq_create_r(h, 2, 2);
        ok = cs && GEOSCoordSeq_setXY_r(h, cs, 0, in[i].ax, in[i].ay) && GEOSCoordSeq_setXY_r(h, cs, 1, in[i].bx, in[i].by);
        if (ok)
            ok = (lines[i] = GEOSGeom_createLineString_r(h, cs)) != NULL;
        else if (cs)
            GEOSCoordSeq_destroy_r(h, cs);
    }
    GEOSGeometry *coll = ok ? GEOSGeom_createCollection_r(h, GEOS_MULTILINESTRING, lines, (unsigned)ns) : NULL;
    if (!coll)
        for (size_t i = 0; i < ns; i++)
            if (lines[i])
                GEOSGeom_destroy_r(h, lines[i]);
    sl_free(s->a, lines, ns * sizeof(GEOSGeometry *));
    GEOSGeometry *noded = coll ? GEOSNode_r(h, coll) : NULL;
    GEOSSTRtree *tree = noded ? GEOSSTRtree_create_r(h, 10) : NULL;
    ok = tree != NULL;
    for (size_t i = 0; i < ns && ok; i++)
        GEOSSTRtree_insert_r(h, tree, GEOSGetGeometryN_r(h, coll, (int)i), (void *)(uintptr_t)(i + 1));
    int np = ok ? GEOSGetNumGeometries_r(h, noded) : 0;
    for (int k = 0; k < np && ok; k++) {
        const GEOSGeometry *piece = GEOSGetGeometryN_r(h, noded, k);
        const GEOSCoordSequence *cs = piece ? GEOSGeom_getCoordSeq_r(h, piece) : NULL;
        unsigned n = 0;
        if (!cs || !GEOSCoordSeq_getSize_r(h, cs, &n))
            continue;
        for (unsigned v = 0; v + 1 < n && ok; v++) {
            double ax, ay, bx, by;
            if (!GEOSCoordSeq_getXY_r(h, cs, v, &ax, &ay) || !GEOSCoordSeq_getXY_r(h, cs, v + 1, &bx, &by))
                continue;
            seg_query q = {in, 0.5 * (ax + bx), 0.5 * (ay + by), INFINITY, 0};
            GEOSGeometry *pt = GEOSGeom_createPointFromXY_r(h, q.mx, q.my);
            if (!pt) {
                ok = false;
                break;
            }
            GEOSSTRtree_query_r(h, tree, pt, on_seg_candidate, &q);
            GEOSGeom_destroy_r(h, pt);
            street_seg sg = {ax, ay, bx, by, isfinite(q.best) ? in[q.best_i].width : 6.0f,
                             isfinite(q.best) ? in[q.best_i].flags : 0u};
            ok = sl_array_push(s->a, out, sizeof sg, &sg, 1) != NULL;
        }
    }
    if (tree)
        GEOSSTRtree_destroy_r(h, tree);
    if (noded)
        GEOSGeom_destroy_r(h, noded);
    if (coll)
        GEOSGeom_destroy_r(h, coll);
    return ok;
}

static node_key key_of(double x, double y)
{
    return (node_key){(int64_t)llround(x * 100), (int64_t)llround(y * 100), (float)x, (float)y, 0};
}

/* The graph: segment ends within a centimetre are one node. */
static sl_status street_graph(gis *s)
{
    if (!s->seg_info.count)
        return SL_OK;
    sl_array noded = {0};
    if (!node_streets(s, &noded)) {
        sl_array_free(s->a, &noded, sizeof(street_seg));
        return sl_fail(s->err, SL_ERROR_INTERNAL, "%s: GEOS could not node the streets: %s", s->path,
                       s->g.message[0] ? s->g.message : "out of memory");
    }
    size_t ns = noded.count;
    const street_seg *info = noded.data;
    node_key *sorted = sl_alloc(s->a, 2 * ns * sizeof(node_key) + 1);
    sl_street_node *nodes = sl_alloc(s->a, 2 * ns * sizeof(sl_street_node) + 1);
    sl_street_edge *edges = sl_alloc(s->a, ns * sizeof(sl_street_edge) + 1);
    sl_status st = SL_OK;
    if (!sorted || !nodes || !edges) {
        st = oom(s);
        goto done;
    }
    for (size_t i = 0; i < ns; i++)
        sorted[2 * i] = key_of(info[i].ax, info[i].ay), sorted[2 * i + 1] = key_of(info[i].bx, info[i].by);
    qsort(sorted, 2 * ns, sizeof(node_key), cmp_node);
    uint32_t nn = 0;
    for (size_t i = 0; i < 2 * ns; i++) {
        if (i > 0 && cmp_node(&sorted[i], &sorted[i - 1]) == 0) {
            sorted[i].id = sorted[i - 1].id;
            continue;
        }
        sorted[i].id = nn;
        nodes[nn++] = (sl_street_node){sorted[i].x, sorted[i].y};
    }
    uint32_t ne = 0;
    for (size_t i = 0; i < ns; i++) {
        node_key ka = key_of(info[i].ax, info[i].ay), kb = key_of(info[i].bx, info[i].by);
        const node_key *a = bsearch(&ka, sorted, 2 * ns, sizeof(node_key), cmp_node);
        const node_key *b = bsearch(&kb, sorted, 2 * ns, sizeof(node_key), cmp_node);
        if (!a || !b || a->id == b->id)
            continue;
        edges[ne++] = (sl_street_edge){a->id, b->id, info[i].width, info[i].flags};
    }
    st = sl_scene_set_street_graph(s->scene, nodes, nn, edges, ne, s->err);
    s->st->street_nodes = nn;
done:
    sl_free(s->a, sorted, 2 * ns * sizeof(node_key) + 1);
    sl_free(s->a, nodes, 2 * ns * sizeof(sl_street_node) + 1);
    sl_free(s->a, edges, ns * sizeof(sl_street_edge) + 1);
    sl_array_free(s->a, &noded, sizeof(street_seg));
    return st;
}

/* ---- ground ---- */

static sl_status ground(gis *s)
{
    if (s->o->no_ground || !(s->bounds.min.x <= s->bounds.max.x))
        return SL_OK;
    double m = 20, x0 = s->bounds.min.x - m, y0 = s->bounds.min.y - m, x1 = s->bounds.max.x + m, y1 = s->bounds.max.y + m;
    double span = fmax(x1 - x0, y1 - y0), tile = fmax(100.0, span / 32);
    int nx = (int)ceil((x1 - x0) / tile), ny = (int)ceil((y1 - y0) / tile);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double ax = x0 + i * tile, ay = y0 + j * tile, bx = fmin(x1, ax + tile), by = fmin(y1, ay + tile);
            float p[12] = {(float)ax, (float)ay, 0, (float)bx, (float)ay, 0, (float)bx, (float)by, 0, (float)ax, (float)by, 0};
            uint32_t ix[6] = {0, 1, 2, 0, 2, 3}, mesh;
            sl_mesh_desc md = {.positions = p, .vertex_count = 4, .indices = ix, .triangle_count = 2};
            sl_status st = sl_scene_add_mesh(s->scene, &md, &mesh, s->err);
            if (st != SL_OK)
                return st;
            sl_object_desc od = {.mesh = mesh, .color = 0x8a8a84ffu, .kind = SL_KIND_GROUND};
            if ((st = sl_scene_add_object(s->scene, &od, NULL, s->err)) != SL_OK)
                return st;
            s->st->ground_tiles++;
        }
    return SL_OK;
}

/* ---- driver ---- */

static sl_status open_layers(gis *s)
{
    int n = GDALDatasetGetLayerCount(s->ds);
    if (n <= 0)
        return sl_fail(s->err, SL_ERROR_FORMAT, "%s: no layers", s->path);
    s->layers = sl_calloc(s->a, (size_t)n, sizeof(layer_info));
    if (!s->layers)
        return oom(s);
    s->layer_count = (uint32_t)n;
    for (int i = 0; i < n; i++) {
        layer_info *li = &s->layers[i];
        li->layer = GDALDatasetGetLayer(s->ds, i);
        sl_escape_text(OGR_L_GetName(li->layer), 100, li->name, sizeof li->name);
        layer_fields(li);
        OGRSpatialReferenceH srs = s->override ? s->override : OGR_L_GetSpatialRef(li->layer);
        li->srs = srs ? OSRClone(srs) : NULL; /* the layer's own is not ours to change */
        if (srs && !li->srs)
            return oom(s);
        if (li->srs)
            OSRSetAxisMappingStrategy(li->srs, OAMS_TRADITIONAL_GIS_ORDER);
        if (s->o->layers) {
            const char *p = s->o->layers;
            while (*p && !li->wanted) {
                size_t k = strcspn(p, ",");
                li->wanted = strlen(OGR_L_GetName(li->layer)) == k && !strncmp(OGR_L_GetName(li->layer), p, k);
                p += k;
                if (*p == ',')
                    p++;
            }
        } else {
            /* CityGML through the GML driver: the buildings' layers (not relief, water, roads) */
            li->wanted = strcmp(s->st->driver, "GML") != 0 || strcasestr(li->name, "building") != NULL;
        }
    }
    if (s->o->layers) { /* every name asked for must exist */
        const char *p = s->o->layers;
        while (*p) {
            size_t k = strcspn(p, ",");
            bool found = false;
            for (uint32_t i = 0; i < s->layer_count && !found; i++)
                found = strlen(OGR_L_GetName(s->layers[i].layer)) == k && !strncmp(OGR_L_GetName(s->layers[i].layer), p, k);
            if (!found && k) {
                char names[256] = "";
                for (uint32_t i = 0; i < s->layer_count; i++)
                    snprintf(names + strlen(names), sizeof names - strlen(names), "%s'%s'", i ? ", " : "", s->layers[i].name);
                char want[128];
                snprintf(want, sizeof want, "%.*s", (int)SL_MIN(k, sizeof want - 1), p);
                char esc[160];
                return sl_fail(s->err, SL_ERROR_NOT_FOUND, "%s: no layer '%s' (layers: %s)", s->path,
                               sl_escape_text(want, 100, esc, sizeof esc), names);
            }
            p += k;
            if (*p == ',')
                p++;
        }
    }
    for (uint32_t i = 0; i < s->layer_count; i++)
        s->st->layers += s->layers[i].wanted;
    return SL_OK;
}

static sl_status check_options(const sl_gis_options *o, sl_error *err)
{
    if (!(o->default_height == 0 || (o->default_height >= 0.1f && o->default_height <= MAX_HEIGHT)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "GIS options: default height %g is outside [0.1, %g] m",
                       (double)o->default_height, MAX_HEIGHT);
    if (!(o->level_height == 0 || (o->level_height >= 0.5f && o->level_height <= 20)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "GIS options: level height %g is outside [0.5, 20] m",
                       (double)o->level_height);
    if (!(o->max_extent == 0 || (o->max_extent >= 10 && o->max_extent <= 1e6f)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "GIS options: max extent %g is outside [10, 1e6] m",
                       (double)o->max_extent);
    if (!(o->min_area == 0 || (o->min_area > 0 && o->min_area <= 1e6f)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "GIS options: min area %g is outside (0, 1e6] m^2", (double)o->min_area);
    return SL_OK;
}

static sl_status run(gis *s)
{
    sl_status st;
    st = open_layers(s);
    if (st == SL_OK)
        st = read_features(s);
    if (st != SL_OK)
        return st;
    if (!s->feats.count)
        return sl_fail(s->err, SL_ERROR_FORMAT,
                       "%s: no buildings (polygons) or streets (lines) in %u layer%s of %u feature%s (%u other features)",
                       s->path, s->st->layers, s->st->layers == 1 ? "" : "s", s->st->features, s->st->features == 1 ? "" : "s",
                       s->st->other);
    if ((st = make_frame(s)) != SL_OK)
        return st;
    feat *fs = s->feats.data;
    for (size_t i = 0; i < s->feats.count; i++) {
        feat *f = &fs[i];
        layer_info *li = &s->layers[f->layer];
        if (s->o->progress.fn && (i & 255) == 0 &&
            !s->o->progress.fn(s->o->progress.user, "gis: buildings and streets", i, s->feats.count))
            return sl_fail(s->err, SL_ERROR_CANCELLED, "%s: cancelled", s->path);
        OGRGeometryH lin = OGR_G_GetLinearGeometry(f->geom, 0, NULL);
        if (!lin)
            return oom(s);
        OGR_G_DestroyGeometry(f->geom);
        f->geom = lin;
        bool transformed = true;
        if (!s->o->metric)
            transformed = OGR_G_Transform(f->geom, li->to_local) == OGRERR_NONE;
        if (!transformed) {
            warn(s, &s->st->dropped_transform, "%s: layer '%s', feature %lld: its coordinates do not reproject", s->path,
                 li->name, (long long)f->fid);
            feat_free(s, f);
            continue;
        }
        if (s->o->metric) {
            /* metric: shift by the origin (GDAL has no geometry translate in its C API: through
             * every point) */
            OGRGeometryH stack[64];
            int top = 0;
            stack[top++] = f->geom;
            while (top > 0) {
                OGRGeometryH g = stack[--top];
                int n = OGR_G_GetGeometryCount(g);
                if (n > 0) {
                    for (int k = 0; k < n; k++) {
                        if (top == 64) {
                            n = -1;
                            break;
                        }
                        stack[top++] = OGR_G_GetGeometryRef(g, k);
                    }
                    if (n < 0)
                        return sl_fail(s->err, SL_ERROR_LIMIT, "%s: layer '%s', feature %lld: geometry nested too deep",
                                       s->path, li->name, (long long)f->fid);
                    continue;
                }
                int np = OGR_G_GetPointCount(g);
                bool z = OGR_G_Is3D(g) != 0;
                for (int k = 0; k < np; k++) {
                    double x = OGR_G_GetX(g, k) - s->ox, y = OGR_G_GetY(g, k) - s->oy;
                    if (z)
                        OGR_G_SetPoint(g, k, x, y, OGR_G_GetZ(g, k));
                    else
                        OGR_G_SetPoint_2D(g, k, x, y);
                }
            }
        }
        bool nonfinite = false;
        if (!coords_ok(s, f->geom, &nonfinite)) {
            if (nonfinite)
                warn(s, &s->st->dropped_invalid, "%s: layer '%s', feature %lld: coordinates are not finite (NaN or infinite)",
                     s->path, li->name, (long long)f->fid);
            else
                warn(s, &s->st->dropped_far, "%s: layer '%s', feature %lld: lies more than %g m from the centre of the data",
                     s->path, li->name, (long long)f->fid, s->max_extent);
            feat_free(s, f);
            continue;
        }
        if (f->kind == FEAT_BUILDING) {
            if ((st = emit_building(s, f)) != SL_OK)
                return st;
        } else {
            uint32_t before = s->st->street_segments;
            if (!street_line(s, f, f->geom))
                return oom(s);
            if (s->st->street_segments > before)
                s->st->streets++;
            else
                warn(s, &s->st->dropped_invalid, "%s: layer '%s', feature %lld: a street without a segment of length",
                     s->path, li->name, (long long)f->fid);
        }
        feat_free(s, f);
    }
    if (!s->st->buildings && !s->st->streets)
        return sl_fail(s->err, SL_ERROR_FORMAT, "%s: nothing usable: %u features, none made a building or a street (first problem: %s)",
                       s->path, s->st->features, s->st->first_warning[0] ? s->st->first_warning : "none recorded");
    if ((st = street_graph(s)) != SL_OK || (st = ground(s)) != SL_OK)
        return st;
    /* metadata */
    char buf[160];
    sl_scene_set_meta(s->scene, "importer", "gis", NULL);
    if ((st = sl_scene_set_meta(s->scene, "gis.driver", s->st->driver, s->err)) != SL_OK ||
        (st = sl_scene_set_meta(s->scene, "gis.crs", s->st->crs, s->err)) != SL_OK)
        return st;
    if (s->o->metric)
        snprintf(buf, sizeof buf, "metric: file coordinates minus %.3f %.3f", s->ox, s->oy);
    else
        snprintf(buf, sizeof buf, "tmerc lat_0=%.8f lon_0=%.8f k=1 WGS84", s->st->origin_lat, s->st->origin_lon);
    if ((st = sl_scene_set_meta(s->scene, "gis.frame", buf, s->err)) != SL_OK)
        return st;
    snprintf(buf, sizeof buf, "%u", s->st->buildings);
    if ((st = sl_scene_set_meta(s->scene, "gis.buildings", buf, s->err)) != SL_OK)
        return st;
    snprintf(buf, sizeof buf, "%u", s->st->default_height);
    if ((st = sl_scene_set_meta(s->scene, "gis.default_heights", buf, s->err)) != SL_OK)
        return st;
    return sl_scene_set_source_file(s->scene, s->path, s->err);
}

static char *dup_or(const sl_allocator *a, const char *v, const char *dflt)
{
    return sl_strdup(a, v && *v ? v : dflt);
}

sl_status sl_import_gis(const char *path, const sl_gis_options *opt, const sl_allocator *alloc, sl_scene *out,
                        sl_gis_stats *stats, sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_gis: NULL argument");
    *out = NULL;
    sl_gis_options defaults = sl_gis_defaults();
    const sl_gis_options *o = opt ? opt : &defaults;
    sl_status st = check_options(o, err);
    if (st != SL_OK)
        return st;
    const char *driver = driver_for(path);
    if (!driver)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: not a GIS file by its extension (.geojson, .json, .shp, .osm, .pbf, .gml)",
                       path);
    struct stat sb;
    if (stat(path, &sb) != 0)
        return sl_fail(err, SL_ERROR_IO, "%s: %s", path, strerror(errno));
    if (!S_ISREG(sb.st_mode))
        return sl_fail(err, SL_ERROR_IO, "%s: not a regular file", path);
    if (sb.st_size == 0)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: empty file", path);
    const sl_allocator *a = sl_alloc_or_default(alloc);
    sl_gis_stats local_stats;
    gis s;
    memset(&s, 0, sizeof s);
    s.path = path, s.o = o, s.a = a, s.err = err;
    s.st = stats ? stats : &local_stats;
    memset(s.st, 0, sizeof *s.st);
    s.st->origin_lon = s.st->origin_lat = NAN;
    snprintf(s.st->driver, sizeof s.st->driver, "%s", driver);
    s.max_extent = o->max_extent > 0 ? o->max_extent : 50000.0;
    s.min_area = o->min_area > 0 ? o->min_area : 1.0;
    s.default_height = o->default_height > 0 ? o->default_height : 10.0;
    s.level_height = o->level_height > 0 ? o->level_height : 3.0;
    s.bounds = sl_aabb_empty();
    double t0 = sl_now();
    s.height_fields = dup_or(a, o->height_fields, DEFAULT_HEIGHT_FIELDS);
    s.levels_fields = dup_or(a, o->levels_fields, DEFAULT_LEVELS_FIELDS);
    if (!s.height_fields || !s.levels_fields) {
        st = oom(&s);
        goto done_strings;
    }
    pthread_once(&gdal_once, gdal_register);
    cpl_capture cap = {{0}};
    CPLPushErrorHandlerEx(on_cpl_error, &cap);
    if (!sl_geos_init(&s.g)) {
        st = sl_fail(err, SL_ERROR_INTERNAL, "%s: GEOS could not start", path);
        goto done_cpl;
    }
    s.geo = new_srs();
    if (!s.geo || OSRSetWellKnownGeogCS(s.geo, "WGS84") != OGRERR_NONE) {
        st = sl_fail(err, SL_ERROR_INTERNAL, "%s: could not set up WGS 84 (is GDAL's proj.db installed?)", path);
        goto done_geos;
    }
    if (o->crs && !o->metric) {
        s.override = new_srs();
        char esc[160];
        if (!s.override || OSRSetFromUserInput(s.override, o->crs) != OGRERR_NONE) {
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: CRS '%s' not understood: %s", path,
                         sl_escape_text(o->crs, 100, esc, sizeof esc), cap.last[0] ? cap.last : "unknown");
            goto done_geos;
        }
        OSRSetAxisMappingStrategy(s.override, OAMS_TRADITIONAL_GIS_ORDER);
    }
    const char *drivers[] = {driver, NULL};
    const char *gml_opts[] = {"WRITE_GFS=NO", NULL};
    s.ds = GDALOpenEx(path, GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers, !strcmp(driver, "GML") ? gml_opts : NULL, NULL);
    if (!s.ds) {
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: GDAL's %s driver cannot read it: %s", path, driver,
                     cap.last[0] ? cap.last : "not recognised");
        goto done_geos;
    }
    if ((st = sl_scene_create(alloc, &s.scene, err)) != SL_OK)
        goto done_ds;
    st = run(&s);
    if (st == SL_OK && cap.last[0] && !s.st->first_warning[0])
        snprintf(s.st->first_warning, sizeof s.st->first_warning, "GDAL: %.240s", cap.last);
done_ds:
    GDALClose(s.ds);
done_geos:
    for (size_t i = 0; i < s.feats.count; i++)
        feat_free(&s, &((feat *)s.feats.data)[i]);
    sl_array_free(a, &s.feats, sizeof(feat));
    for (uint32_t i = 0; i < s.layer_count; i++) {
        if (s.layers[i].to_geo)
            OCTDestroyCoordinateTransformation(s.layers[i].to_geo);
        if (s.layers[i].to_local)
            OCTDestroyCoordinateTransformation(s.layers[i].to_local);
        if (s.layers[i].srs)
            OSRRelease(s.layers[i].srs);
    }
    if (s.layers)
        sl_free(a, s.layers, s.layer_count * sizeof(layer_info));
    if (s.override)
        OSRRelease(s.override);
    if (s.geo)
        OSRRelease(s.geo);
    if (s.local)
        OSRRelease(s.local);
    sl_array_free(a, &s.pos, 3 * sizeof(float));
    sl_array_free(a, &s.idx, 3 * sizeof(uint32_t));
    sl_array_free(a, &s.seg_info, sizeof(street_seg));
    if (s.ring)
        sl_free(a, s.ring, s.ring_cap * sizeof(double));
    sl_geos_finish(&s.g);
done_cpl:
    CPLPopErrorHandler();
done_strings:
    sl_strfree(a, s.height_fields);
    sl_strfree(a, s.levels_fields);
    s.st->seconds = sl_now() - t0;
    if (st != SL_OK) {
        sl_scene_destroy(s.scene);
        return st;
    }
    *out = s.scene;
    return SL_OK;
}

/* GIS import (sl_import_gis, docs/gis-import.md): a city of 3 x 3 blocks written by the test as
 * GeoJSON (WGS 84), as a shapefile in UTM 33N (through OGR, with its .prj) and without a .prj, as
 * OpenStreetMap XML and as CityGML; the buildings' sizes after reprojection against the metres the
 * test laid them out in, heights from height / building:levels / the default, holes kept,
 * footprints inside their buildings, the street graph joined at the crossings; the imported city
 * is a normal scene (street view cells, a walk, every conservative culling method with zero misses
 * against the oracle); bad input (unclosed rings, bow ties, missing and unusable heights, NaN,
 * huge coordinates, an unknown CRS, empty layers, not a GIS file) fails with a clear message or
 * is a counted warning. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <pthread.h>
#include <unistd.h>

#include <gdal.h>
#include <ogr_api.h>
#include <ogr_srs_api.h>

#include "sightline/cull.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/region.h"
#include "sightline/slscene.h"
#include "sightline/scene.h"
#include "support/counting_alloc.h"
#include "support/synth_check.h"

#define LON0 16.37
#define LAT0 48.21
#define PITCH 72.0  /* lattice spacing, metres */
#define BLOCKS 3
#define SIDE 26.0   /* building side, metres */

static char g_dir[256];

/* Metres per degree at LAT0 on WGS 84 (the series of the meridian arc and of the parallel). */
static double m_per_deg_lat(void)
{
    double p = LAT0 * M_PI / 180;
    return 111132.954 - 559.822 * cos(2 * p) + 1.175 * cos(4 * p);
}
static double m_per_deg_lon(void)
{
    double p = LAT0 * M_PI / 180;
    return 111412.84 * cos(p) - 93.5 * cos(3 * p);
}
static double lon_of(double x) { return LON0 + x / m_per_deg_lon(); }
static double lat_of(double y) { return LAT0 + y / m_per_deg_lat(); }

static const char *path_in(const char *name)
{
    static char buf[8][512];
    static int k;
    k = (k + 1) % 8;
    snprintf(buf[k], sizeof buf[k], "%s/%s", g_dir, name);
    return buf[k];
}

/* The layout in metres: building b of block (i, j), 2 x 2 buildings per block. */
typedef struct bld {
    double x0, y0, x1, y1;
    int attr;            /* 0 height, 1 levels, 2 nothing (default), 3 height + courtyard */
    double value;
} bld;

static int layout(bld *out)
{
    int n = 0;
    for (int j = 0; j < BLOCKS; j++)
        for (int i = 0; i < BLOCKS; i++)
            for (int b = 0; b < 4; b++) {
                double x = i * PITCH + 8 + (b & 1) * (SIDE + 4), y = j * PITCH + 8 + (b >> 1) * (SIDE + 4);
                int k = (i + 3 * j + b) % 4;
                out[n] = (bld){x, y, x + SIDE, y + SIDE, k, k == 1 ? 3 + (b % 3) : 12 + 3 * ((i + j + b) % 5)};
                n++;
            }
    return n;
}

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* The city as GeoJSON: polygons (one with a courtyard per block) and the street lattice as lines
 * through every crossing. */
static void write_geojson(const char *path)
{
    bld b[64];
    int n = layout(b);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "{\"type\":\"FeatureCollection\",\"features\":[\n");
    for (int k = 0; k < n; k++) {
        char props[128];
        if (b[k].attr == 0 || b[k].attr == 3)
            snprintf(props, sizeof props, "\"building\":\"yes\",\"height\":\"%g\"", b[k].value);
        else if (b[k].attr == 1)
            snprintf(props, sizeof props, "\"building\":\"yes\",\"building:levels\":%g", b[k].value);
        else
            snprintf(props, sizeof props, "\"building\":\"yes\",\"name\":\"no height %d\"", k);
        fprintf(f, "{\"type\":\"Feature\",\"properties\":{%s},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[", props);
        double xs[5] = {b[k].x0, b[k].x1, b[k].x1, b[k].x0, b[k].x0}, ys[5] = {b[k].y0, b[k].y0, b[k].y1, b[k].y1, b[k].y0};
        fprintf(f, "[");
        for (int v = 0; v < 5; v++)
            fprintf(f, "%s[%.9f,%.9f]", v ? "," : "", lon_of(xs[v]), lat_of(ys[v]));
        fprintf(f, "]");
        if (b[k].attr == 3) { /* a courtyard: a hole of 10 x 10 m in the middle */
            double cx = 0.5 * (b[k].x0 + b[k].x1), cy = 0.5 * (b[k].y0 + b[k].y1);
            double hx[5] = {cx - 5, cx - 5, cx + 5, cx + 5, cx - 5}, hy[5] = {cy - 5, cy + 5, cy + 5, cy - 5, cy - 5};
            fprintf(f, ",[");
            for (int v = 0; v < 5; v++)
                fprintf(f, "%s[%.9f,%.9f]", v ? "," : "", lon_of(hx[v]), lat_of(hy[v]));
            fprintf(f, "]");
        }
        fprintf(f, "]}},\n");
    }
    /* streets: x = const and y = const lines through the crossings */
    for (int dir = 0; dir < 2; dir++)
        for (int k = 0; k <= BLOCKS; k++) {
            fprintf(f, "{\"type\":\"Feature\",\"properties\":{\"highway\":\"%s\"},\"geometry\":{\"type\":\"LineString\","
                       "\"coordinates\":[", k == 1 ? "primary" : "residential");
            for (int m = 0; m <= BLOCKS; m++) {
                double x = dir ? m * PITCH : k * PITCH, y = dir ? k * PITCH : m * PITCH;
                fprintf(f, "%s[%.9f,%.9f]", m ? "," : "", lon_of(x), lat_of(y));
            }
            fprintf(f, "]}}%s\n", dir == 1 && k == BLOCKS ? "" : ",");
        }
    fprintf(f, "]}\n");
    fclose(f);
}

/* The buildings as a shapefile through OGR: in UTM 33N (EPSG:32633), or with no CRS (no .prj). */
static void write_shapefile(const char *path, bool with_crs)
{
    GDALAllRegister();
    GDALDriverH drv = GDALGetDriverByName("ESRI Shapefile");
    assert_non_null(drv);
    GDALDatasetH ds = GDALCreate(drv, path, 0, 0, 0, GDT_Unknown, NULL);
    assert_non_null(ds);
    OGRSpatialReferenceH utm = OSRNewSpatialReference(NULL), geo = OSRNewSpatialReference(NULL);
    assert_int_equal(OSRImportFromEPSG(utm, 32633), OGRERR_NONE);
    assert_int_equal(OSRSetWellKnownGeogCS(geo, "WGS84"), OGRERR_NONE);
    OSRSetAxisMappingStrategy(utm, OAMS_TRADITIONAL_GIS_ORDER);
    OSRSetAxisMappingStrategy(geo, OAMS_TRADITIONAL_GIS_ORDER);
    OGRCoordinateTransformationH ct = OCTNewCoordinateTransformation(geo, utm);
    assert_non_null(ct);
    OGRLayerH l = GDALDatasetCreateLayer(ds, "buildings", with_crs ? utm : NULL, wkbPolygon, NULL);
    assert_non_null(l);
    OGRFieldDefnH fd = OGR_Fld_Create("height", OFTReal);
    assert_int_equal(OGR_L_CreateField(l, fd, TRUE), OGRERR_NONE);
    OGR_Fld_Destroy(fd);
    bld b[64];
    int n = layout(b);
    for (int k = 0; k < n; k++) {
        OGRFeatureH f = OGR_F_Create(OGR_L_GetLayerDefn(l));
        if (b[k].attr != 2)
            OGR_F_SetFieldDouble(f, 0, b[k].attr == 1 ? 3 * b[k].value : b[k].value);
        OGRGeometryH ring = OGR_G_CreateGeometry(wkbLinearRing), poly = OGR_G_CreateGeometry(wkbPolygon);
        double xs[5] = {b[k].x0, b[k].x0, b[k].x1, b[k].x1, b[k].x0}, ys[5] = {b[k].y0, b[k].y1, b[k].y1, b[k].y0, b[k].y0};
        for (int v = 0; v < 5; v++) {
            double x = lon_of(xs[v]), y = lat_of(ys[v]), z = 0;
            assert_true(OCTTransform(ct, 1, &x, &y, &z));
            OGR_G_AddPoint_2D(ring, x, y);
        }
        OGR_G_AddGeometryDirectly(poly, ring);
        OGR_F_SetGeometryDirectly(f, poly);
        assert_int_equal(OGR_L_CreateFeature(l, f), OGRERR_NONE);
        OGR_F_Destroy(f);
    }
    OCTDestroyCoordinateTransformation(ct);
    OSRRelease(utm);
    OSRRelease(geo);
    GDALClose(ds);
}

static const char osm_xml[] =
    "<?xml version='1.0' encoding='UTF-8'?>\n"
    "<osm version='0.6' generator='test_gis'>\n"
    "  <node id='1' lat='48.2100' lon='16.3700'/> <node id='2' lat='48.2100' lon='16.3704'/>\n"
    "  <node id='3' lat='48.2103' lon='16.3704'/> <node id='4' lat='48.2103' lon='16.3700'/>\n"
    "  <node id='5' lat='48.2100' lon='16.3710'/> <node id='6' lat='48.2100' lon='16.3714'/>\n"
    "  <node id='7' lat='48.2103' lon='16.3714'/> <node id='8' lat='48.2103' lon='16.3710'/>\n"
    "  <node id='10' lat='48.2098' lon='16.3695'/> <node id='11' lat='48.2098' lon='16.3707'/>\n"
    "  <node id='12' lat='48.2098' lon='16.3720'/> <node id='13' lat='48.2106' lon='16.3707'/>\n"
    "  <node id='14' lat='48.2092' lon='16.3707'/>\n"
    "  <way id='100'><nd ref='1'/><nd ref='2'/><nd ref='3'/><nd ref='4'/><nd ref='1'/>\n"
    "    <tag k='building' v='yes'/><tag k='height' v='21.5'/><tag k='name' v='Haus A'/></way>\n"
    "  <way id='101'><nd ref='5'/><nd ref='6'/><nd ref='7'/><nd ref='8'/><nd ref='5'/>\n"
    "    <tag k='building' v='apartments'/><tag k='building:levels' v='5'/><tag k='roof:height' v='3'/></way>\n"
    "  <way id='102'><nd ref='10'/><nd ref='11'/><nd ref='12'/><tag k='highway' v='residential'/></way>\n"
    "  <way id='103'><nd ref='13'/><nd ref='11'/><nd ref='14'/><tag k='highway' v='footway'/></way>\n"
    "  <way id='104'><nd ref='10'/><nd ref='14'/><tag k='waterway' v='stream'/></way>\n"
    "</osm>\n";

/* One CityGML 2.0 building: an LOD1 box of 20 x 16 m, 9 m tall, standing at 150 m, in ETRS89 /
 * UTM 33N (EPSG:25833), with its measuredHeight. */
static void write_citygml(const char *path)
{
    double x0 = 601000, y0 = 5340000, x1 = x0 + 20, y1 = y0 + 16, z0 = 150, z1 = 159;
    char faces[4096] = "";
    double c[8][3] = {{x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0},
                      {x0, y0, z1}, {x1, y0, z1}, {x1, y1, z1}, {x0, y1, z1}};
    int quads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    for (int q = 0; q < 6; q++) {
        char pos[512] = "";
        for (int v = 0; v <= 4; v++) {
            const double *p = c[quads[q][v % 4]];
            snprintf(pos + strlen(pos), sizeof pos - strlen(pos), "%s%.2f %.2f %.2f", v ? " " : "", p[0], p[1], p[2]);
        }
        snprintf(faces + strlen(faces), sizeof faces - strlen(faces),
                 "<gml:surfaceMember><gml:Polygon><gml:exterior><gml:LinearRing><gml:posList>%s</gml:posList>"
                 "</gml:LinearRing></gml:exterior></gml:Polygon></gml:surfaceMember>\n",
                 pos);
    }
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
            "<core:CityModel xmlns:core=\"http://www.opengis.net/citygml/2.0\" "
            "xmlns:bldg=\"http://www.opengis.net/citygml/building/2.0\" xmlns:gml=\"http://www.opengis.net/gml\">\n"
            "<core:cityObjectMember><bldg:Building gml:id=\"B1\">\n"
            "<bldg:measuredHeight uom=\"m\">9</bldg:measuredHeight>\n"
            "<bldg:lod1Solid><gml:Solid srsName=\"EPSG:25833\" srsDimension=\"3\"><gml:exterior><gml:CompositeSurface>\n"
            "%s</gml:CompositeSurface></gml:exterior></gml:Solid></bldg:lod1Solid>\n"
            "</bldg:Building></core:cityObjectMember>\n</core:CityModel>\n",
            faces);
    fclose(f);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/sl_test_gis_XXXXXX");
    assert_non_null(mkdtemp(g_dir));
    write_geojson(path_in("city.geojson"));
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

static sl_scene import_ok(const char *path, const sl_gis_options *o, sl_gis_stats *st)
{
    sl_scene s = NULL;
    sl_error err = {0};
    sl_status rc = sl_import_gis(path, o, NULL, &s, st, &err);
    if (rc != SL_OK)
        fail_msg("%s: %s", path, err.message);
    return s;
}

/* The building objects' bounds, in the order of the layout (one object per building). */
static void check_city(sl_scene s, const sl_gis_stats *st, double tol, double pos_tol)
{
    bld b[64];
    int n = layout(b);
    assert_int_equal(st->buildings, (uint32_t)n);
    uint32_t k = 0;
    for (uint32_t o = 0; o < sl_scene_object_count(s); o++) {
        sl_object_view v = sl_scene_object(s, o);
        if (v.kind != SL_KIND_BUILDING)
            continue;
        assert_true(k < (uint32_t)n);
        /* sizes in metres: the reprojection is what makes them metres */
        double w = v.bounds.max.x - v.bounds.min.x, d = v.bounds.max.y - v.bounds.min.y;
        if (fabs(w - SIDE) > tol || fabs(d - SIDE) > tol)
            fail_msg("building %u is %.3f x %.3f m, laid out as %g x %g m", k, w, d, SIDE, SIDE);
        double want = b[k].attr == 1 ? 3 * b[k].value : b[k].attr == 2 ? 10 : b[k].value;
        assert_float_equal(v.bounds.max.z, want, 1e-3);
        assert_float_equal(v.bounds.min.z, 0, 1e-6);
        /* relative positions (the frame's origin is the data's centre) */
        sl_object_view first = sl_scene_object(s, 0);
        double dx = (v.bounds.min.x - first.bounds.min.x) - (b[k].x0 - b[0].x0);
        double dy = (v.bounds.min.y - first.bounds.min.y) - (b[k].y0 - b[0].y0);
        if (fabs(dx) > pos_tol || fabs(dy) > pos_tol)
            fail_msg("building %u is off its place by %.3f, %.3f m", k, dx, dy);
        k++;
    }
    assert_int_equal(k, (uint32_t)n);
    /* footprints: each inside its building, from the ground to the roof */
    uint32_t nf = sl_scene_footprint_count(s);
    assert_true(nf >= (uint32_t)n);
    for (uint32_t f = 0; f < nf; f++) {
        sl_footprint_view fv = sl_scene_footprint(s, f);
        assert_true(fv.object < sl_scene_object_count(s));
        sl_aabb ob = sl_scene_object_bounds(s, fv.object);
        for (uint32_t i = 0; i < fv.vertex_count; i++) {
            assert_true(fv.xy[2 * i] >= ob.min.x - 1e-3f && fv.xy[2 * i] <= ob.max.x + 1e-3f);
            assert_true(fv.xy[2 * i + 1] >= ob.min.y - 1e-3f && fv.xy[2 * i + 1] <= ob.max.y + 1e-3f);
        }
        assert_true(fv.roof_z <= ob.max.z + 1e-4f && fv.base_z >= ob.min.z - 1e-4f);
    }
}

static void test_geojson_city(void **state)
{
    (void)state;
    sl_gis_stats st;
    sl_scene s = import_ok(path_in("city.geojson"), NULL, &st);
    check_city(s, &st, 0.05, 0.1);
    assert_string_equal(st.driver, "GeoJSON");
    assert_true(fabs(st.origin_lon - lon_of(BLOCKS * PITCH / 2)) < 1e-3);
    assert_true(fabs(st.origin_lat - lat_of(BLOCKS * PITCH / 2)) < 1e-3);
    /* 9 buildings without a height got the default, as a counted warning */
    bld b[64];
    int n = layout(b), none = 0, holes = 0;
    for (int k = 0; k < n; k++)
        none += b[k].attr == 2, holes += b[k].attr == 3;
    assert_int_equal(st.default_height, (uint32_t)none);
    assert_true(strstr(st.first_warning, "no height") != NULL);
    /* a courtyard cuts its footprint into pieces: more footprints than buildings */
    assert_true(holes > 0);
    assert_true(st.footprints > st.buildings);
    /* streets: 8 lines, 3 segments each, joined at the 16 crossings */
    assert_int_equal(st.streets, 2 * (BLOCKS + 1));
    assert_int_equal(st.street_segments, 2 * (BLOCKS + 1) * BLOCKS);
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nn, ne;
    sl_scene_street_graph(s, &nodes, &nn, &edges, &ne);
    assert_int_equal(nn, (BLOCKS + 1) * (BLOCKS + 1));
    assert_int_equal(ne, 2 * (BLOCKS + 1) * BLOCKS);
    uint32_t avenues = 0;
    for (uint32_t e = 0; e < ne; e++)
        avenues += (edges[e].flags & SL_STREET_AVENUE) != 0;
    assert_int_equal(avenues, 2 * BLOCKS); /* the two "primary" lines */
    assert_int_equal(sl_scene_street_polygon_count(s), st.street_segments);
    assert_true(st.ground_tiles >= 4);
    assert_string_equal(sl_scene_meta(s, "importer"), "gis");
    assert_non_null(sl_scene_meta(s, "gis.frame"));
    /* names: the name tag where there is one */
    assert_true(sl_scene_find_object(s, "no height 2") != SL_NONE);
    sl_scene_destroy(s);
}

/* The same buildings from a shapefile in UTM 33N: the same sizes and heights. */
static void test_shapefile_utm(void **state)
{
    (void)state;
    write_shapefile(path_in("utm.shp"), true);
    sl_gis_stats st;
    sl_scene s = import_ok(path_in("utm.shp"), NULL, &st);
    check_city(s, &st, 0.05, 0.1);
    assert_string_equal(st.driver, "ESRI Shapefile");
    assert_true(strstr(st.crs, "UTM zone 33N") != NULL);
    assert_int_equal(st.streets, 0);
    sl_scene_destroy(s);
}

/* A shapefile without its .prj: an error naming the layer and what to do; --metric or --crs
 * imports it. */
static void test_unknown_crs(void **state)
{
    (void)state;
    write_shapefile(path_in("noprj.shp"), false);
    unlink(path_in("noprj.prj"));
    sl_scene s = NULL;
    sl_error err = {0};
    assert_int_equal(sl_import_gis(path_in("noprj.shp"), NULL, NULL, &s, NULL, &err), SL_ERROR_UNSUPPORTED);
    assert_null(s);
    assert_non_null(strstr(err.message, "noprj.shp"));
    assert_non_null(strstr(err.message, "no coordinate reference system"));
    assert_non_null(strstr(err.message, "--metric"));
    /* the user says what it is */
    sl_gis_options o = sl_gis_defaults();
    o.crs = "EPSG:32633";
    sl_gis_stats st;
    s = import_ok(path_in("noprj.shp"), &o, &st);
    check_city(s, &st, 0.05, 0.1);
    sl_scene_destroy(s);
    /* or that the coordinates are metres: UTM's grid north at 16.37 E, 48.21 N is turned by its
     * convergence (1.02 degrees) from true north, so a 26 m square's box grows by 26 sin(1.02)
     * = 0.46 m; its scale (0.9996) changes it by 1 cm */
    o = sl_gis_defaults();
    o.metric = true;
    s = import_ok(path_in("noprj.shp"), &o, &st);
    check_city(s, &st, 0.6, 4.0); /* 216 m x sin(1.02 degrees) = 3.8 m */
    assert_string_equal(st.crs, "metric (local)");
    sl_scene_destroy(s);
    /* a CRS OGR does not know */
    o = sl_gis_defaults();
    o.crs = "EPSG:999999";
    assert_int_equal(sl_import_gis(path_in("noprj.shp"), &o, NULL, &s, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "EPSG:999999"));
}

static void test_osm_xml(void **state)
{
    (void)state;
    write_file(path_in("block.osm"), osm_xml);
    sl_gis_stats st;
    sl_scene s = import_ok(path_in("block.osm"), NULL, &st);
    assert_string_equal(st.driver, "OSM");
    assert_int_equal(st.buildings, 2);
    assert_int_equal(st.streets, 2); /* the stream is not a street */
    uint32_t a = sl_scene_find_object(s, "Haus A");
    assert_true(a != SL_NONE);
    sl_aabb ab = sl_scene_object_bounds(s, a);
    assert_float_equal(ab.max.z, 21.5, 1e-3);
    /* 0.0004 degrees of longitude, 0.0003 of latitude */
    assert_float_equal(ab.max.x - ab.min.x, 0.0004 * m_per_deg_lon(), 0.05);
    assert_float_equal(ab.max.y - ab.min.y, 0.0003 * m_per_deg_lat(), 0.05);
    /* 5 levels of 3 m with a 3 m roof: the footprint stops at the eave, the mesh at 15 m */
    uint32_t b = sl_scene_find_object(s, "osm way 101");
    assert_true(b != SL_NONE);
    assert_float_equal(sl_scene_object_bounds(s, b).max.z, 15, 1e-3);
    bool found = false;
    for (uint32_t f = 0; f < sl_scene_footprint_count(s); f++) {
        sl_footprint_view fv = sl_scene_footprint(s, f);
        if (fv.object == b) {
            assert_float_equal(fv.roof_z, 12, 1e-3);
            found = true;
        }
    }
    assert_true(found);
    /* the two ways share node 11: one graph */
    uint32_t nn, ne;
    sl_scene_street_graph(s, NULL, &nn, NULL, &ne);
    assert_int_equal(ne, 4);
    assert_int_equal(nn, 5);
    sl_scene_destroy(s);
}

static void test_citygml(void **state)
{
    (void)state;
    write_citygml(path_in("one.gml"));
    sl_gis_stats st;
    sl_scene s = import_ok(path_in("one.gml"), NULL, &st);
    assert_int_equal(st.buildings, 1);
    sl_aabb b = sl_scene_object_bounds(s, 0);
    assert_float_equal(b.max.z, 9, 1e-3);
    assert_float_equal(b.min.z, 0, 1e-6);
    /* 20 x 16 m: the footprints' area (the box is turned by UTM's convergence, about 1 degree) */
    double area = 0;
    assert_true(sl_scene_footprint_count(s) >= 1);
    for (uint32_t f = 0; f < sl_scene_footprint_count(s); f++) {
        sl_footprint_view fv = sl_scene_footprint(s, f);
        for (uint32_t i = 0; i < fv.vertex_count; i++) {
            uint32_t j = (i + 1) % fv.vertex_count;
            area += 0.5 * ((double)fv.xy[2 * i] * fv.xy[2 * j + 1] - (double)fv.xy[2 * j] * fv.xy[2 * i + 1]);
        }
        assert_float_equal(fv.roof_z, 9, 1e-3);
    }
    assert_float_equal(area, 320, 0.5);
    assert_true(b.max.x - b.min.x < 20.5 && b.max.x - b.min.x > 20);
    /* the importer wrote nothing beside the file (the GML driver's .gfs) */
    assert_int_not_equal(access(path_in("one.gfs"), F_OK), 0);
    sl_scene_destroy(s);
}

/* The imported city works as a generated one: street view cells, a walk, and every conservative
 * method that runs with its default options misses nothing against the oracle. */
static void test_city_is_a_scene(void **state)
{
    (void)state;
    sl_gis_stats st;
    sl_scene s = import_ok(path_in("city.geojson"), NULL, &st);
    sl_error err;
    sl_viewcells cells = NULL;
    assert_int_equal(sl_viewcells_from_streets(s, NULL, &cells, &err), SL_OK);
    assert_true(sl_viewcells_count(cells) > 10);
    sl_viewcells_destroy(cells);
    sl_path walk = NULL;
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.frames = 200;
    assert_int_equal(sl_path_generate(s, &po, NULL, &walk, &err), SL_OK);
    assert_int_equal(sl_path_count(walk), 200);
    sl_path_destroy(walk);
    sl_path views = NULL;
    enum { NV = 24 };
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, NV, 7, NULL, NULL, &views, &err), SL_OK);
    sl_camera cams[NV];
    for (uint32_t i = 0; i < NV; i++) {
        cams[i] = sl_path_camera(views, i);
        cams[i].width = 320, cams[i].height = 240;
    }
    sl_path_destroy(views);
    uint32_t ran = 0;
    double vfc = 0, best = 1e9;
    for (uint32_t m = 0; m < sl_cull_method_count(); m++) {
        sl_cull_method_desc d;
        assert_int_equal(sl_cull_method_info(m, &d, &err), SL_OK);
        if (d.guarantee != SL_CONSERVATIVE)
            continue;
        sl_culler c = NULL;
        if (sl_culler_create(d.name, s, NULL, NULL, &c, &err) != SL_OK)
            continue; /* needs an option (pvs: a file) */
        sl_culler_destroy(c);
        sl_synth_views r = sl_synth_run_views(s, d.name, NULL, cams, NV);
        if (r.missed)
            fail_msg("%s missed %llu objects on the imported city", d.name, (unsigned long long)r.missed);
        if (!strcmp(d.name, "vfc"))
            vfc = r.overestimation;
        else if (r.overestimation < best)
            best = r.overestimation;
        ran++;
    }
    assert_true(ran >= 8);
    /* the footprints make occlusion work: some method culls tighter than the frustum */
    printf("imported city: vfc over-estimation %.2f, best conservative %.2f (%u methods)\n", vfc, best, ran);
    assert_true(best < vfc);
    sl_scene_destroy(s);
}

/* Bad input: counted warnings for what can be repaired or left out, clear errors otherwise. */
static void test_bad_input(void **state)
{
    (void)state;
    char poly[512];
    /* an unclosed ring, a bow tie, an unusable height, a NaN-free file with one feature 1e30 away */
    snprintf(poly, sizeof poly, "%s", "");
    write_file(path_in("bad.geojson"),
               "{\"type\":\"FeatureCollection\",\"features\":[\n"
               "{\"type\":\"Feature\",\"properties\":{\"height\":\"12\"},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":"
               "[[[16.3700,48.2100],[16.3703,48.2100],[16.3703,48.2103],[16.3700,48.2103]]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{\"height\":\"tall\"},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":"
               "[[[16.3710,48.2100],[16.3714,48.2104],[16.3714,48.2100],[16.3710,48.2104],[16.3710,48.2100]]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{\"height\":\"-4\"},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":"
               "[[[16.3720,48.2100],[16.3723,48.2100],[16.3723,48.2103],[16.3720,48.2100]]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":"
               "[[[16.3730,48.2100],[16.3730,48.2100],[16.3730,48.2100],[16.3730,48.2100]]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":"
               "[[[1e30,1e30],[2e30,1e30],[2e30,2e30],[1e30,1e30]]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":"
               "[[[16.3700,48.3100],[16.3703,48.3100],[16.3703,48.3103],[16.3700,48.3100]]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{},\"geometry\":{\"type\":\"Point\",\"coordinates\":[16.37,48.21]}}\n"
               "]}\n");
    sl_gis_stats st;
    sl_gis_options o = sl_gis_defaults();
    o.max_extent = 5000; /* the last polygon lies 11 km north */
    sl_scene s = import_ok(path_in("bad.geojson"), &o, &st);
    assert_int_equal(st.features, 7);
    assert_int_equal(st.unclosed_rings, 1);
    assert_int_equal(st.repaired, 1);          /* the bow tie */
    assert_int_equal(st.bad_height, 2);        /* "tall", "-4" */
    assert_int_equal(st.default_height, 2);    /* those two (the others without one are dropped) */
    assert_int_equal(st.dropped_transform, 1); /* 1e30 is no longitude */
    assert_int_equal(st.dropped_far, 1);
    assert_true(st.dropped_invalid >= 1);      /* the ring of one repeated point */
    assert_int_equal(st.other, 1);             /* the point */
    assert_int_equal(st.buildings, 3);
    assert_int_equal(st.building_parts, 4);    /* the bow tie is two triangles */
    sl_scene_destroy(s);

    sl_error err;
    s = NULL;
    /* every coordinate out of longitude/latitude range: projected data labelled WGS 84 */
    write_file(path_in("huge.geojson"),
               "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{},\"geometry\":"
               "{\"type\":\"Polygon\",\"coordinates\":[[[601000,5340000],[601020,5340000],[601020,5340020],[601000,5340000]]]}}]}");
    assert_int_equal(sl_import_gis(path_in("huge.geojson"), NULL, NULL, &s, NULL, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "look projected"));
    assert_null(s);
    o = sl_gis_defaults();
    o.metric = true; /* which they are */
    s = import_ok(path_in("huge.geojson"), &o, &st);
    assert_int_equal(st.buildings, 1);
    sl_scene_destroy(s);
    s = NULL;
    /* NaN: json-c reads it; either the driver refuses the file or the feature is dropped */
    write_file(path_in("nan.geojson"),
               "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{},\"geometry\":"
               "{\"type\":\"Polygon\",\"coordinates\":[[[NaN,48.21],[16.3703,48.21],[16.3703,48.2103],[NaN,48.21]]]}}]}");
    sl_status rc = sl_import_gis(path_in("nan.geojson"), NULL, NULL, &s, &st, &err);
    assert_int_not_equal(rc, SL_OK);
    assert_non_null(strstr(err.message, "nan.geojson"));
    assert_null(s);
    /* an empty layer */
    write_file(path_in("empty.geojson"), "{\"type\":\"FeatureCollection\",\"features\":[]}");
    assert_int_equal(sl_import_gis(path_in("empty.geojson"), NULL, NULL, &s, NULL, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "no buildings"));
    /* only points */
    write_file(path_in("points.geojson"),
               "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{},\"geometry\":"
               "{\"type\":\"Point\",\"coordinates\":[16.37,48.21]}}]}");
    assert_int_equal(sl_import_gis(path_in("points.geojson"), NULL, NULL, &s, NULL, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "1 other"));
    /* not GIS data */
    write_file(path_in("text.geojson"), "this is not JSON at all\n");
    assert_int_equal(sl_import_gis(path_in("text.geojson"), NULL, NULL, &s, NULL, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "text.geojson"));
    assert_non_null(strstr(err.message, "GeoJSON driver cannot read it"));
    write_file(path_in("text.shp"), "not a shapefile\n");
    assert_int_equal(sl_import_gis(path_in("text.shp"), NULL, NULL, &s, NULL, &err), SL_ERROR_FORMAT);
    write_file(path_in("text.osm"), "<html>no</html>\n");
    assert_int_not_equal(sl_import_gis(path_in("text.osm"), NULL, NULL, &s, NULL, &err), SL_OK);
    assert_non_null(strstr(err.message, "text.osm"));
    write_file(path_in("zero.gml"), "");
    assert_int_equal(sl_import_gis(path_in("zero.gml"), NULL, NULL, &s, NULL, &err), SL_ERROR_FORMAT);
    assert_int_equal(sl_import_gis(path_in("missing.geojson"), NULL, NULL, &s, NULL, &err), SL_ERROR_IO);
    assert_int_equal(sl_import_gis(path_in("x.obj"), NULL, NULL, &s, NULL, &err), SL_ERROR_UNSUPPORTED);
    /* a layer that is not there */
    o = sl_gis_defaults();
    o.layers = "roads";
    assert_int_equal(sl_import_gis(path_in("city.geojson"), &o, NULL, &s, NULL, &err), SL_ERROR_NOT_FOUND);
    assert_non_null(strstr(err.message, "'city'"));
    /* options out of range */
    o = sl_gis_defaults();
    o.default_height = -1;
    assert_int_equal(sl_import_gis(path_in("city.geojson"), &o, NULL, &s, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(s);
}

/* Street lines crossing without a shared vertex are joined where they cross; lines with no
 * highway field in a layer without one are all streets; widths by class or the width tag. */
static void test_crossing_streets(void **state)
{
    (void)state;
    write_file(path_in("cross.geojson"),
               "{\"type\":\"FeatureCollection\",\"features\":[\n"
               "{\"type\":\"Feature\",\"properties\":{\"highway\":\"primary\"},\"geometry\":{\"type\":\"LineString\","
               "\"coordinates\":[[16.3700,48.2100],[16.3720,48.2100]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{\"highway\":\"service\",\"width\":\"4.5\"},\"geometry\":"
               "{\"type\":\"LineString\",\"coordinates\":[[16.3710,48.2090],[16.3710,48.2110]]}},\n"
               "{\"type\":\"Feature\",\"properties\":{\"waterway\":\"canal\"},\"geometry\":{\"type\":\"LineString\","
               "\"coordinates\":[[16.3700,48.2095],[16.3720,48.2095]]}}\n"
               "]}\n");
    sl_gis_stats st;
    sl_scene s = import_ok(path_in("cross.geojson"), NULL, &st);
    assert_int_equal(st.buildings, 0);
    assert_int_equal(st.streets, 2);
    assert_int_equal(st.other, 1);
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nn, ne;
    sl_scene_street_graph(s, &nodes, &nn, &edges, &ne);
    assert_int_equal(nn, 5);
    assert_int_equal(ne, 4);
    uint32_t deg[5] = {0};
    for (uint32_t e = 0; e < ne; e++) {
        deg[edges[e].a]++, deg[edges[e].b]++;
        bool avenue = (edges[e].flags & SL_STREET_AVENUE) != 0;
        assert_float_equal(edges[e].width, avenue ? 12 : 4.5, 1e-6);
    }
    uint32_t crossings = 0;
    for (uint32_t v = 0; v < nn; v++)
        crossings += deg[v] == 4;
    assert_int_equal(crossings, 1);
    sl_scene_destroy(s);
}

/* The same file twice gives the same scene, byte for byte. */
static void test_deterministic(void **state)
{
    (void)state;
    sl_error err;
    for (int k = 0; k < 2; k++) {
        sl_scene s = import_ok(path_in("city.geojson"), NULL, NULL);
        assert_int_equal(sl_scene_save(s, path_in(k ? "b.slscene" : "a.slscene"), &err), SL_OK);
        sl_scene_destroy(s);
    }
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", path_in("a.slscene"), path_in("b.slscene"));
    assert_int_equal(system(cmd), 0);
    /* and sl_scene_open takes it by its extension */
    sl_scene s = NULL;
    assert_int_equal(sl_scene_open(path_in("city.geojson"), NULL, NULL, &s, &err), SL_OK);
    assert_true(sl_scene_footprint_count(s) > 0);
    sl_scene_destroy(s);
    /* every byte through the caller's allocator comes back, on success and on failure */
    sl_test_counter c = {0};
    sl_allocator ca = sl_test_counting_allocator(&c);
    const char *files[] = {"city.geojson", "bad.geojson", "block.osm", "noprj.shp", "huge.geojson", "text.geojson"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        s = NULL;
        if (sl_import_gis(path_in(files[i]), NULL, &ca, &s, NULL, &err) == SL_OK)
            sl_scene_destroy(s);
        assert_int_equal(c.live, 0);
    }
    assert_true(c.calls > 0);
    assert_true(sl_gis_path("x.GeoJSON") && sl_gis_path("a/b.osm.pbf") && sl_gis_path("c.shp") && !sl_gis_path("d.obj"));
}

/* Two threads importing at once (GDAL's error handler is per thread, GEOS has a context per call)
 * get the same scenes as one thread alone. */
typedef struct job {
    const char *in, *out;
    sl_status st;
    char message[512];
} job;

static void *import_job(void *user)
{
    job *j = user;
    sl_scene s = NULL;
    sl_error err = {0};
    j->st = sl_import_gis(j->in, NULL, NULL, &s, NULL, &err);
    if (j->st == SL_OK)
        j->st = sl_scene_save(s, j->out, &err);
    snprintf(j->message, sizeof j->message, "%s", err.message);
    sl_scene_destroy(s);
    return NULL;
}

static void test_threads(void **state)
{
    (void)state;
    job jobs[4] = {{path_in("city.geojson"), path_in("t0.slscene"), SL_OK, ""},
                   {path_in("block.osm"), path_in("t1.slscene"), SL_OK, ""},
                   {path_in("city.geojson"), path_in("t2.slscene"), SL_OK, ""},
                   {path_in("text.geojson"), path_in("t3.slscene"), SL_OK, ""}};
    pthread_t t[4];
    for (int i = 0; i < 4; i++)
        assert_int_equal(pthread_create(&t[i], NULL, import_job, &jobs[i]), 0);
    for (int i = 0; i < 4; i++)
        assert_int_equal(pthread_join(t[i], NULL), 0);
    assert_int_equal(jobs[0].st, SL_OK);
    assert_int_equal(jobs[1].st, SL_OK);
    assert_int_equal(jobs[2].st, SL_OK);
    assert_int_equal(jobs[3].st, SL_ERROR_FORMAT);
    assert_non_null(strstr(jobs[3].message, "text.geojson")); /* its own message, not another thread's */
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s' && cmp -s '%s' '%s'", path_in("t0.slscene"), path_in("t2.slscene"),
             path_in("t0.slscene"), path_in("a.slscene"));
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_geojson_city), cmocka_unit_test(test_shapefile_utm), cmocka_unit_test(test_unknown_crs),
        cmocka_unit_test(test_osm_xml),      cmocka_unit_test(test_citygml),       cmocka_unit_test(test_city_is_a_scene),
        cmocka_unit_test(test_bad_input),    cmocka_unit_test(test_crossing_streets), cmocka_unit_test(test_deterministic),
        cmocka_unit_test(test_threads),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}

/* Report graphics, internal to the library and the command: SVG line plots, and the images of
 * oracle views (object ids, depth, overdraw) and top-down maps as PNG. Everything is written
 * atomically (temporary file, then rename). */
#ifndef SL_TRUTH_PLOT_H
#define SL_TRUTH_PLOT_H

#include "sightline/camera.h"
#include "sightline/truth.h"
#include "core/sl_core.h"

/* One line of a plot: count y values at the plot's x values; non-finite values break the line. */
typedef struct sl_plot_series {
    const char *name;
    const double *y;
    size_t count;
    uint32_t color;            /* 0xRRGGBB */
    bool dashed;               /* a reference line: long dashes, no markers */
    uint32_t style;            /* 1 + the index whose dash pattern and marker the line gets (give the
                                  index given to sl_plot_color, so that a series looks the same in
                                  every plot); 0: its position in the plot */
} sl_plot_series;

typedef enum sl_plot_scale { SL_PLOT_LINEAR = 0, SL_PLOT_LOG = 1, SL_PLOT_AUTO = 2 } sl_plot_scale;

typedef struct sl_plot {
    const char *title, *x_label, *y_label;
    const double *x;           /* shared x values, or NULL: 0, 1, 2 ... (the axis spans their range) */
    const sl_plot_series *series;
    uint32_t series_count;
    sl_plot_scale y_scale;     /* AUTO: logarithmic when the positive values span over 2 decades */
    uint32_t width, height;    /* 0, 0: 960 x 480 (taller when the legend needs it) */
    const char *empty_note;    /* shown in the plot area without series (NULL: "no data") */
} sl_plot;

/* Write a line plot as a standalone SVG file (axes, ticks, grid, legend, title). */
sl_status sl_plot_write_svg(const sl_plot *plot, const char *path, const sl_allocator *alloc, sl_error *err);

/* Colour of series i from a qualitative palette of SL_PLOT_COLORS colours (0xRRGGBB); it repeats
 * after that, but with another marker: series i gets marker i % SL_PLOT_MARKERS and dash pattern
 * i % SL_PLOT_DASHES, so no two of the first SL_PLOT_COLORS * SL_PLOT_MARKERS series look alike. */
#define SL_PLOT_COLORS 14u
#define SL_PLOT_MARKERS 7u
#define SL_PLOT_DASHES 5u
uint32_t sl_plot_color(uint32_t i);

/* The PNGs of an oracle view (ids, depth, overdraw): sl_image_write_* in sightline/truth.h. */

/* An RGB image to draw on (rows top to bottom, 3 bytes per pixel). */
typedef struct sl_canvas {
    uint8_t *rgb;
    uint32_t width, height;
} sl_canvas;

/* A line of the given thickness in pixels; parts outside the canvas are skipped. */
void sl_canvas_line(sl_canvas *c, double x0, double y0, double x1, double y1, uint32_t color, int thickness);
/* A circle outline of radius r. */
void sl_canvas_ring(sl_canvas *c, double cx, double cy, double r, uint32_t color, int thickness);
/* A filled disc of radius r. */
void sl_canvas_disc(sl_canvas *c, double cx, double cy, double r, uint32_t color);

#endif

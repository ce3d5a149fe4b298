/* PNG reading and writing through libpng. Writes go through the atomic writer (temporary file,
 * then rename), so an interrupted run never leaves a truncated image. */
#include "sl_core.h"
#include "sightline/image.h"

#include <math.h>
#include <png.h>
#include <setjmp.h>

typedef struct png_sink {
    sl_atomic_file *file;
} png_sink;

static void sink_write(png_structp png, png_bytep data, size_t size)
{
    png_sink *s = png_get_io_ptr(png);
    sl_atomic_write(s->file, data, size);
}

static void sink_flush(png_structp png) { (void)png; }

typedef struct png_job {
    sl_atomic_file *file;
    uint32_t width, height, channels;
    const uint8_t *pixels;
    size_t stride;
} png_job;

/* Encode with libpng's longjmp error handling confined to this function; returns false on error. */
static bool png_encode(png_structp png, png_infop info, const png_job *job)
{
    png_sink sink = {job->file};
    if (setjmp(png_jmpbuf(png)))
        return false;
    static const int types[5] = {0, PNG_COLOR_TYPE_GRAY, 0, PNG_COLOR_TYPE_RGB, PNG_COLOR_TYPE_RGBA};
    png_set_write_fn(png, &sink, sink_write, sink_flush);
    png_set_IHDR(png, info, job->width, job->height, 8, types[job->channels], PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 6);
    png_write_info(png, info);
    for (uint32_t y = 0; y < job->height; y++)
        png_write_row(png, (png_const_bytep)(job->pixels + (size_t)y * job->stride));
    png_write_end(png, info);
    return true;
}

sl_status sl_png_write(const char *path, uint32_t width, uint32_t height, uint32_t channels, const uint8_t *pixels,
                       size_t stride, sl_error *err)
{
    if (!path || !pixels || !width || !height || (channels != 1 && channels != 3 && channels != 4))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_png_write: bad arguments");
    if (width > (1u << 20) || height > (1u << 20))
        return sl_fail(err, SL_ERROR_LIMIT, "%s: image %ux%u is too large", path, width, height);
    sl_atomic_file f;
    sl_status st = sl_atomic_open(NULL, path, &f, err);
    if (st != SL_OK)
        return st;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(&png, &info);
        sl_atomic_abort(&f);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: cannot create PNG writer", path);
    }
    png_job job = {&f, width, height, channels, pixels, stride ? stride : (size_t)width * channels};
    bool failed = !png_encode(png, info, &job);
    png_destroy_write_struct(&png, &info);
    if (failed) {
        sl_atomic_abort(&f);
        return sl_fail(err, SL_ERROR_IO, "%s: PNG encoding failed", path);
    }
    return sl_atomic_commit(&f, err);
}

sl_status sl_png_read_rgba(const char *path, const sl_allocator *alloc, uint8_t **pixels, uint32_t *width, uint32_t *height,
                           sl_error *err)
{
    *pixels = NULL;
    *width = *height = 0;
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path))
        return sl_fail(err, SL_ERROR_FORMAT, "%s: %s", path, img.message);
    img.format = PNG_FORMAT_RGBA;
    if (img.width > (1u << 16) || img.height > (1u << 16)) {
        png_image_free(&img);
        return sl_fail(err, SL_ERROR_LIMIT, "%s: image %ux%u is too large", path, img.width, img.height);
    }
    size_t size = PNG_IMAGE_SIZE(img);
    uint8_t *buf = sl_alloc(alloc, size);
    if (!buf) {
        png_image_free(&img);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    if (!png_image_finish_read(&img, NULL, buf, 0, NULL)) {
        sl_free(alloc, buf, size);
        return sl_fail(err, SL_ERROR_FORMAT, "%s: %s", path, img.message);
    }
    *pixels = buf;
    *width = img.width;
    *height = img.height;
    return SL_OK;
}

uint32_t sl_id_color(uint32_t id)
{
    /* golden-ratio hue steps keep neighbouring ids apart; saturation/value vary with more bits */
    float h = fmodf((float)id * 0.61803398875f, 1.0f);
    float s = 0.55f + 0.35f * (float)((id * 2654435761u) >> 30) / 3.0f;
    float v = 0.70f + 0.30f * (float)(((id * 2246822519u) >> 29) & 3) / 3.0f;
    float r, g, b;
    float h6 = h * 6.0f;
    int i = (int)h6;
    float f = h6 - (float)i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    switch (i % 6) {
    case 0: r = v, g = t, b = p; break;
    case 1: r = q, g = v, b = p; break;
    case 2: r = p, g = v, b = t; break;
    case 3: r = p, g = q, b = v; break;
    case 4: r = t, g = p, b = v; break;
    default: r = v, g = p, b = q; break;
    }
    return ((uint32_t)(r * 255.0f + 0.5f) << 16) | ((uint32_t)(g * 255.0f + 0.5f) << 8) | (uint32_t)(b * 255.0f + 0.5f);
}

uint32_t sl_ramp_color(float t)
{
    /* piecewise-linear approximation of a viridis-like ramp through five anchors */
    static const float anchors[5][3] = {
        {0.267f, 0.005f, 0.329f}, {0.229f, 0.322f, 0.546f}, {0.128f, 0.567f, 0.551f}, {0.369f, 0.789f, 0.383f}, {0.993f, 0.906f, 0.144f}};
    if (!(t >= 0))
        t = 0;
    if (t > 1)
        t = 1;
    float x = t * 4.0f;
    int i = (int)x;
    if (i > 3)
        i = 3;
    float f = x - (float)i;
    uint32_t c = 0;
    for (int k = 0; k < 3; k++) {
        float v = anchors[i][k] * (1 - f) + anchors[i + 1][k] * f;
        c = (c << 8) | (uint32_t)(v * 255.0f + 0.5f);
    }
    return c;
}

/* Sightline images: PNG output through libpng, written atomically, plus colour helpers used by the
 * id-buffer, depth and map images. */
#ifndef SIGHTLINE_IMAGE_H
#define SIGHTLINE_IMAGE_H

#include "core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Write an 8-bit PNG. channels: 1 (grey), 3 (RGB) or 4 (RGBA); rows top to bottom, `stride` bytes
 * apart (0 means width*channels). Written to a temporary file and renamed. */
SL_API sl_status sl_png_write(const char *path, uint32_t width, uint32_t height, uint32_t channels, const uint8_t *pixels,
                              size_t stride, sl_error *err);

/* Read an 8-bit PNG into RGBA (4 channels), allocated with alloc (free with size width*height*4). */
SL_API sl_status sl_png_read_rgba(const char *path, const sl_allocator *alloc, uint8_t **pixels, uint32_t *width,
                                  uint32_t *height, sl_error *err);

/* A well-spread, deterministic colour for an integer id (0xRRGGBB). */
SL_API uint32_t sl_id_color(uint32_t id);

/* Colour ramp (perceptually ordered, dark blue → yellow) for t in [0,1]: 0xRRGGBB. */
SL_API uint32_t sl_ramp_color(float t);

#ifdef __cplusplus
}
#endif
#endif

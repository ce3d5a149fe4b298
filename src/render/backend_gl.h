/* The GL draw backend and the render layer's own culling methods (glq: backend_gl.c, gpu_hiz.c). */
#ifndef SL_RENDER_BACKEND_GL_H
#define SL_RENDER_BACKEND_GL_H

#include "render/render_internal.h"
#include "cull/culler_internal.h"

/* Is the table a renderer's GL backend (sl_renderer_backend)? Then *out is its renderer. */
bool sl_render_backend_of(const sl_draw_backend *backend, sl_renderer *out);

/* The cull-face state of a facing group (SL_RENDER_GROUP_TWO_SIDED, _CULL_CCW, _CULL_CW), as
 * sl_render_draw_ids sets it. */
void sl_render_facing_state(int facing);

/* gpu-hiz (gpu_hiz.c): the method table, created through sl_culler_create_from_method by
 * sl_renderer_create_culler with the renderer's backend, and its public description. */
extern const sl_cull_method sl_render_method_gpu_hiz;
extern const sl_cull_method_desc sl_render_desc_gpu_hiz;

#endif

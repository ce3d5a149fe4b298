/* The scene's materials on the GPU (render_internal.h, "Materials"): one SSBO of base colours,
 * alpha modes and texture layers, and one texture array holding every distinct base-colour
 * texture, decoded with stb_image (libstb) and resampled to a common square size. */
#include "render/render_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef SL_HAVE_STB
#include <stb_image.h>
#include <stb_image_resize.h>
#endif

/* The side of every layer: 512 for a few textures, smaller for many (bounded memory). */
static uint32_t layer_size(uint32_t layers)
{
    return layers <= 16 ? 512 : layers <= 64 ? 256 : 128;
}

sl_status sl_render_upload_materials(sl_renderer r, sl_error *err)
{
    sl_scene s = r->scene;
    uint32_t n = sl_scene_material_count(s);
    r->material_count = n;
    size_t bytes = ((size_t)n + 1) * sizeof(sl_render_material_gpu);
    size_t pbytes = ((size_t)n + 1) * sizeof(const char *);
    sl_render_material_gpu *m = sl_render_alloc(r, bytes);
    const char **paths = sl_render_alloc(r, pbytes); /* material -> its texture's path (one layer per path) */
    if (!m || !paths) {
        sl_render_free(r, m, bytes);
        sl_render_free(r, paths, pbytes);
        return sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "renderer: %zu bytes of materials", bytes);
    }
    uint32_t layers = 0;
    for (uint32_t i = 1; i <= n; i++) {
        sl_material mat;
        if (!sl_scene_material(s, i, &mat))
            continue;
        memcpy(m[i].base_color, mat.base_color, sizeof m[i].base_color);
        m[i].alpha_mode = mat.alpha_mode;
        m[i].alpha_cutoff = mat.alpha_cutoff;
        m[i].flags = mat.flags;
        if (!r->opt.textures || !mat.base_color_texture || !mat.base_color_texture[0])
            continue;
        paths[i] = mat.base_color_texture;
        uint32_t same = 0;
        for (uint32_t k = 1; k < i && !same; k++)
            if (paths[k] && !strcmp(paths[k], paths[i]))
                same = m[k].layer;
        m[i].layer = same ? same : ++layers;
    }
    sl_status st = SL_OK;
#ifdef SL_HAVE_STB
    if (layers) {
        uint32_t size = layer_size(layers);
        r->texture_size = size;
        glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &r->texture_array);
        GLsizei levels = 1;
        for (uint32_t k = size; k > 1; k /= 2)
            levels++;
        glTextureStorage3D(r->texture_array, levels, GL_RGBA8, (GLsizei)size, (GLsizei)size, (GLsizei)layers);
        glTextureParameteri(r->texture_array, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
        glTextureParameteri(r->texture_array, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTextureParameteri(r->texture_array, GL_TEXTURE_WRAP_S, GL_REPEAT);
        glTextureParameteri(r->texture_array, GL_TEXTURE_WRAP_T, GL_REPEAT);
        size_t sbytes = (size_t)size * size * 4;
        uint8_t *scaled = sl_render_alloc(r, sbytes);
        if (!scaled)
            st = sl_render_fail(err, SL_ERROR_OUT_OF_MEMORY, "renderer: texture scratch");
        for (uint32_t i = 1; i <= n && st == SL_OK; i++) {
            if (!m[i].layer)
                continue;
            bool first = true; /* decode each layer once: at its first material */
            for (uint32_t k = 1; k < i; k++)
                if (m[k].layer == m[i].layer)
                    first = false;
            if (!first)
                continue;
            char file[4096] = "";
            sl_error terr = {SL_OK, ""};
            int w = 0, h = 0, comp = 0;
            uint8_t *px = NULL;
            if (sl_scene_texture_path(s, i, file, sizeof file, &terr) == SL_OK)
                px = stbi_load(file, &w, &h, &comp, 4);
            if (!px) {
                /* a missing or undecodable texture: the material's colour alone (white texel) */
                if (!r->texture_warning[0])
                    snprintf(r->texture_warning, sizeof r->texture_warning, "material %u texture %.120s: %.120s", i, paths[i],
                             terr.status == SL_OK ? stbi_failure_reason() : terr.message);
                memset(scaled, 255, (size_t)size * size * 4);
            } else {
                if ((uint32_t)w == size && (uint32_t)h == size)
                    memcpy(scaled, px, (size_t)size * size * 4);
                else
                    stbir_resize_uint8(px, w, h, 0, scaled, (int)size, (int)size, 0, 4);
                r->texture_bytes += (uint64_t)size * size * 4;
                stbi_image_free(px);
            }
            glTextureSubImage3D(r->texture_array, 0, 0, 0, (GLint)(m[i].layer - 1), (GLsizei)size, (GLsizei)size, 1,
                                GL_RGBA, GL_UNSIGNED_BYTE, scaled);
        }
        sl_render_free(r, scaled, sbytes);
        if (st == SL_OK) {
            glGenerateTextureMipmap(r->texture_array);
            r->texture_layers = layers;
            st = sl_render_check(r, "uploading the base-colour textures", err);
        }
    }
#else
    for (uint32_t i = 1; i <= n; i++)
        m[i].layer = 0; /* built without libstb: no textures decoded */
    (void)layer_size;
#endif
    if (st == SL_OK) {
        glCreateBuffers(1, &r->material_ssbo);
        glNamedBufferStorage(r->material_ssbo, (GLsizeiptr)bytes, m, 0);
        st = sl_render_check(r, "uploading the materials", err);
    }
    sl_render_free(r, m, bytes);
    sl_render_free(r, paths, pbytes);
    return st;
}

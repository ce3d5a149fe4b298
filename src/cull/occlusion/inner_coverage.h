/* Occluders by inner coverage (res=any): proxies drawn so that they cover only pixel centres, at
 * every resolution and sample position, that their objects cover. MESH and SCENE_MESH triangles
 * shrunk on screen by the pixel footprint (sl_occ_render_mesh_shrunk), prisms eroded face by face
 * (inner=faces: sl_occ_render_prism_eroded) or by the silhouette of each convex piece (inner=hull,
 * the default: sl_occ_render_prism_hull), meshes by the silhouettes of their convex parts
 * (sl_occ_render_mesh_hull, convex_parts.h). The rasterizer wrapper (raster.c) calls them; the
 * rules are in docs/occlusion.md and docs/culler-contract.md, "Guarantees and resolution". */
#ifndef SL_CULL_OCCLUSION_INNER_COVERAGE_H
#define SL_CULL_OCCLUSION_INNER_COVERAGE_H

#include "cull/occlusion/proxies.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/view.h"

/* A MESH proxy's triangles (all of them when tris is NULL, else the ntris listed) shrunk on screen
 * so that they cover only pixel centres the oracle gives to the object. */
void sl_occ_render_mesh_shrunk(sl_occ_raster *r, const struct sl_scene_t *sc, const sl_occ_view *v, uint32_t mesh,
                               sl_affine xf, const uint32_t *tris, uint32_t ntris);
/* res=any, inner=faces: a prism by the inner coverage of each of its convex faces. */
void sl_occ_render_prism_eroded(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const sl_occ_proxy *pr);
/* res=any, inner=hull: a prism by the inner coverage of each convex piece's silhouette. */
void sl_occ_render_prism_hull(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, const sl_occ_proxy *pr);
/* res=any, inner=hull: a MESH or SCENE_MESH proxy by the silhouettes of its convex parts (the rest
 * shrunk triangle by triangle). */
void sl_occ_render_mesh_hull(sl_occ_raster *r, const sl_occ_set *s, const sl_occ_view *v, uint32_t mesh, sl_affine xf);

#endif

/* The occlusion framework of the online occlusion methods (hzb, hom, lazygrid, lazygrid-z, busygrid,
 * frusta, plp, cplp), one idea a file (issue 13 section 5); this header includes them all (for the
 * tests and the fuzz target; a method includes only the parts it uses):
 *   view.h          the frame's view, box projection, near region, frustum classification
 *   walk.h          the front-to-back BVH walk
 *   proxies.h       occluder proxies (prisms, meshes, scene occluder meshes)
 *   select.h        Coorg-Teller occluder selection
 *   options.h       the options shared by the methods
 *   base.h          the base of every method (BVH, proxies, selection buffers)
 *   raster.h        the rasterizer wrapper (render, count, record, dump)
 *   inner_coverage.h  occluders by inner coverage (res=any)
 *   object_tests.h  hidden-object tests by an object's own triangles and by box rows
 *   exact.h         the exact layer (the oracle's own rasterizer)
 *   pyramid.h       screen pyramids over the rasterizer's subtiles
 *   project.h       (internal to these files) double-precision transforms and projections
 *   ../occlusion_debug.h  depth and pyramid PNGs, frame recording and replay
 * The design is in docs/occlusion.md.
 *
 * Everything here is allocation-free per frame except the rasterizer's (re)creation when the
 * camera's resolution changes and the debugging outputs of the frame asked for.
 */
#ifndef SL_CULL_OCCLUSION_OCCLUSION_H
#define SL_CULL_OCCLUSION_OCCLUSION_H

#include "cull/occlusion/base.h"
#include "cull/occlusion/exact.h"
#include "cull/occlusion/inner_coverage.h"
#include "cull/occlusion/object_tests.h"
#include "cull/occlusion/options.h"
#include "cull/occlusion/proxies.h"
#include "cull/occlusion/pyramid.h"
#include "cull/occlusion/raster.h"
#include "cull/occlusion/select.h"
#include "cull/occlusion/view.h"
#include "cull/occlusion/walk.h"
#include "cull/occlusion_debug.h"

#endif

/* The C interface of moc_peer.h over Intel's Masked Occlusion Culling, compiled only with
 * -DSL_MOC_DIR (MOC's header comes from that checkout). Written for Sightline's benchmark. */
#include "moc_peer.h"

#include <new>

#include "MaskedOcclusionCulling.h"

struct slmoc {
    MaskedOcclusionCulling *moc;
};

static MaskedOcclusionCulling::BackfaceWinding winding(int backface)
{
    return backface == 1 ? MaskedOcclusionCulling::BACKFACE_CW
                         : backface == 2 ? MaskedOcclusionCulling::BACKFACE_CCW : MaskedOcclusionCulling::BACKFACE_NONE;
}

extern "C" {

slmoc *slmoc_create(int isa)
{
    slmoc *m = new (std::nothrow) slmoc;
    if (!m)
        return nullptr;
    m->moc = MaskedOcclusionCulling::Create((MaskedOcclusionCulling::Implementation)isa);
    if (!m->moc) {
        delete m;
        return nullptr;
    }
    return m;
}

void slmoc_destroy(slmoc *m)
{
    if (!m)
        return;
    MaskedOcclusionCulling::Destroy(m->moc);
    delete m;
}

int slmoc_isa(const slmoc *m) { return (int)m->moc->GetImplementation(); }

const char *slmoc_isa_name(int isa)
{
    return isa == SLMOC_SSE2 ? "sse2" : isa == SLMOC_SSE41 ? "sse41" : isa == SLMOC_AVX2 ? "avx2" : isa == SLMOC_AVX512 ? "avx512" : "?";
}

void slmoc_set_resolution(slmoc *m, unsigned width, unsigned height) { m->moc->SetResolution(width, height); }

void slmoc_set_near_clip(slmoc *m, float near_w) { m->moc->SetNearClipPlane(near_w); }

void slmoc_clear(slmoc *m) { m->moc->ClearBuffer(); }

int slmoc_render(slmoc *m, const float *vertices, const unsigned *indices, int triangle_count,
                 const float model_to_clip[16], int backface, int stride, int offset_y, int offset_w, int clip)
{
    MaskedOcclusionCulling::VertexLayout layout(stride, offset_y, offset_w);
    return (int)m->moc->RenderTriangles(vertices, indices, triangle_count, model_to_clip, winding(backface),
                                        clip ? MaskedOcclusionCulling::CLIP_PLANE_ALL : MaskedOcclusionCulling::CLIP_PLANE_NONE,
                                        layout);
}

int slmoc_test_rect(const slmoc *m, float xmin, float ymin, float xmax, float ymax, float wmin)
{
    return (int)m->moc->TestRect(xmin, ymin, xmax, ymax, wmin);
}

int slmoc_test_triangles(slmoc *m, const float *vertices, const unsigned *indices, int triangle_count,
                         const float model_to_clip[16], int backface, int stride, int offset_y, int offset_w)
{
    MaskedOcclusionCulling::VertexLayout layout(stride, offset_y, offset_w);
    return (int)m->moc->TestTriangles(vertices, indices, triangle_count, model_to_clip, winding(backface),
                                      MaskedOcclusionCulling::CLIP_PLANE_ALL, layout);
}
}

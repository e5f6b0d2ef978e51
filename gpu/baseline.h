// `shadowcull bake --method gpu`: the original tool's method, rebuilt on OSMesa. It is the
// baseline every report compares with.
//
//   *** NOT CONSERVATIVE. ***  It samples each light view at pixel centres, so a group lit
//   only through a gap narrower than a pixel (a 2 cm slit), or thinner than one (a 5 mm
//   rod), gets no sample and is culled although its shadow is visible: a false cull. It
//   also ignores bias, slope bias and filter radius. Use it to compare with, never as a
//   proof; the default pipeline's GPU stage is gpu/confirm_stage.h.
//
// Per chunk window and light (occlusion-query shadow caster culling as in D. Bittner,
// O. Mattausch, A. Silvennoinen, M. Wimmer, "Shadow Caster Culling for Efficient Shadow
// Mapping", I3D 2011, here decided offline per primitive group):
//  - light views covering the window: orthographic for a directional light, the six cube
//    faces for a point light, the cone's frustum for a spot light (gpu/light_view.h);
//  - a terrain height pass, only when the window has terrain: receivers under the terrain
//    by more than terrainTolerance are discarded and do not count;
//  - a depth + stencil pass over the whole window (neighbour chunks included): depth keeps
//    the surface nearest the light, the stencil counts every receiving fragment per pixel
//    (front faces, and back faces of two-sided groups; beyond range or outside the cone
//    nothing counts);
//  - an occlusion-query pass over the centre chunk's groups: depth test LEQUAL (the group
//    is the nearest surface there, i.e. lit) and stencil test "more than one fragment here"
//    (something lies behind it). Queries are issued for every group first, then read.
//  - with alpha-tested groups in the window, the two passes run twice, with and without
//    them as occluders (without them, they neither occlude nor count), and the results are
//    OR'ed.
// A bit is kept ("N samples passed at R") when any sample passed, else culled ("0 samples
// passed at R").
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/stage.h"

namespace shadowcull::gpu {

struct GpuBaselineOptions {
    int resolution = 1024;  // pixels per side of each light view (--gpu-resolution)
};

// Samples passed for one bit, summed over views and alpha passes.
struct BaselineCount {
    size_t object = 0;  // index into ChunkVerdicts::objects
    int group = 0;
    int light = 0;
    uint64_t samples = 0;
};

class GpuBaselineMethod : public Stage {
public:
    static constexpr const char* kStageName = "gpu-baseline";

    explicit GpuBaselineMethod(GpuBaselineOptions options = {});
    ~GpuBaselineMethod() override;
    GpuBaselineMethod(const GpuBaselineMethod&) = delete;
    GpuBaselineMethod& operator=(const GpuBaselineMethod&) = delete;

    const char* name() const override { return kStageName; }
    // GlContext::report() of the context the passes ran on ("" before the
    // first run that needed them).
    std::string glDescription() const;
    // Decides every undecided bit of the centre chunk (see above). The OpenGL context is
    // made on the first call; no context is an ErrorKind::Internal error.
    Status run(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats) override;

    // Per-bit sample counts of the last run (bits that were undecided then).
    const std::vector<BaselineCount>& lastCounts() const { return counts_; }

private:
    struct Gl;
    Status ensureGl(int resolution);  // the context, program and target, made on the first call
    GpuBaselineOptions options_;
    std::unique_ptr<Gl> gl_;
    std::vector<BaselineCount> counts_;
};

}  // namespace shadowcull::gpu

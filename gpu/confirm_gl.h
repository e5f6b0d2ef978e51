// The OpenGL resources of the conservative confirmation (confirm_stage.h): its programs,
// render targets and buffers, made once per stage on its first window that needs them
// (GpuConfirmStage::ensureGl, confirm_gl.cpp) and kept while the stage lives. Private to
// the stage's translation units.
#pragma once

#include <memory>
#include <vector>

#include "gpu/confirm_stage.h"
#include "gpu/conservative.h"
#include "gpu/gl_api.h"

namespace shadowcull::gpu {

struct GpuConfirmStage::Gl {
    std::unique_ptr<GlSession> session;
    // The raster programs, one per pass (Pass), then the occluders' resolve and clear.
    enum Pass { kOccluders, kReceivers, kCount, kRecord, kPasses };
    GLuint raster[kPasses] = {0, 0, 0, 0};
    GLuint resolve = 0, clear = 0;
    RenderTarget work, occ, recv;
    GLuint vao = 0, vbo = 0, rectVao = 0, rectVbo = 0;
    GLuint ssbo[4] = {0, 0, 0, 0};  // counts, records, slots, passed pieces (see kConfirmRasterFs)
    size_t vboPieces = 0;  // the piece buffer's size: it only grows (reallocating faulted it in anew per view)
    std::vector<RasterPiece> all;  // a view's pieces, kept for its capacity likewise
    GLint64 maxStorageBlock = 0;  // bytes, GL_MAX_SHADER_STORAGE_BLOCK_SIZE
};

}  // namespace shadowcull::gpu

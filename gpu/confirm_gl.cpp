// Setting up the confirmation passes' OpenGL resources (confirm_gl.h).

#include "gpu/confirm_gl.h"

#include <cstddef>

#include "gpu/confirm_shaders.h"

namespace shadowcull::gpu {

Status GpuConfirmStage::ensureGl() {
    if (gl_) return gl_->session->makeCurrent();
    const int res = options_.resolution;
    if (res < 1) return makeError(ErrorKind::BadInput, "", 0, "GPU resolution must be at least 1");
    auto g = std::make_unique<Gl>();
    Expected<std::unique_ptr<GlSession>> s = openGlSession();
    if (!s) return s.error();
    g->session = std::move(*s);
    const GlApi& gl = g->session->gl;
    for (int pass = 0; pass < Gl::kPasses; ++pass) {
        Expected<GLuint> raster = gl.program(kConfirmRasterVs, nullptr, confirmRasterFs(pass).c_str());
        if (!raster) return raster.error();
        g->raster[pass] = *raster;
    }
    Expected<GLuint> resolve = gl.program(kConfirmRectVs, nullptr, kConfirmResolveFs);
    if (!resolve) return resolve.error();
    g->resolve = *resolve;
    Expected<GLuint> clear = gl.program(kConfirmRectVs, nullptr, kConfirmClearFs);
    if (!clear) return clear.error();
    g->clear = *clear;
    Expected<RenderTarget> work = makeRenderTarget(gl, res, res, {GL_RG32F}, false);
    if (!work) return work.error();
    g->work = *work;
    Expected<RenderTarget> occ = makeRenderTarget(gl, res, res, {GL_R32F}, false);
    if (!occ) return occ.error();
    g->occ = *occ;
    Expected<RenderTarget> recv = makeRenderTarget(gl, res, res, {GL_R32F}, false);
    if (!recv) return recv.error();
    g->recv = *recv;
    gl.GenVertexArrays(1, &g->vao);
    gl.GenVertexArrays(1, &g->rectVao);
    gl.GenBuffers(1, &g->rectVbo);
    gl.BindVertexArray(g->rectVao);
    gl.BindBuffer(GL_ARRAY_BUFFER, g->rectVbo);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 2 * sizeof(float), nullptr);
    gl.GenBuffers(1, &g->vbo);
    gl.BindVertexArray(g->vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, g->vbo);
    const GLsizei stride = sizeof(RasterPiece);
    for (GLuint k = 0; k < 7; ++k) {
        gl.EnableVertexAttribArray(k);
        gl.VertexAttribPointer(k, 4, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<const void*>(size_t(16 * k)));
        gl.VertexAttribDivisor(k, 1);
    }
    gl.EnableVertexAttribArray(7);
    gl.VertexAttribIPointer(7, 1, GL_UNSIGNED_INT, stride, reinterpret_cast<const void*>(offsetof(RasterPiece, id)));
    gl.VertexAttribDivisor(7, 1);
    for (GLuint k = 8; k < 10; ++k) {
        gl.EnableVertexAttribArray(k);
        gl.VertexAttribPointer(k, 4, GL_FLOAT, GL_FALSE, stride,
                               reinterpret_cast<const void*>(offsetof(RasterPiece, cover) + 16 * (k - 8)));
        gl.VertexAttribDivisor(k, 1);
    }
    gl.BindVertexArray(0);
    gl.GenBuffers(4, g->ssbo);
    GLint maxBlock = 0;
    gl.GetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &maxBlock);
    g->maxStorageBlock = maxBlock > 0 ? maxBlock : (16 << 20);
    if (Status st = gl.check("setting up the confirmation passes"); !st) return st;
    gl_ = std::move(g);
    return Status::ok();
}

}  // namespace shadowcull::gpu

// OSMesa implementation of GlContext (see gl_context.h). The only file that sees
// <GL/osmesa.h>; compiled only where libOSMesa is installed (gpu/CMakeLists.txt).

#include <cstring>
#include <vector>

#include <GL/osmesa.h>

#include "gpu/gl_backends.h"

namespace shadowcull::gpu::backends {

namespace {

class OsMesaContext final : public GlContext {
public:
    OsMesaContext(OSMesaContext ctx, int w, int h) : ctx_(ctx), w_(w), h_(h), pixels_(size_t(w) * size_t(h) * 4) {}
    ~OsMesaContext() override {
        if (ctx_) OSMesaDestroyContext(ctx_);
    }
    OsMesaContext(const OsMesaContext&) = delete;
    OsMesaContext& operator=(const OsMesaContext&) = delete;

    bool makeCurrent() override { return OSMesaMakeCurrent(ctx_, pixels_.data(), GL_UNSIGNED_BYTE, w_, h_) == GL_TRUE; }
    void* getProcAddress(const char* name) const override {
        return reinterpret_cast<void*>(OSMesaGetProcAddress(name));
    }
    int width() const override { return w_; }
    int height() const override { return h_; }

private:
    OSMesaContext ctx_ = nullptr;
    int w_, h_;
    std::vector<unsigned char> pixels_;
};

}  // namespace

Expected<std::unique_ptr<GlContext>> createOsMesaContext(int width, int height) {
    // Core profile, newest first: the passes need 4.3 (storage buffers in fragment shaders).
    const int versions[][2] = {{4, 6}, {4, 5}, {4, 3}};
    OSMesaContext ctx = nullptr;
    for (const auto& v : versions) {
        const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 24, OSMESA_STENCIL_BITS, 8,
                               OSMESA_PROFILE, OSMESA_CORE_PROFILE, OSMESA_CONTEXT_MAJOR_VERSION, v[0],
                               OSMESA_CONTEXT_MINOR_VERSION, v[1], 0};
        ctx = OSMesaCreateContextAttribs(attribs, nullptr);
        if (ctx) break;
    }
    if (!ctx) return makeError(ErrorKind::Internal, "", 0, "OSMesaCreateContextAttribs gave no OpenGL 4.3+ core profile context");
    auto context = std::make_unique<OsMesaContext>(ctx, width, height);
    if (Status s = context->identify("OSMesa"); !s) return s.error();
    return std::unique_ptr<GlContext>(std::move(context));
}

}  // namespace shadowcull::gpu::backends

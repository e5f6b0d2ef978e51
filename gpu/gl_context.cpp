// OSMesa implementation of GlContext (see gl_context.h). This is the only file that sees
// <GL/osmesa.h>; everything else uses <GL/glcorearb.h> types and loaded entry points.

#include "gpu/gl_context.h"

#include <cstdlib>
#include <cstring>
#include <vector>

#include <GL/osmesa.h>

namespace shadowcull::gpu {

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
    std::string description() const override { return description_; }
    void setDescription(std::string d) { description_ = std::move(d); }

private:
    OSMesaContext ctx_ = nullptr;
    int w_, h_;
    std::vector<unsigned char> pixels_;
    std::string description_;
};

}  // namespace

Expected<std::unique_ptr<GlContext>> createOffscreenContext(int width, int height) {
    auto fail = [](const std::string& why) {
        return makeError(ErrorKind::Internal, "", 0, "no offscreen OpenGL context: " + why);
    };
    if (std::getenv("SHADOWCULL_NO_GL")) return fail("SHADOWCULL_NO_GL is set");
    if (width < 1 || height < 1) return fail("empty framebuffer size");
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
    if (!ctx) return fail("OSMesaCreateContextAttribs gave no OpenGL 4.3+ core profile context");
    auto context = std::make_unique<OsMesaContext>(ctx, width, height);
    if (!context->makeCurrent()) return fail("OSMesaMakeCurrent failed");
    using GetString = const unsigned char* (*)(unsigned int);
    auto getString = reinterpret_cast<GetString>(context->getProcAddress("glGetString"));
    if (!getString) return fail("glGetString not found");
    const char* version = reinterpret_cast<const char*>(getString(0x1F02 /* GL_VERSION */));
    const char* renderer = reinterpret_cast<const char*>(getString(0x1F01 /* GL_RENDERER */));
    context->setDescription(std::string("OSMesa, OpenGL ") + (version ? version : "?") + ", " +
                            (renderer ? renderer : "?"));
    return std::unique_ptr<GlContext>(std::move(context));
}

}  // namespace shadowcull::gpu

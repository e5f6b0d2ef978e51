// gpu/: a small interface over an offscreen OpenGL context, so that the GPU passes do not
// depend on how the context was made. Two implementations, neither with a window:
//  - EGL (gl_context_egl.cpp): a device display (EGL_EXT_platform_device: headless NVIDIA,
//    AMD, Intel drivers and Mesa's software device) or Mesa's surfaceless platform
//    (EGL_MESA_platform_surfaceless, llvmpipe on a machine without a GPU);
//  - OSMesa (gl_context_osmesa.cpp): Mesa's off-screen renderer, built only where
//    libOSMesa is installed (gone from Mesa 25.1 on).
// Every pass renders into its own framebuffer objects and only needs makeCurrent() and
// getProcAddress(); all GL functions are loaded through getProcAddress() (gpu/gl_api.h),
// never linked from libGL (OpenGL::GL), whose dispatch table is not the one the
// context's own entry points use. What was found about EGL and OSMesa in one process is
// in docs/design.md ("OpenGL backends").
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "util/status.h"

namespace shadowcull::gpu {

class GlContext {
public:
    virtual ~GlContext() = default;
    // Makes the context current on the calling thread (one thread at a time).
    virtual bool makeCurrent() = 0;
    // Address of a GL entry point, or nullptr.
    virtual void* getProcAddress(const char* name) const = 0;
    // The context's own offscreen framebuffer size (EGL contexts have none: the passes
    // render into framebuffer objects of their own).
    virtual int width() const = 0;
    virtual int height() const = 0;
    // "EGL surfaceless: Mesa/X.org, llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core
    // Profile) Mesa 22.3.6": the backend, then GL_VENDOR, GL_RENDERER, GL_VERSION, for reports.
    std::string description() const { return backend_ + ": " + vendor_ + ", " + renderer_ + ", OpenGL " + version_; }
    const std::string& backend() const { return backend_; }  // "EGL device 0", "EGL surfaceless", "OSMesa"
    const std::string& vendor() const { return vendor_; }
    const std::string& renderer() const { return renderer_; }
    const std::string& version() const { return version_; }
    // What the choice tried before this backend, and why each failed ("EGL device: no
    // hardware device (1 found: 0 software)"); "" when the first try gave this context.
    const std::string& passedOver() const { return passedOver_; }
    void setPassedOver(std::string tried) { passedOver_ = std::move(tried); }
    // The "OpenGL:" line of the reports: description(), then what auto passed over, so a
    // machine whose GPU was expected but not used says why.
    std::string report() const {
        return passedOver_.empty() ? description() : description() + " (passed over: " + passedOver_ + ")";
    }

    // Makes the context current, reads GL_VENDOR / GL_RENDERER / GL_VERSION and refuses a
    // GL older than 4.3 (the passes use storage buffers in fragment shaders). Called once
    // by each implementation's factory.
    Status identify(std::string backend);

private:
    std::string backend_, vendor_, renderer_, version_, passedOver_;
};

// Which backend createOffscreenContext uses. Auto: a hardware EGL device, then Mesa's
// surfaceless platform, then OSMesa. Egl: an EGL device (the given one, else a hardware
// one), then surfaceless; never OSMesa. OsMesa: only OSMesa.
enum class GlBackend { Auto, Egl, OsMesa };
struct GlChoice {
    GlBackend backend = GlBackend::Auto;
    int device = -1;  // EGL device index (as `shadowcull --version` lists them); -1: pick one
};

// "auto", "egl", "osmesa" -> GlBackend; nullopt-like error for anything else.
Expected<GlBackend> parseGlBackend(const std::string& name);
const char* glBackendName(GlBackend backend);

// The process-wide choice createOffscreenContext(w, h) uses. It starts from the
// environment (SHADOWCULL_GL=auto|egl|osmesa, SHADOWCULL_GL_DEVICE=N; unset or invalid:
// auto), so that a test suite or a child process can be pointed at one backend; the CLI's
// --gl / --gl-device set it for the run.
void setGlChoice(const GlChoice& choice);
GlChoice glChoice();

// An offscreen OpenGL 4.3+ core context (4.6, 4.5 asked first) on the chosen backend.
// ErrorKind::Internal when none can be made; the message says what each backend tried
// said ("EGL device: no hardware device (1 found: 0 software); EGL surfaceless: ...").
// Setting the environment variable SHADOWCULL_NO_GL makes it fail, to exercise the paths
// that run without a context. width x height is the OSMesa framebuffer (EGL has none).
Expected<std::unique_ptr<GlContext>> createOffscreenContext(int width, int height);
Expected<std::unique_ptr<GlContext>> createOffscreenContext(int width, int height, const GlChoice& choice);

// What this machine offers, one line per backend or EGL device, for `shadowcull
// --version`: "EGL device 0: software (llvmpipe ...), OpenGL 4.5 ..." or why not.
std::vector<std::string> listGlBackends();

}  // namespace shadowcull::gpu

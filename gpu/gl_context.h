// gpu/: a small interface over an offscreen OpenGL context, so that the GPU passes do not
// depend on how the context was made. The implementation here is OSMesa (Mesa's
// off-screen renderer; llvmpipe gives OpenGL 4.5 core on a machine without a GPU). Where a
// Mesa no longer ships OSMesa, an EGL surfaceless context (EGL_MESA_platform_surfaceless,
// or EGL_KHR_surfaceless_context on a device display) can implement the same interface:
// every pass renders into its own framebuffer objects and only needs makeCurrent() and
// getProcAddress().
//
// Link only libOSMesa, never libGL beside it: both carry a GL dispatch table, and entry
// points taken from one while the other's context is current do nothing or crash. All GL
// functions are therefore loaded through getProcAddress() (gpu/gl_api.h).
#pragma once

#include <memory>
#include <string>

#include "core/status.h"

namespace shadowcull::gpu {

class GlContext {
public:
    virtual ~GlContext() = default;
    // Makes the context current on the calling thread (one thread at a time).
    virtual bool makeCurrent() = 0;
    // Address of a GL entry point, or nullptr.
    virtual void* getProcAddress(const char* name) const = 0;
    // The context's own offscreen framebuffer (the passes render into FBOs of their own).
    virtual int width() const = 0;
    virtual int height() const = 0;
    // "OSMesa, OpenGL 4.5 (Core Profile) Mesa 22.3.6, llvmpipe (...)" for reports.
    virtual std::string description() const = 0;
};

// An offscreen OpenGL 4.3+ core context with a w x h RGBA framebuffer (OpenGL 4.5 asked
// first). ErrorKind::Internal when none can be made (no OSMesa, no core profile, a GL
// older than 4.3). Setting the environment variable SHADOWCULL_NO_GL makes it fail, to
// exercise the paths that run without a context.
Expected<std::unique_ptr<GlContext>> createOffscreenContext(int width, int height);

}  // namespace shadowcull::gpu

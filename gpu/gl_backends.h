// The backends behind createOffscreenContext (gpu/gl_context.h), for gl_context.cpp only.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gpu/gl_context.h"
#include "util/status.h"

namespace shadowcull::gpu::backends {

// One EGL device as EGL_EXT_device_enumeration lists it.
struct EglDeviceInfo {
    int index = 0;
    bool software = false;  // EGL_MESA_device_software: Mesa's llvmpipe device, no GPU
    std::string node;       // DRM render node ("/dev/dri/renderD128"), or empty
};

// The devices, or an error saying why none can be listed (no EGL_EXT_platform_device ...).
Expected<std::vector<EglDeviceInfo>> eglDevices();
// A context on device `index` (EGL_EXT_platform_device).
Expected<std::unique_ptr<GlContext>> createEglDeviceContext(int index);
// A context on Mesa's surfaceless platform (EGL_MESA_platform_surfaceless).
Expected<std::unique_ptr<GlContext>> createEglSurfacelessContext();
// An OSMesa context with a width x height RGBA framebuffer; an error when the build has
// no OSMesa (SHADOWCULL_HAVE_OSMESA unset) or the library makes no 4.3+ core context.
Expected<std::unique_ptr<GlContext>> createOsMesaContext(int width, int height);

}  // namespace shadowcull::gpu::backends

// EGL implementation of GlContext (see gl_context.h): no window and no surface. A context
// is made current with EGL_NO_SURFACE (EGL_KHR_surfaceless_context) and the passes render
// into framebuffer objects. The only file that sees <EGL/egl.h>.

#include <algorithm>
#include <cstdio>
#include <cstring>

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include "gpu/gl_backends.h"

namespace shadowcull::gpu::backends {

namespace {

Error eglFailure(const std::string& what) {
    char code[16];
    std::snprintf(code, sizeof code, "0x%04X", unsigned(eglGetError()));
    return makeError(ErrorKind::Internal, "", 0, what + " failed (EGL error " + code + ")");
}

bool hasExtension(const char* list, const char* name) {
    if (!list) return false;
    const size_t n = std::strlen(name);
    for (const char* p = std::strstr(list, name); p; p = std::strstr(p + n, name))
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

// EGL displays are per process (one per platform and native display) and one
// eglTerminate ends every context on them; initialising one loads the driver again. So a
// display is initialised once (eglInitialize of an initialised display does nothing) and
// never terminated: it lives as long as the process, like the driver it loaded.
Status initializeDisplay(EGLDisplay display) {
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) return eglFailure("eglInitialize");
    return Status::ok();
}

class EglContext final : public GlContext {
public:
    EglContext(EGLDisplay display, EGLContext context) : display_(display), context_(context) {}
    ~EglContext() override {
        if (eglGetCurrentContext() == context_) eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(display_, context_);
    }
    EglContext(const EglContext&) = delete;
    EglContext& operator=(const EglContext&) = delete;

    bool makeCurrent() override {
        // Binding the API is per thread: a new thread starts on EGL_OPENGL_ES_API.
        return eglBindAPI(EGL_OPENGL_API) && eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_);
    }
    void* getProcAddress(const char* name) const override {
        // EGL_KHR_get_all_proc_addresses: core entry points come back too.
        return reinterpret_cast<void*>(eglGetProcAddress(name));
    }
    int width() const override { return 0; }
    int height() const override { return 0; }

private:
    EGLDisplay display_;
    EGLContext context_;
};

// A 4.3+ core context on the display.
Expected<std::unique_ptr<GlContext>> contextOn(EGLDisplay display, const std::string& backend) {
    if (Status s = initializeDisplay(display); !s) return s.error();
    const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
    if (!hasExtension(extensions, "EGL_KHR_surfaceless_context"))
        return makeError(ErrorKind::Internal, "", 0, "the display has no EGL_KHR_surfaceless_context");
    if (!eglBindAPI(EGL_OPENGL_API)) return eglFailure("eglBindAPI(EGL_OPENGL_API)");
    // No surface is ever made, so any config that renders OpenGL will do; without one,
    // EGL_KHR_no_config_context.
    EGLConfig config = nullptr;
    const EGLint configAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint configs = 0;
    if (!eglChooseConfig(display, configAttribs, &config, 1, &configs) || configs < 1) {
        if (!hasExtension(extensions, "EGL_KHR_no_config_context"))
            return makeError(ErrorKind::Internal, "", 0, "the display has no OpenGL config");
        config = EGL_NO_CONFIG_KHR;
    }
    const int versions[][2] = {{4, 6}, {4, 5}, {4, 3}};
    EGLContext context = EGL_NO_CONTEXT;
    for (const auto& v : versions) {
        const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, v[0], EGL_CONTEXT_MINOR_VERSION, v[1],
                                  EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
        context = eglCreateContext(display, config, EGL_NO_CONTEXT, attribs);
        if (context != EGL_NO_CONTEXT) break;
    }
    if (context == EGL_NO_CONTEXT) return eglFailure("eglCreateContext (OpenGL 4.3+ core)");
    auto ctx = std::make_unique<EglContext>(display, context);
    if (Status s = ctx->identify(backend); !s) return s.error();
    return std::unique_ptr<GlContext>(std::move(ctx));
}

template <typename F>
F loadEgl(const char* name) {
    return reinterpret_cast<F>(eglGetProcAddress(name));
}

struct DeviceApi {
    PFNEGLQUERYDEVICESEXTPROC queryDevices = nullptr;
    PFNEGLQUERYDEVICESTRINGEXTPROC queryDeviceString = nullptr;
    PFNEGLGETPLATFORMDISPLAYEXTPROC platformDisplay = nullptr;
};

Expected<DeviceApi> deviceApi() {
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!hasExtension(client, "EGL_EXT_platform_device"))
        return makeError(ErrorKind::Internal, "", 0, "libEGL has no EGL_EXT_platform_device");
    DeviceApi api;
    api.queryDevices = loadEgl<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
    api.queryDeviceString = loadEgl<PFNEGLQUERYDEVICESTRINGEXTPROC>("eglQueryDeviceStringEXT");
    api.platformDisplay = loadEgl<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
    if (!api.queryDevices || !api.queryDeviceString || !api.platformDisplay)
        return makeError(ErrorKind::Internal, "", 0, "libEGL lacks eglQueryDevicesEXT / eglGetPlatformDisplayEXT");
    return api;
}

Expected<std::vector<EGLDeviceEXT>> deviceHandles(const DeviceApi& api) {
    EGLint n = 0;
    if (!api.queryDevices(0, nullptr, &n)) return eglFailure("eglQueryDevicesEXT");
    std::vector<EGLDeviceEXT> devices(size_t(std::max(n, 0)));
    if (n > 0 && !api.queryDevices(n, devices.data(), &n)) return eglFailure("eglQueryDevicesEXT");
    devices.resize(size_t(std::max(n, 0)));
    return devices;
}

}  // namespace

Expected<std::vector<EglDeviceInfo>> eglDevices() {
    Expected<DeviceApi> api = deviceApi();
    if (!api) return api.error();
    Expected<std::vector<EGLDeviceEXT>> handles = deviceHandles(*api);
    if (!handles) return handles.error();
    std::vector<EglDeviceInfo> out;
    for (size_t k = 0; k < handles->size(); ++k) {
        EglDeviceInfo d;
        d.index = int(k);
        const char* ext = api->queryDeviceString((*handles)[k], EGL_EXTENSIONS);
        d.software = hasExtension(ext, "EGL_MESA_device_software");
        if (hasExtension(ext, "EGL_EXT_device_drm_render_node")) {
            const char* node = api->queryDeviceString((*handles)[k], EGL_DRM_RENDER_NODE_FILE_EXT);
            if (node) d.node = node;
        }
        if (d.node.empty() && hasExtension(ext, "EGL_EXT_device_drm")) {
            const char* node = api->queryDeviceString((*handles)[k], EGL_DRM_DEVICE_FILE_EXT);
            if (node) d.node = node;
        }
        out.push_back(d);
    }
    return out;
}

Expected<std::unique_ptr<GlContext>> createEglDeviceContext(int index) {
    Expected<DeviceApi> api = deviceApi();
    if (!api) return api.error();
    Expected<std::vector<EGLDeviceEXT>> handles = deviceHandles(*api);
    if (!handles) return handles.error();
    if (index < 0 || size_t(index) >= handles->size())
        return makeError(ErrorKind::Internal, "", 0, "no EGL device " + std::to_string(index) + " (" + std::to_string(handles->size()) + " found)");
    EGLDisplay display = api->platformDisplay(EGL_PLATFORM_DEVICE_EXT, (*handles)[size_t(index)], nullptr);
    if (display == EGL_NO_DISPLAY) return eglFailure("eglGetPlatformDisplayEXT(device " + std::to_string(index) + ")");
    return contextOn(display, "EGL device " + std::to_string(index));
}

Expected<std::unique_ptr<GlContext>> createEglSurfacelessContext() {
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!hasExtension(client, "EGL_MESA_platform_surfaceless"))
        return makeError(ErrorKind::Internal, "", 0, "libEGL has no EGL_MESA_platform_surfaceless");
    auto platformDisplay = loadEgl<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
    if (!platformDisplay) return makeError(ErrorKind::Internal, "", 0, "libEGL lacks eglGetPlatformDisplayEXT");
    EGLDisplay display = platformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (display == EGL_NO_DISPLAY) return eglFailure("eglGetPlatformDisplayEXT(surfaceless)");
    return contextOn(display, "EGL surfaceless");
}

}  // namespace shadowcull::gpu::backends

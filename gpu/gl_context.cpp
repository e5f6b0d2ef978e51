// The backend choice behind createOffscreenContext (see gl_context.h): auto tries a
// hardware EGL device, then Mesa's surfaceless platform, then OSMesa, and says what each
// one answered when none gives a context.

#include "gpu/gl_context.h"

#include <atomic>
#include <cstdlib>
#include <mutex>

#include "gpu/gl_backends.h"

namespace shadowcull::gpu {

Status GlContext::identify(std::string backend) {
    backend_ = std::move(backend);
    if (!makeCurrent()) return makeError(ErrorKind::Internal, "", 0, backend_ + ": cannot make the context current");
    using GetString = const unsigned char* (*)(unsigned int);
    auto getString = reinterpret_cast<GetString>(getProcAddress("glGetString"));
    if (!getString) return makeError(ErrorKind::Internal, "", 0, backend_ + ": glGetString not found");
    auto text = [&](unsigned int name) {
        const char* s = reinterpret_cast<const char*>(getString(name));
        return std::string(s ? s : "?");
    };
    vendor_ = text(0x1F00 /* GL_VENDOR */);
    renderer_ = text(0x1F01 /* GL_RENDERER */);
    version_ = text(0x1F02 /* GL_VERSION */);
    // "4.5 (Core Profile) Mesa 22.3.6", "4.6.0 NVIDIA 550.54": major.minor lead.
    int major = 0, minor = 0;
    if (std::sscanf(version_.c_str(), "%d.%d", &major, &minor) != 2 || major * 10 + minor < 43)
        return makeError(ErrorKind::Internal, "", 0, backend_ + ": OpenGL " + version_ + " is older than 4.3");
    return Status::ok();
}

Expected<GlBackend> parseGlBackend(const std::string& name) {
    if (name == "auto") return GlBackend::Auto;
    if (name == "egl") return GlBackend::Egl;
    if (name == "osmesa") return GlBackend::OsMesa;
    return makeError(ErrorKind::BadInput, "", 0, "unknown OpenGL backend '" + name + "' (auto, egl or osmesa)");
}

const char* glBackendName(GlBackend backend) {
    switch (backend) {
        case GlBackend::Egl: return "egl";
        case GlBackend::OsMesa: return "osmesa";
        case GlBackend::Auto: break;
    }
    return "auto";
}

namespace {

std::mutex choiceMutex;

GlChoice& currentChoice() {
    static GlChoice choice = [] {
        GlChoice c;
        if (const char* b = std::getenv("SHADOWCULL_GL"))
            if (Expected<GlBackend> parsed = parseGlBackend(b)) c.backend = *parsed;
        if (const char* d = std::getenv("SHADOWCULL_GL_DEVICE")) {
            char* end = nullptr;
            const long n = std::strtol(d, &end, 10);
            if (end != d && *end == '\0' && n >= 0 && n < 1000) c.device = int(n);
        }
        return c;
    }();
    return choice;
}

// "0 software", "1 /dev/dri/renderD128" for the messages.
std::string deviceList(const std::vector<backends::EglDeviceInfo>& devices) {
    std::string s;
    for (const auto& d : devices) {
        if (!s.empty()) s += ", ";
        s += std::to_string(d.index) + (d.software ? " software" : d.node.empty() ? " (no render node)" : " " + d.node);
    }
    return s;
}

// A hardware EGL device (the first one that is not Mesa's software device and gives a
// context), or why none.
Expected<std::unique_ptr<GlContext>> hardwareDevice() {
    Expected<std::vector<backends::EglDeviceInfo>> devices = backends::eglDevices();
    if (!devices) return devices.error();
    std::string why;
    for (const auto& d : *devices) {
        if (d.software) continue;
        Expected<std::unique_ptr<GlContext>> ctx = backends::createEglDeviceContext(d.index);
        if (ctx) return ctx;
        why += "; device " + std::to_string(d.index) + ": " + ctx.error().message;
    }
    return makeError(ErrorKind::Internal, "", 0,
                     "no hardware device (" + std::to_string(devices->size()) + " found" +
                         (devices->empty() ? "" : ": " + deviceList(*devices)) + ")" + why);
}

}  // namespace

void setGlChoice(const GlChoice& choice) {
    std::lock_guard<std::mutex> lock(choiceMutex);
    currentChoice() = choice;
}

GlChoice glChoice() {
    std::lock_guard<std::mutex> lock(choiceMutex);
    return currentChoice();
}

Expected<std::unique_ptr<GlContext>> createOffscreenContext(int width, int height) {
    return createOffscreenContext(width, height, glChoice());
}

Expected<std::unique_ptr<GlContext>> createOffscreenContext(int width, int height, const GlChoice& choice) {
    auto fail = [](const std::string& why) {
        return makeError(ErrorKind::Internal, "", 0, "no offscreen OpenGL context: " + why);
    };
    if (std::getenv("SHADOWCULL_NO_GL")) return fail("SHADOWCULL_NO_GL is set");
    if (width < 1 || height < 1) return fail("empty framebuffer size");
    std::string tried;
    auto note = [&](const char* what, const Error& e) { tried += (tried.empty() ? "" : "; ") + std::string(what) + ": " + e.message; };
    if (choice.backend != GlBackend::OsMesa) {
        // A device asked for by number is used or refused, never swapped for another one.
        if (choice.device >= 0) {
            Expected<std::unique_ptr<GlContext>> ctx = backends::createEglDeviceContext(choice.device);
            if (!ctx) return fail("EGL device " + std::to_string(choice.device) + ": " + ctx.error().message);
            return ctx;
        }
        Expected<std::unique_ptr<GlContext>> device = hardwareDevice();
        if (device) return device;
        note("EGL device", device.error());
        Expected<std::unique_ptr<GlContext>> surfaceless = backends::createEglSurfacelessContext();
        if (surfaceless) {
            (*surfaceless)->setPassedOver(tried);
            return surfaceless;
        }
        note("EGL surfaceless", surfaceless.error());
    }
    if (choice.backend != GlBackend::Egl) {
        Expected<std::unique_ptr<GlContext>> osmesa = backends::createOsMesaContext(width, height);
        if (osmesa) {
            (*osmesa)->setPassedOver(tried);
            return osmesa;
        }
        note("OSMesa", osmesa.error());
    }
    return fail(tried);
}

std::vector<std::string> listGlBackends() {
    std::vector<std::string> lines;
    if (std::getenv("SHADOWCULL_NO_GL")) return {"none (SHADOWCULL_NO_GL is set)"};
    auto line = [&](const std::string& name, const Expected<std::unique_ptr<GlContext>>& ctx) {
        lines.push_back(ctx ? (*ctx)->description() : name + ": unavailable (" + ctx.error().message + ")");
    };
    Expected<std::vector<backends::EglDeviceInfo>> devices = backends::eglDevices();
    if (!devices) {
        lines.push_back("EGL devices: unavailable (" + devices.error().message + ")");
    } else {
        if (devices->empty()) lines.push_back("EGL devices: none found");
        for (const auto& d : *devices) {
            const std::string name = "EGL device " + std::to_string(d.index);
            Expected<std::unique_ptr<GlContext>> ctx = backends::createEglDeviceContext(d.index);
            line(name, ctx);
            lines.back() += d.software ? " [software]" : d.node.empty() ? "" : " [" + d.node + "]";
        }
    }
    line("EGL surfaceless", backends::createEglSurfacelessContext());
    line("OSMesa", backends::createOsMesaContext(16, 16));
    return lines;
}

}  // namespace shadowcull::gpu

#include "gpu/gl_api.h"

#include <atomic>
#include <mutex>

namespace shadowcull::gpu {

namespace {

// The object counts behind liveGlObjects(): the entry points that make and delete objects
// are wrapped by functions that count, then call the library's. OSMesa hands out the same
// entry points for every context (they dispatch on the current one), so one table of the
// library's functions serves every GlApi.
enum ObjectKind { kBuffers, kVertexArrays, kTextures, kFramebuffers, kRenderbuffers, kQueries, kShaders, kPrograms, kKinds };
std::atomic<int64_t> liveObjects[kKinds];
GlApi library;  // the library's entry points of the wrapped functions (set once)
std::once_flag libraryLoaded;

int64_t named(GLsizei n, const GLuint* ids) {
    int64_t k = 0;
    for (GLsizei i = 0; i < n; ++i) k += ids[i] != 0;
    return k;
}

#define SHADOWCULL_GL_COUNTED_PAIR(kind, Gen, Delete)                                   \
    void APIENTRY counted##Gen(GLsizei n, GLuint* ids) {                                \
        library.Gen(n, ids);                                                            \
        liveObjects[kind] += named(n, ids);                                             \
    }                                                                                   \
    void APIENTRY counted##Delete(GLsizei n, const GLuint* ids) {                       \
        liveObjects[kind] -= named(n, ids);                                             \
        library.Delete(n, ids);                                                         \
    }
SHADOWCULL_GL_COUNTED_PAIR(kBuffers, GenBuffers, DeleteBuffers)
SHADOWCULL_GL_COUNTED_PAIR(kVertexArrays, GenVertexArrays, DeleteVertexArrays)
SHADOWCULL_GL_COUNTED_PAIR(kTextures, GenTextures, DeleteTextures)
SHADOWCULL_GL_COUNTED_PAIR(kFramebuffers, GenFramebuffers, DeleteFramebuffers)
SHADOWCULL_GL_COUNTED_PAIR(kRenderbuffers, GenRenderbuffers, DeleteRenderbuffers)
SHADOWCULL_GL_COUNTED_PAIR(kQueries, GenQueries, DeleteQueries)
#undef SHADOWCULL_GL_COUNTED_PAIR

GLuint APIENTRY countedCreateShader(GLenum type) {
    const GLuint s = library.CreateShader(type);
    liveObjects[kShaders] += s != 0;
    return s;
}
void APIENTRY countedDeleteShader(GLuint s) {
    liveObjects[kShaders] -= s != 0;
    library.DeleteShader(s);
}
GLuint APIENTRY countedCreateProgram() {
    const GLuint p = library.CreateProgram();
    liveObjects[kPrograms] += p != 0;
    return p;
}
void APIENTRY countedDeleteProgram(GLuint p) {
    liveObjects[kPrograms] -= p != 0;
    library.DeleteProgram(p);
}

#define SHADOWCULL_GL_COUNTED(X)                                                                              \
    X(GenBuffers) X(DeleteBuffers) X(GenVertexArrays) X(DeleteVertexArrays) X(GenTextures) X(DeleteTextures) \
    X(GenFramebuffers) X(DeleteFramebuffers) X(GenRenderbuffers) X(DeleteRenderbuffers) X(GenQueries)       \
    X(DeleteQueries) X(CreateShader) X(DeleteShader) X(CreateProgram) X(DeleteProgram)

}  // namespace

GlObjectCounts liveGlObjects() {
    GlObjectCounts c;
    c.buffers = liveObjects[kBuffers], c.vertexArrays = liveObjects[kVertexArrays];
    c.textures = liveObjects[kTextures], c.framebuffers = liveObjects[kFramebuffers];
    c.renderbuffers = liveObjects[kRenderbuffers], c.queries = liveObjects[kQueries];
    c.shaders = liveObjects[kShaders], c.programs = liveObjects[kPrograms];
    return c;
}

Status GlApi::load(const GlContext& context) {
#define SHADOWCULL_GL_LOAD(type, name)                                                           \
    name = reinterpret_cast<type>(context.getProcAddress("gl" #name));                          \
    if (!name) return makeError(ErrorKind::Internal, "", 0, "OpenGL entry point gl" #name " not found");
    SHADOWCULL_GL_FUNCTIONS(SHADOWCULL_GL_LOAD)
#undef SHADOWCULL_GL_LOAD
    // Count the objects made and deleted (see liveGlObjects), when this context's entry
    // points are the library's first ones (always, with one backend per process).
    std::call_once(libraryLoaded, [&] {
#define SHADOWCULL_GL_KEEP(name) library.name = name;
        SHADOWCULL_GL_COUNTED(SHADOWCULL_GL_KEEP)
#undef SHADOWCULL_GL_KEEP
    });
    bool same = true;
#define SHADOWCULL_GL_SAME(name) same &= library.name == name;
    SHADOWCULL_GL_COUNTED(SHADOWCULL_GL_SAME)
#undef SHADOWCULL_GL_SAME
    if (same) {
#define SHADOWCULL_GL_WRAP(name) name = &counted##name;
        SHADOWCULL_GL_COUNTED(SHADOWCULL_GL_WRAP)
#undef SHADOWCULL_GL_WRAP
    }
    return Status::ok();
}

Status GlApi::check(const char* what) const {
    const GLenum e = GetError();
    if (e == GL_NO_ERROR) return Status::ok();
    while (GetError() != GL_NO_ERROR) {
    }
    return makeError(ErrorKind::Internal, "", 0, std::string("OpenGL error ") + std::to_string(e) + " in " + what);
}

namespace {

Expected<GLuint> compile(const GlApi& gl, GLenum kind, const char* source) {
    GLuint s = gl.CreateShader(kind);
    gl.ShaderSource(s, 1, &source, nullptr);
    gl.CompileShader(s);
    GLint ok = 0;
    gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[4096] = {0};
        gl.GetShaderInfoLog(s, sizeof log - 1, nullptr, log);
        gl.DeleteShader(s);
        return makeError(ErrorKind::Internal, "", 0, std::string("GLSL compile error: ") + log);
    }
    return s;
}

}  // namespace

Expected<GLuint> GlApi::program(const char* vertex, const char* geometry, const char* fragment) const {
    std::vector<GLuint> shaders;
    auto cleanup = [&] {
        for (GLuint s : shaders) DeleteShader(s);
    };
    const std::pair<GLenum, const char*> stages[] = {
        {GL_VERTEX_SHADER, vertex}, {GL_GEOMETRY_SHADER, geometry}, {GL_FRAGMENT_SHADER, fragment}};
    for (const auto& [kind, src] : stages) {
        if (!src) continue;
        Expected<GLuint> s = compile(*this, kind, src);
        if (!s) {
            cleanup();
            return s.error();
        }
        shaders.push_back(*s);
    }
    GLuint p = CreateProgram();
    for (GLuint s : shaders) AttachShader(p, s);
    LinkProgram(p);
    cleanup();
    GLint ok = 0;
    GetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[4096] = {0};
        GetProgramInfoLog(p, sizeof log - 1, nullptr, log);
        DeleteProgram(p);
        return makeError(ErrorKind::Internal, "", 0, std::string("GLSL link error: ") + log);
    }
    return p;
}

Expected<RenderTarget> makeRenderTarget(const GlApi& gl, int width, int height, const std::vector<GLenum>& formats,
                                        bool depthStencil) {
    // Too large a target fails with a GL error later, or not at all on some drivers: say so
    // up front, against the limit of what is allocated (textures, a renderbuffer).
    auto limit = [&](GLenum name, const char* what) -> Status {
        GLint max = 0;
        gl.GetIntegerv(name, &max);
        if (width > max || height > max)
            return makeError(ErrorKind::Internal, "", 0,
                             "GPU render target " + std::to_string(width) + " x " + std::to_string(height) +
                                 " exceeds the " + what + " limit " + std::to_string(max) + " (lower --gpu-resolution)");
        return Status::ok();
    };
    if (!formats.empty())
        if (Status s = limit(GL_MAX_TEXTURE_SIZE, "texture"); !s) return s.error();
    if (depthStencil)
        if (Status s = limit(GL_MAX_RENDERBUFFER_SIZE, "renderbuffer"); !s) return s.error();
    RenderTarget t;
    t.width = width;
    t.height = height;
    gl.GenFramebuffers(1, &t.fbo);
    gl.BindFramebuffer(GL_FRAMEBUFFER, t.fbo);
    std::vector<GLenum> drawBuffers;
    for (size_t k = 0; k < formats.size(); ++k) {
        GLuint tex = 0;
        gl.GenTextures(1, &tex);
        gl.BindTexture(GL_TEXTURE_2D, tex);
        gl.TexStorage2D(GL_TEXTURE_2D, 1, formats[k], width, height);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        gl.FramebufferTexture2D(GL_FRAMEBUFFER, GLenum(GL_COLOR_ATTACHMENT0 + k), GL_TEXTURE_2D, tex, 0);
        t.colour.push_back(tex);
    }
    if (depthStencil) {
        gl.GenRenderbuffers(1, &t.depthStencil);
        gl.BindRenderbuffer(GL_RENDERBUFFER, t.depthStencil);
        gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH32F_STENCIL8, width, height);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, t.depthStencil);
    }
    const GLenum status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
        destroyRenderTarget(gl, t);
        return makeError(ErrorKind::Internal, "", 0,
                         "OpenGL framebuffer " + std::to_string(width) + "x" + std::to_string(height) +
                             " incomplete (status " + std::to_string(status) + ")");
    }
    if (Status s = gl.check("creating a render target"); !s) {
        destroyRenderTarget(gl, t);
        return s.error();
    }
    return t;
}

void destroyRenderTarget(const GlApi& gl, RenderTarget& t) {
    if (!t.colour.empty()) gl.DeleteTextures(GLsizei(t.colour.size()), t.colour.data());
    if (t.depthStencil) gl.DeleteRenderbuffers(1, &t.depthStencil);
    if (t.fbo) gl.DeleteFramebuffers(1, &t.fbo);
    t = RenderTarget{};
}

std::vector<float> readFloatPixels(const GlApi& gl, const RenderTarget& t, int attachment, int channels, int channel) {
    std::vector<float> all(size_t(t.width) * size_t(t.height) * size_t(channels));
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, t.fbo);
    gl.ReadBuffer(GLenum(GL_COLOR_ATTACHMENT0 + attachment));
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, t.width, t.height, channels == 1 ? GL_RED : channels == 2 ? GL_RG : GL_RGBA, GL_FLOAT,
                  all.data());
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    std::vector<float> out(size_t(t.width) * size_t(t.height));
    for (size_t k = 0; k < out.size(); ++k) out[k] = all[k * size_t(channels) + size_t(channel)];
    return out;
}

}  // namespace shadowcull::gpu

namespace shadowcull::gpu {

Status GlSession::makeCurrent() const {
    if (!context || !context->makeCurrent())
        return makeError(ErrorKind::Internal, "", 0, "cannot make the OpenGL context current");
    return Status::ok();
}

Expected<std::unique_ptr<GlSession>> openGlSession() {
    Expected<std::unique_ptr<GlContext>> ctx = createOffscreenContext(16, 16);
    if (!ctx) return ctx.error();
    auto session = std::make_unique<GlSession>();
    session->context = std::move(*ctx);
    if (Status s = session->makeCurrent(); !s) return s.error();
    if (Status s = session->gl.load(*session->context); !s) return s.error();
    return session;
}

GpuTimer::GpuTimer(const GlApi& gl) : gl_(gl), wallStart_(std::chrono::steady_clock::now()) {
    GLint bits = 0;
    gl_.GetQueryiv(GL_TIMESTAMP, GL_QUERY_COUNTER_BITS, &bits);
    if (bits <= 0) return;
    gl_.GenQueries(2, queries_);
    gl_.QueryCounter(queries_[0], GL_TIMESTAMP);
}

GpuTimer::~GpuTimer() {
    if (queries_[0]) gl_.DeleteQueries(2, queries_);
}

void GpuTimer::addTo(StageStats& stats) {
    if (!queries_[0]) return;
    gl_.QueryCounter(queries_[1], GL_TIMESTAMP);
    GLuint64 t0 = 0, t1 = 0;
    gl_.GetQueryObjectui64v(queries_[0], GL_QUERY_RESULT, &t0);
    gl_.GetQueryObjectui64v(queries_[1], GL_QUERY_RESULT, &t1);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wallStart_).count();
    const double gpu = t1 >= t0 ? double(t1 - t0) * 1e-9 : -1.0;
    if (gpu < 0.0 || gpu > wall) return;
    stats.gpuSeconds += gpu;
    stats.gpuTimed = true;
}

}  // namespace shadowcull::gpu

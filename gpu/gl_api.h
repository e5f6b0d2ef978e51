// The GL entry points the passes use, loaded through GlContext::getProcAddress (no libGL
// at link time, see gl_context.h), and a few small RAII helpers: programs, textures,
// framebuffers and buffers. Errors come back as ErrorKind::Internal.
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include <GL/glcorearb.h>

#include "core/stage.h"
#include "gpu/gl_context.h"
#include "util/status.h"

namespace shadowcull::gpu {

#define SHADOWCULL_GL_FUNCTIONS(X)                                                   \
    X(PFNGLGETSTRINGPROC, GetString)                                                 \
    X(PFNGLGETERRORPROC, GetError)                                                   \
    X(PFNGLGETINTEGERVPROC, GetIntegerv)                                             \
    X(PFNGLENABLEPROC, Enable)                                                       \
    X(PFNGLDISABLEPROC, Disable)                                                     \
    X(PFNGLVIEWPORTPROC, Viewport)                                                   \
    X(PFNGLSCISSORPROC, Scissor)                                                     \
    X(PFNGLCLEARPROC, Clear)                                                         \
    X(PFNGLCLEARCOLORPROC, ClearColor)                                               \
    X(PFNGLCLEARDEPTHPROC, ClearDepth)                                               \
    X(PFNGLCLEARSTENCILPROC, ClearStencil)                                           \
    X(PFNGLCLEARBUFFERFVPROC, ClearBufferfv)                                         \
    X(PFNGLCOLORMASKPROC, ColorMask)                                                 \
    X(PFNGLDEPTHMASKPROC, DepthMask)                                                 \
    X(PFNGLDEPTHFUNCPROC, DepthFunc)                                                 \
    X(PFNGLSTENCILFUNCPROC, StencilFunc)                                             \
    X(PFNGLSTENCILOPSEPARATEPROC, StencilOpSeparate)                                 \
    X(PFNGLSTENCILMASKPROC, StencilMask)                                             \
    X(PFNGLBLENDEQUATIONPROC, BlendEquation)                                         \
    X(PFNGLBLENDFUNCPROC, BlendFunc)                                                 \
    X(PFNGLFRONTFACEPROC, FrontFace)                                                 \
    X(PFNGLFINISHPROC, Finish)                                                       \
    X(PFNGLREADPIXELSPROC, ReadPixels)                                               \
    X(PFNGLREADBUFFERPROC, ReadBuffer)                                               \
    X(PFNGLPIXELSTOREIPROC, PixelStorei)                                             \
    X(PFNGLDRAWBUFFERPROC, DrawBuffer)                                               \
    X(PFNGLDRAWBUFFERSPROC, DrawBuffers)                                             \
    X(PFNGLGENBUFFERSPROC, GenBuffers)                                               \
    X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                                         \
    X(PFNGLBINDBUFFERPROC, BindBuffer)                                               \
    X(PFNGLBUFFERDATAPROC, BufferData)                                               \
    X(PFNGLBUFFERSUBDATAPROC, BufferSubData)                                         \
    X(PFNGLGETBUFFERSUBDATAPROC, GetBufferSubData)                                   \
    X(PFNGLBINDBUFFERBASEPROC, BindBufferBase)                                       \
    X(PFNGLMEMORYBARRIERPROC, MemoryBarrier)                                         \
    X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays)                                     \
    X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                               \
    X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                                     \
    X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray)                     \
    X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)                             \
    X(PFNGLVERTEXATTRIBIPOINTERPROC, VertexAttribIPointer)                           \
    X(PFNGLDRAWARRAYSPROC, DrawArrays)                                               \
    X(PFNGLDRAWARRAYSINSTANCEDBASEINSTANCEPROC, DrawArraysInstancedBaseInstance)     \
    X(PFNGLVERTEXATTRIBDIVISORPROC, VertexAttribDivisor)                             \
    X(PFNGLCREATESHADERPROC, CreateShader)                                           \
    X(PFNGLSHADERSOURCEPROC, ShaderSource)                                           \
    X(PFNGLCOMPILESHADERPROC, CompileShader)                                         \
    X(PFNGLGETSHADERIVPROC, GetShaderiv)                                             \
    X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                                   \
    X(PFNGLDELETESHADERPROC, DeleteShader)                                           \
    X(PFNGLCREATEPROGRAMPROC, CreateProgram)                                         \
    X(PFNGLATTACHSHADERPROC, AttachShader)                                           \
    X(PFNGLLINKPROGRAMPROC, LinkProgram)                                             \
    X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                           \
    X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                                 \
    X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                         \
    X(PFNGLUSEPROGRAMPROC, UseProgram)                                               \
    X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                               \
    X(PFNGLUNIFORM1IPROC, Uniform1i)                                                 \
    X(PFNGLUNIFORM1FPROC, Uniform1f)                                                 \
    X(PFNGLUNIFORM1UIPROC, Uniform1ui)                                               \
    X(PFNGLUNIFORM2FPROC, Uniform2f)                                                 \
    X(PFNGLUNIFORM2IPROC, Uniform2i)                                                 \
    X(PFNGLUNIFORM3FPROC, Uniform3f)                                                 \
    X(PFNGLUNIFORM4FPROC, Uniform4f)                                                 \
    X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv)                                   \
    X(PFNGLGENTEXTURESPROC, GenTextures)                                             \
    X(PFNGLDELETETEXTURESPROC, DeleteTextures)                                       \
    X(PFNGLBINDTEXTUREPROC, BindTexture)                                             \
    X(PFNGLACTIVETEXTUREPROC, ActiveTexture)                                         \
    X(PFNGLTEXSTORAGE2DPROC, TexStorage2D)                                           \
    X(PFNGLTEXPARAMETERIPROC, TexParameteri)                                         \
    X(PFNGLGENFRAMEBUFFERSPROC, GenFramebuffers)                                     \
    X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                               \
    X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                                     \
    X(PFNGLFRAMEBUFFERTEXTURE2DPROC, FramebufferTexture2D)                           \
    X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, FramebufferRenderbuffer)                     \
    X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, CheckFramebufferStatus)                       \
    X(PFNGLGENRENDERBUFFERSPROC, GenRenderbuffers)                                   \
    X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                             \
    X(PFNGLBINDRENDERBUFFERPROC, BindRenderbuffer)                                   \
    X(PFNGLRENDERBUFFERSTORAGEPROC, RenderbufferStorage)                             \
    X(PFNGLGENQUERIESPROC, GenQueries)                                               \
    X(PFNGLDELETEQUERIESPROC, DeleteQueries)                                         \
    X(PFNGLBEGINQUERYPROC, BeginQuery)                                               \
    X(PFNGLENDQUERYPROC, EndQuery)                                                   \
    X(PFNGLGETQUERYOBJECTUI64VPROC, GetQueryObjectui64v)                             \
    X(PFNGLGETQUERYIVPROC, GetQueryiv)                                               \
    X(PFNGLQUERYCOUNTERPROC, QueryCounter)

// The loaded entry points, named without the "gl" prefix: gl.DrawArrays(...).
struct GlApi {
#define SHADOWCULL_GL_MEMBER(type, name) type name = nullptr;
    SHADOWCULL_GL_FUNCTIONS(SHADOWCULL_GL_MEMBER)
#undef SHADOWCULL_GL_MEMBER

    // Loads every entry point; an error names the first one missing.
    Status load(const GlContext& context);
    // GL_NO_ERROR, or an Internal error naming `what` and the GL error code.
    Status check(const char* what) const;
    // Compiles and links a program from vertex, optional geometry and fragment source.
    Expected<GLuint> program(const char* vertex, const char* geometry, const char* fragment) const;
    GLint uniform(GLuint prog, const char* name) const { return GetUniformLocation(prog, name); }
};

// An offscreen render target: colour textures (GL_R32F, GL_RG32F, GL_RGBA8 ...) and an
// optional depth+stencil renderbuffer (GL_DEPTH32F_STENCIL8), all `size` x `size`.
struct RenderTarget {
    GLuint fbo = 0;
    std::vector<GLuint> colour;  // textures, attachments 0..n-1
    GLuint depthStencil = 0;     // renderbuffer or 0
    int width = 0, height = 0;
};

Expected<RenderTarget> makeRenderTarget(const GlApi& gl, int width, int height, const std::vector<GLenum>& colourFormats,
                                        bool depthStencil);
void destroyRenderTarget(const GlApi& gl, RenderTarget& target);

// OpenGL objects made through a GlApi (Gen*/Create*) and not deleted since (Delete*), over
// every context of the process: what a pass leaves behind. Objects freed by destroying
// their context are not subtracted, so compare counts taken while the same contexts live
// (e.g. after K and after 2K chunks of one bake: a pass that forgets to delete what it
// made per chunk shows up as growth). Names 0 are not counted.
struct GlObjectCounts {
    int64_t buffers = 0, vertexArrays = 0, textures = 0, framebuffers = 0, renderbuffers = 0, queries = 0,
            shaders = 0, programs = 0;
    int64_t total() const {
        return buffers + vertexArrays + textures + framebuffers + renderbuffers + queries + shaders + programs;
    }
};
GlObjectCounts liveGlObjects();

// Reads a colour attachment of a float target (one float per pixel, channel `channel`
// of `channels`), rows bottom to top.
std::vector<float> readFloatPixels(const GlApi& gl, const RenderTarget& target, int attachment, int channels, int channel);

}  // namespace shadowcull::gpu

namespace shadowcull::gpu {

// A context with its entry points loaded (what every pass needs).
struct GlSession {
    std::unique_ptr<GlContext> context;
    GlApi gl;
    // Makes the context current on this thread; Internal error if it cannot.
    Status makeCurrent() const;
};

// createOffscreenContext (a small default framebuffer: the passes use FBOs) + GlApi::load.
Expected<std::unique_ptr<GlSession>> openGlSession();

// The GPU's own time for the GL work between construction and addTo(), where the driver
// has timer queries (GL_QUERY_COUNTER_BITS of GL_TIMESTAMP > 0): two GL_TIMESTAMP
// queries (glQueryCounter), the difference of when the GPU reached each. Not one
// GL_TIME_ELAPSED query: llvmpipe (Mesa 22.3) sums per-thread intervals of which some never
// started, and returned ~3000 s for a 2 s stage. A result longer than the wall time
// between the two calls is impossible (the work ends in a read-back before addTo returns)
// and is dropped (stats.gpuTimed stays false). addTo waits for the result.
class GpuTimer {
public:
    explicit GpuTimer(const GlApi& gl);
    ~GpuTimer();
    GpuTimer(const GpuTimer&) = delete;
    GpuTimer& operator=(const GpuTimer&) = delete;
    // Adds the GPU seconds to stats.gpuSeconds and sets stats.gpuTimed (nothing without a
    // timer, or with an impossible result). Call once.
    void addTo(StageStats& stats);

private:
    const GlApi& gl_;
    GLuint queries_[2] = {0, 0};
    std::chrono::steady_clock::time_point wallStart_;
};

}  // namespace shadowcull::gpu

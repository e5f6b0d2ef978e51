#include "gpu/render.h"

#include <cmath>
#include <cstdio>
#include <vector>

#include "core/png_write.h"
#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/window_draw.h"

namespace shadowcull::gpu {

namespace {

const char* kRenderVs = R"(#version 430 core
layout(location = 0) in vec3 aPos;
uniform mat4 uClip;
out vec3 vPos;
void main() { vPos = aPos; gl_Position = uClip * vec4(aPos, 1.0); }
)";

const char* kRenderFs = R"(#version 430 core
in vec3 vPos;
uniform vec3 uColour;
uniform bool uPoint;
uniform vec3 uLightPos;
uniform vec3 uLightDir;
layout(location = 0) out vec4 oColour;
void main() {
    vec3 n = normalize(cross(dFdx(vPos), dFdy(vPos)));
    vec3 l = uPoint ? normalize(vPos - uLightPos) : uLightDir;
    float shade = 0.35 + 0.65 * abs(dot(n, l));
    oColour = vec4(uColour * shade, 1.0);
}
)";

// libpng's own stderr lines become the tool's messages there (core/png_write.h).
Status writePng(const std::string& path, int width, int height, const std::vector<unsigned char>& rgbTopDown) {
    return writeRgbPng(path, width, height, rgbTopDown);
}

}  // namespace

Status renderLightView(const BakeWindow& w, const ChunkVerdicts& cv, int light, int resolution,
                       const std::string& pngPath) {
    if (light < 0 || light >= int(w.lsLights.size()))
        return makeError(ErrorKind::BadInput, "", 0,
                         "no light " + std::to_string(light + 1) + " (the space has " +
                             std::to_string(w.lsLights.size()) + ")");
    if (resolution < 1 || resolution > 8192)
        return makeError(ErrorKind::BadInput, "", 0, "render resolution must be within 1..8192");
    const Light& L = w.lsLights[size_t(light)];
    const std::vector<LightView> views = lightViews(w, L, resolution);
    const int cols = views.size() > 1 ? 3 : 1, rows = views.size() > 1 ? 2 : 1;
    const int width = cols * resolution, height = rows * resolution;

    Expected<std::unique_ptr<GlSession>> session = openGlSession();
    if (!session) return session.error();
    const GlApi& gl = (*session)->gl;
    Expected<GLuint> prog = gl.program(kRenderVs, nullptr, kRenderFs);
    if (!prog) return prog.error();
    Expected<RenderTarget> target = makeRenderTarget(gl, width, height, {GL_RGBA8}, true);
    if (!target) return target.error();
    WindowTriangles tris(w);
    WindowBuffers buffers;
    if (Status s = buffers.upload(gl, w, tris); !s) return s;

    // Colour of each (window object, group).
    std::vector<int> verdictObject(w.objects.size(), -1);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].windowObject >= 0) verdictObject[size_t(cv.objects[oi].windowObject)] = int(oi);
    auto colourOf = [&](const GroupRange& r) -> glm::vec3 {
        const int oi = verdictObject[r.object];
        if (!w.objects[r.object].centre || oi < 0) return {0.55f, 0.55f, 0.55f};
        if (int(r.group) >= cv.objects[size_t(oi)].groupCount || light >= cv.lightCount) return {0.95f, 0.85f, 0.1f};
        switch (cv.at(size_t(oi), int(r.group), light).verdict) {
            case Verdict::Culled: return {0.85f, 0.12f, 0.1f};
            case Verdict::Kept: return {0.2f, 0.8f, 0.25f};
            case Verdict::Undecided: break;
        }
        return {0.95f, 0.85f, 0.1f};
    };

    gl.BindFramebuffer(GL_FRAMEBUFFER, target->fbo);
    gl.Viewport(0, 0, width, height);
    gl.ClearColor(0, 0, 0, 1);
    gl.ClearDepth(1.0);
    gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    gl.Disable(GL_CULL_FACE);
    gl.UseProgram(*prog);
    gl.Uniform1i(gl.uniform(*prog, "uPoint"), L.type != LightType::Directional);
    gl.Uniform3f(gl.uniform(*prog, "uLightPos"), float(L.position.x), float(L.position.y), float(L.position.z));
    gl.Uniform3f(gl.uniform(*prog, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
    const GLint uClip = gl.uniform(*prog, "uClip"), uColour = gl.uniform(*prog, "uColour");
    buffers.bind(gl);
    const double nearZ = std::max(1e-3, 1e-4 * L.range), farZ = L.range * 1.001 + nearZ;
    for (size_t v = 0; v < views.size(); ++v) {
        // Tiles: +x -x +y on the top row, -y +z -z below.
        const int col = int(v) % cols, row = rows - 1 - int(v) / cols;
        gl.Viewport(col * resolution, row * resolution, resolution, resolution);
        const std::array<float, 16> clip = views[v].clipMatrix(nearZ, farZ, 1e-3 * (views[v].w1 - views[v].w0) + 1e-3);
        gl.UniformMatrix4fv(uClip, 1, GL_FALSE, clip.data());
        for (const GroupRange& r : buffers.ranges()) {
            const glm::vec3 c = colourOf(r);
            gl.Uniform3f(uColour, c.x, c.y, c.z);
            gl.DrawArrays(GL_TRIANGLES, r.first, r.count);
        }
    }
    gl.BindVertexArray(0);
    std::vector<unsigned char> rgba(size_t(width) * size_t(height) * 4);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, target->fbo);
    gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    if (Status s = gl.check("rendering the light view"); !s) return s;
    buffers.destroy(gl);
    destroyRenderTarget(gl, *target);
    gl.DeleteProgram(*prog);

    std::vector<unsigned char> rgb(size_t(width) * size_t(height) * 3);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c)
                rgb[(size_t(y) * size_t(width) + size_t(x)) * 3 + size_t(c)] =
                    rgba[(size_t(height - 1 - y) * size_t(width) + size_t(x)) * 4 + size_t(c)];
    return writePng(pngPath, width, height, rgb);
}

}  // namespace shadowcull::gpu

#include "gpu/window_draw.h"

namespace shadowcull::gpu {

const char* const kWindowPositionVs = R"(#version 430 core
layout(location = 0) in vec3 aPos;
uniform mat4 uClip;
out vec3 vPos;
void main() { vPos = aPos; gl_Position = uClip * vec4(aPos, 1.0); }
)";

std::vector<Aabb> groupBounds(const BakeWindow& w, const WindowTriangles& tris, size_t object) {
    const WindowObject& o = w.objects[object];
    std::vector<Aabb> boxes(o.mesh->groups.size());
    for (uint32_t t : tris.object(object).triangles) {
        const size_t g = size_t(o.mesh->triangleGroup[t]);
        if (g < boxes.size())
            for (uint32_t v : o.mesh->triangles[t]) boxes[g].extend(tris.object(object).positions[v]);
    }
    return boxes;
}

Status WindowBuffers::upload(const GlApi& gl, const BakeWindow& w, const WindowTriangles& tris) {
    std::vector<float> data;
    ranges_.clear();
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        const WindowTriangles::Object& to = tris.object(k);
        std::vector<std::vector<uint32_t>> byGroup(o.mesh->groups.size());
        for (uint32_t t : to.triangles) byGroup[o.mesh->triangleGroup[t]].push_back(t);
        for (size_t g = 0; g < byGroup.size(); ++g) {
            if (byGroup[g].empty()) continue;
            GroupRange r;
            r.object = uint32_t(k);
            r.group = uint32_t(g);
            r.first = GLint(data.size() / 3);
            for (uint32_t t : byGroup[g])
                for (uint32_t v : o.mesh->triangles[t]) {
                    const glm::dvec3& p = to.positions[v];
                    data.push_back(float(p.x));
                    data.push_back(float(p.y));
                    data.push_back(float(p.z));
                }
            r.count = GLsizei(data.size() / 3) - r.first;
            ranges_.push_back(r);
        }
    }
    gl.GenVertexArrays(1, &vao_);
    gl.BindVertexArray(vao_);
    gl.GenBuffers(1, &vbo_);
    gl.BindBuffer(GL_ARRAY_BUFFER, vbo_);
    gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(data.size() * sizeof(float)), data.data(), GL_STATIC_DRAW);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    gl.BindVertexArray(0);
    return gl.check("uploading the window's triangles");
}

void WindowBuffers::destroy(const GlApi& gl) {
    if (vbo_) gl.DeleteBuffers(1, &vbo_);
    if (vao_) gl.DeleteVertexArrays(1, &vao_);
    vbo_ = vao_ = 0;
    ranges_.clear();
}

namespace {

const char* kHeightVs = R"(#version 430 core
layout(location = 0) in vec3 aPos;
uniform mat4 uClip;
out float vY;
void main() { vY = aPos.y; gl_Position = uClip * vec4(aPos, 1.0); }
)";

const char* kHeightFs = R"(#version 430 core
in float vY;
layout(location = 0) out vec4 oHeight;
void main() { oHeight = vec4(vY, 0.0, 0.0, 1.0); }
)";

}  // namespace

Expected<TerrainHeightMap> renderTerrainHeights(const GlApi& gl, const BakeWindow& w, const WindowBuffers& buffers,
                                                int resolution) {
    TerrainHeightMap map;
    map.x0 = w.lsBounds.min.x, map.x1 = w.lsBounds.max.x;
    map.z0 = w.lsBounds.min.z, map.z1 = w.lsBounds.max.z;
    if (!(map.x1 > map.x0)) map.x1 = map.x0 + 1;
    if (!(map.z1 > map.z0)) map.z1 = map.z0 + 1;
    // A view straight down: U = +x, V = -z (lightBasis), so v runs over [-z1, -z0].
    LightView top;
    top.W = glm::dvec3(0, -1, 0);
    lightBasis(top.W, top.U, top.V);
    top.u0 = map.x0, top.u1 = map.x1, top.v0 = -map.z1, top.v1 = -map.z0;
    top.w0 = -w.lsBounds.max.y, top.w1 = -w.lsBounds.min.y;
    top.width = top.height = resolution;
    Expected<GLuint> prog = gl.program(kHeightVs, nullptr, kHeightFs);
    if (!prog) return prog.error();
    Expected<RenderTarget> target = makeRenderTarget(gl, resolution, resolution, {GL_R32F}, false);
    if (!target) {
        gl.DeleteProgram(*prog);
        return target.error();
    }
    gl.BindFramebuffer(GL_FRAMEBUFFER, target->fbo);
    gl.Viewport(0, 0, resolution, resolution);
    const float far[4] = {1e30f, 0, 0, 0};
    gl.ClearBufferfv(GL_COLOR, 0, far);
    gl.Disable(GL_DEPTH_TEST);
    gl.Disable(GL_STENCIL_TEST);
    gl.Disable(GL_CULL_FACE);
    gl.Enable(GL_BLEND);
    gl.BlendEquation(GL_MIN);  // the lowest terrain counts (docs/format.md, terrain rule)
    gl.UseProgram(*prog);
    const std::array<float, 16> clip = top.clipMatrix(0, 0, 1.0);
    gl.UniformMatrix4fv(gl.uniform(*prog, "uClip"), 1, GL_FALSE, clip.data());
    buffers.bind(gl);
    for (const GroupRange& r : buffers.ranges())
        if (w.objects[r.object].kind == ChunkObject::Kind::Terrain) gl.DrawArrays(GL_TRIANGLES, r.first, r.count);
    gl.BindVertexArray(0);
    gl.Disable(GL_BLEND);
    gl.BlendEquation(GL_FUNC_ADD);
    gl.UseProgram(0);
    gl.DeleteProgram(*prog);
    // Keep the texture, drop the framebuffer.
    map.texture = target->colour[0];
    target->colour.clear();
    destroyRenderTarget(gl, *target);
    if (Status s = gl.check("rendering terrain heights"); !s) {
        gl.DeleteTextures(1, &map.texture);
        return s.error();
    }
    return map;
}

}  // namespace shadowcull::gpu

// The original method (see baseline.h): plain rasterisation at pixel centres, a stencil
// count of receiving fragments per pixel and occlusion queries. Not conservative.
//
// Occlusion-query shadow caster culling: D. Bittner, O. Mattausch, A. Silvennoinen,
// M. Wimmer, "Shadow Caster Culling for Efficient Shadow Mapping", I3D 2011.

#include "gpu/baseline.h"

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <tuple>

#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/window_draw.h"

namespace shadowcull::gpu {

namespace {

constexpr double kPi = 3.14159265358979323846;

const char* kCountVs = R"(#version 430 core
layout(location = 0) in vec3 aPos;
uniform mat4 uClip;
out vec3 vPos;
// The query pass must reproduce the depth pass's depths exactly (depth test LEQUAL).
invariant gl_Position;
void main() { vPos = aPos; gl_Position = uClip * vec4(aPos, 1.0); }
)";

// Discards what may not count: beyond the range, outside the cone, under the terrain.
const char* kCountFs = R"(#version 430 core
in vec3 vPos;
uniform int uLightType;  // 0 directional, 1 point, 2 spot
uniform vec3 uLightPos;
uniform vec3 uLightDir;
uniform float uRange;
uniform float uCosCone;
uniform bool uTerrainRule;
uniform sampler2D uHeights;
uniform vec4 uHeightRect;  // x0, z0, x1, z1 (window-local)
uniform float uTolerance;
layout(location = 0) out vec4 oColour;
void main() {
    if (uLightType != 0) {
        vec3 d = vPos - uLightPos;
        float dist = length(d);
        if (dist > uRange) discard;
        if (uLightType == 2 && dot(d, uLightDir) < uCosCone * dist) discard;
    }
    if (uTerrainRule) {
        vec2 st = vec2((vPos.x - uHeightRect.x) / (uHeightRect.z - uHeightRect.x),
                       (uHeightRect.w - vPos.z) / (uHeightRect.w - uHeightRect.y));
        float h = texture(uHeights, st).r;
        if (h < 1e29 && vPos.y < h - uTolerance) discard;
    }
    oColour = vec4(1.0);
}
)";

std::string formatCount(uint64_t n) { return std::to_string(n); }

}  // namespace

struct GpuBaselineMethod::Gl {
    std::unique_ptr<GlSession> session;
    GLuint program = 0;
    RenderTarget target;
};

GpuBaselineMethod::GpuBaselineMethod(GpuBaselineOptions options) : options_(options) {}
GpuBaselineMethod::~GpuBaselineMethod() = default;  // destroying the context frees its objects

std::string GpuBaselineMethod::glDescription() const { return gl_ ? gl_->session->context->report() : std::string(); }

Status GpuBaselineMethod::run(const BakeWindow& w, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    counts_.clear();
    const std::vector<bool> lights = lightsWithUndecided(cv);
    bool any = false;
    for (bool b : lights) any |= b;
    if (!any) return Status::ok();
    const int res = options_.resolution;
    if (res < 1) return makeError(ErrorKind::BadInput, "", 0, "GPU resolution must be at least 1");

    if (!gl_) {
        auto g = std::make_unique<Gl>();
        Expected<std::unique_ptr<GlSession>> s = openGlSession();
        if (!s) return s.error();
        g->session = std::move(*s);
        const GlApi& gl = g->session->gl;
        Expected<GLuint> p = gl.program(kCountVs, nullptr, kCountFs);
        if (!p) return p.error();
        g->program = *p;
        Expected<RenderTarget> t = makeRenderTarget(gl, res, res, {GL_R8}, true);
        if (!t) return t.error();
        g->target = *t;
        gl_ = std::move(g);
    }
    if (Status s = gl_->session->makeCurrent(); !s) return s;
    const GlApi& gl = gl_->session->gl;
    GpuTimer gpuTime(gl);

    // Which centre group ranges need queries: verdict object of each window object.
    std::vector<int> verdictObject(w.objects.size(), -1);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].windowObject >= 0) verdictObject[size_t(cv.objects[oi].windowObject)] = int(oi);
    std::map<std::tuple<size_t, int, int>, size_t> countIndex;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        for (int g = 0; g < cv.objects[oi].groupCount; ++g)
            for (int l = 0; l < cv.lightCount; ++l)
                if (cv.at(oi, g, l).verdict == Verdict::Undecided) {
                    countIndex[{oi, g, l}] = counts_.size();
                    counts_.push_back({oi, g, l, 0});
                }

    WindowTriangles tris(w);
    WindowBuffers buffers;
    if (Status s = buffers.upload(gl, w, tris); !s) {
        buffers.destroy(gl);
        return s;
    }
    TerrainHeightMap heights;
    if (w.hasTerrain) {
        Expected<TerrainHeightMap> h = renderTerrainHeights(gl, w, buffers, std::max(res, 64));
        if (!h) {
            buffers.destroy(gl);
            return h.error();
        }
        heights = *h;
    }

    const GLuint prog = gl_->program;
    gl.UseProgram(prog);
    const GLint uClip = gl.uniform(prog, "uClip"), uTerrainRule = gl.uniform(prog, "uTerrainRule");
    gl.Uniform1i(gl.uniform(prog, "uHeights"), 0);
    gl.Uniform4f(gl.uniform(prog, "uHeightRect"), float(heights.x0), float(heights.z0), float(heights.x1),
                 float(heights.z1));
    gl.Uniform1f(gl.uniform(prog, "uTolerance"), float(w.terrainTolerance));
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, heights.texture);
    gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->target.fbo);
    gl.Viewport(0, 0, res, res);
    gl.Disable(GL_CULL_FACE);
    gl.Disable(GL_BLEND);
    gl.Enable(GL_DEPTH_TEST);
    gl.Enable(GL_STENCIL_TEST);
    gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    buffers.bind(gl);

    struct Pending {
        GLuint query;
        size_t count;
    };
    std::vector<Pending> pending;
    auto readPending = [&] {
        for (const Pending& p : pending) {
            GLuint64 n = 0;
            gl.GetQueryObjectui64v(p.query, GL_QUERY_RESULT, &n);
            counts_[p.count].samples += n;
        }
        std::vector<GLuint> ids;
        ids.reserve(pending.size());
        for (const Pending& p : pending) ids.push_back(p.query);
        if (!ids.empty()) gl.DeleteQueries(GLsizei(ids.size()), ids.data());
        pending.clear();
    };
    const bool alphaPasses = w.hasAlphaTested;
    for (int l = 0; l < cv.lightCount; ++l) {
        if (!lights[size_t(l)]) continue;
        const Light& L = w.lsLights[size_t(l)];
        gl.Uniform1i(gl.uniform(prog, "uLightType"), L.type == LightType::Directional ? 0 : L.type == LightType::Point ? 1 : 2);
        gl.Uniform3f(gl.uniform(prog, "uLightPos"), float(L.position.x), float(L.position.y), float(L.position.z));
        gl.Uniform3f(gl.uniform(prog, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
        gl.Uniform1f(gl.uniform(prog, "uRange"), float(L.range));
        gl.Uniform1f(gl.uniform(prog, "uCosCone"), float(std::cos(L.coneHalfAngleDeg * kPi / 180.0)));
        const double nearZ = std::max(1e-3, 1e-4 * L.range), farZ = L.range * 1.001 + nearZ;
        for (const LightView& view : lightViews(w, L, res)) {
            const std::array<float, 16> clip = view.clipMatrix(nearZ, farZ, 1e-3 * (view.w1 - view.w0) + 1e-3);
            gl.UniformMatrix4fv(uClip, 1, GL_FALSE, clip.data());
            for (int pass = 0; pass < (alphaPasses ? 2 : 1); ++pass) {
                const bool withoutAlpha = pass == 1;
                // Depth + stencil: nearest depth, count receiving fragments per pixel.
                gl.DepthMask(GL_TRUE);
                gl.StencilMask(0xff);
                gl.ClearDepth(1.0);
                gl.ClearStencil(0);
                gl.Clear(GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
                gl.DepthFunc(GL_LESS);
                gl.StencilFunc(GL_ALWAYS, 0, 0xff);
                for (const GroupRange& r : buffers.ranges()) {
                    const WindowObject& o = w.objects[r.object];
                    const PrimitiveGroup& pg = o.mesh->groups[r.group];
                    if (withoutAlpha && pg.alphaTested) continue;
                    gl.FrontFace(o.flipsWinding ? GL_CW : GL_CCW);
                    gl.StencilOpSeparate(GL_FRONT, GL_INCR, GL_INCR, GL_INCR);
                    if (pg.twoSided()) gl.StencilOpSeparate(GL_BACK, GL_INCR, GL_INCR, GL_INCR);
                    else gl.StencilOpSeparate(GL_BACK, GL_KEEP, GL_KEEP, GL_KEEP);
                    gl.Uniform1i(uTerrainRule, w.hasTerrain && o.kind != ChunkObject::Kind::Terrain);
                    gl.DrawArrays(GL_TRIANGLES, r.first, r.count);
                }
                // Queries over the centre chunk's undecided groups: lit (LEQUAL) with
                // something behind (stencil > 1). Issue all, read later.
                gl.DepthMask(GL_FALSE);
                gl.DepthFunc(GL_LEQUAL);
                gl.StencilMask(0);
                gl.StencilOpSeparate(GL_FRONT_AND_BACK, GL_KEEP, GL_KEEP, GL_KEEP);
                for (const GroupRange& r : buffers.ranges()) {
                    const int oi = verdictObject[r.object];
                    if (oi < 0) continue;
                    auto it = countIndex.find({size_t(oi), int(r.group), l});
                    if (it == countIndex.end()) continue;
                    const WindowObject& o = w.objects[r.object];
                    const bool alpha = o.mesh->groups[r.group].alphaTested;
                    // Without the alpha-tested groups in the count, an alpha-tested caster
                    // is not counted at its own pixel: one fragment behind it suffices.
                    gl.StencilFunc(withoutAlpha && alpha ? GL_LEQUAL : GL_LESS, 1, 0xff);
                    gl.Uniform1i(uTerrainRule, w.hasTerrain && o.kind != ChunkObject::Kind::Terrain);
                    GLuint q = 0;
                    gl.GenQueries(1, &q);
                    gl.BeginQuery(GL_SAMPLES_PASSED, q);
                    gl.DrawArrays(GL_TRIANGLES, r.first, r.count);
                    gl.EndQuery(GL_SAMPLES_PASSED);
                    pending.push_back({q, it->second});
                }
                // Read this pass's queries (issued all at once, read after) before the next
                // pass: llvmpipe corrupted its heap with thousands of queries outstanding
                // across passes (free(): corrupted unsorted chunks in DeleteQueries).
                readPending();
                stats.gpuPasses += 2;
            }
        }
    }
    gl.BindVertexArray(0);
    gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    gl.DepthMask(GL_TRUE);
    gl.StencilMask(0xff);
    gl.Disable(GL_DEPTH_TEST);
    gl.Disable(GL_STENCIL_TEST);
    gl.UseProgram(0);
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    if (heights.texture) gl.DeleteTextures(1, &heights.texture);
    buffers.destroy(gl);
    gpuTime.addTo(stats);
    if (Status s = gl.check("the baseline passes"); !s) return s;

    // A bake keeps every decision to its end, so the reasons are shared: one per sample
    // count (most bits of a world are "0 samples passed"). A reason of its own per bit cost
    // ~240 bytes each, ~2.3 MB per chunk of the benchmark's world M, for the whole bake.
    const std::string at = " at " + std::to_string(res) + " px";
    std::map<uint64_t, std::shared_ptr<const Evidence>> reasons;
    for (const BaselineCount& c : counts_) {
        Decision& d = cv.at(c.object, c.group, c.light);
        ++stats.bitsExamined;
        std::shared_ptr<const Evidence>& reason = reasons[c.samples];
        if (!reason) reason = std::make_shared<const Evidence>(Evidence{formatCount(c.samples) + " samples passed" + at, {}, {}});
        decide(d, c.samples > 0 ? Verdict::Kept : Verdict::Culled, kStageName, reason);
        ++(c.samples > 0 ? stats.provedKept : stats.provedCulled);
    }
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

}  // namespace shadowcull::gpu

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
#include <string>
#include <tuple>
#include <vector>

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

// The bits to count: every undecided (group, light) of the centre chunk, and where a
// window object's verdicts are.
struct CountedBits {
    std::vector<int> verdictObject;  // per window object: index into ChunkVerdicts::objects, or -1
    std::map<std::tuple<size_t, int, int>, size_t> countIndex;  // (object, group, light) -> index into the counts
};

CountedBits countedBits(const BakeWindow& w, const ChunkVerdicts& cv, std::vector<BaselineCount>& counts) {
    CountedBits bits;
    bits.verdictObject.assign(w.objects.size(), -1);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].windowObject >= 0) bits.verdictObject[size_t(cv.objects[oi].windowObject)] = int(oi);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        for (int g = 0; g < cv.objects[oi].groupCount; ++g)
            for (int l = 0; l < cv.lightCount; ++l)
                if (cv.at(oi, g, l).verdict == Verdict::Undecided) {
                    bits.countIndex[{oi, g, l}] = counts.size();
                    counts.push_back({oi, g, l, 0});
                }
    return bits;
}

// The window's triangles on the GPU and, with terrain, its height map (heights.texture
// stays 0 without). On an error nothing is left allocated.
Status uploadWindow(const GlApi& gl, const BakeWindow& w, const WindowTriangles& tris, int res, WindowBuffers& buffers,
                    TerrainHeightMap& heights) {
    if (Status s = buffers.upload(gl, w, tris); !s) {
        buffers.destroy(gl);
        return s;
    }
    if (w.hasTerrain) {
        Expected<TerrainHeightMap> h = renderTerrainHeights(gl, w, buffers, std::max(res, 64));
        if (!h) {
            buffers.destroy(gl);
            return h.error();
        }
        heights = *h;
    }
    return Status::ok();
}

// The depth + stencil and query passes over one window, light by light (baseline.h).
class BaselinePasses {
public:
    BaselinePasses(const GlApi& gl, GLuint program, const BakeWindow& w, const WindowBuffers& buffers,
                   const CountedBits& bits, std::vector<BaselineCount>& counts, StageStats& stats)
        : gl_(gl), prog_(program), w_(w), buffers_(buffers), bits_(bits), counts_(counts), stats_(stats) {}

    // The program's window-wide uniforms and the state every pass shares.
    void setUp(const TerrainHeightMap& heights, GLuint fbo, int res) {
        gl_.UseProgram(prog_);
        uClip_ = gl_.uniform(prog_, "uClip"), uTerrainRule_ = gl_.uniform(prog_, "uTerrainRule");
        gl_.Uniform1i(gl_.uniform(prog_, "uHeights"), 0);
        gl_.Uniform4f(gl_.uniform(prog_, "uHeightRect"), float(heights.x0), float(heights.z0), float(heights.x1),
                      float(heights.z1));
        gl_.Uniform1f(gl_.uniform(prog_, "uTolerance"), float(w_.terrainTolerance));
        gl_.ActiveTexture(GL_TEXTURE0);
        gl_.BindTexture(GL_TEXTURE_2D, heights.texture);
        gl_.BindFramebuffer(GL_FRAMEBUFFER, fbo);
        gl_.Viewport(0, 0, res, res);
        gl_.Disable(GL_CULL_FACE);
        gl_.Disable(GL_BLEND);
        gl_.Enable(GL_DEPTH_TEST);
        gl_.Enable(GL_STENCIL_TEST);
        gl_.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        buffers_.bind(gl_);
    }

    // Every view of light l, once or (with alpha-tested groups in the window) twice.
    void drawLight(int l, int res) {
        const Light& L = w_.lsLights[size_t(l)];
        gl_.Uniform1i(gl_.uniform(prog_, "uLightType"), L.type == LightType::Directional ? 0 : L.type == LightType::Point ? 1 : 2);
        gl_.Uniform3f(gl_.uniform(prog_, "uLightPos"), float(L.position.x), float(L.position.y), float(L.position.z));
        gl_.Uniform3f(gl_.uniform(prog_, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
        gl_.Uniform1f(gl_.uniform(prog_, "uRange"), float(L.range));
        gl_.Uniform1f(gl_.uniform(prog_, "uCosCone"), float(std::cos(L.coneHalfAngleDeg * kPi / 180.0)));
        const double nearZ = std::max(1e-3, 1e-4 * L.range), farZ = L.range * 1.001 + nearZ;
        const bool alphaPasses = w_.hasAlphaTested;
        for (const LightView& view : lightViews(w_, L, res)) {
            const std::array<float, 16> clip = view.clipMatrix(nearZ, farZ, 1e-3 * (view.w1 - view.w0) + 1e-3);
            gl_.UniformMatrix4fv(uClip_, 1, GL_FALSE, clip.data());
            for (int pass = 0; pass < (alphaPasses ? 2 : 1); ++pass) {
                const bool withoutAlpha = pass == 1;
                countReceivers(withoutAlpha);
                queryGroups(l, withoutAlpha);
                // Read this pass's queries (issued all at once, read after) before the next
                // pass: llvmpipe corrupted its heap with thousands of queries outstanding
                // across passes (free(): corrupted unsorted chunks in DeleteQueries).
                readPending();
                stats_.gpuPasses += 2;
            }
        }
    }

    void tearDown() {
        gl_.BindVertexArray(0);
        gl_.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        gl_.DepthMask(GL_TRUE);
        gl_.StencilMask(0xff);
        gl_.Disable(GL_DEPTH_TEST);
        gl_.Disable(GL_STENCIL_TEST);
        gl_.UseProgram(0);
        gl_.BindFramebuffer(GL_FRAMEBUFFER, 0);
    }

private:
    // Depth + stencil: nearest depth, count receiving fragments per pixel.
    void countReceivers(bool withoutAlpha) {
        gl_.DepthMask(GL_TRUE);
        gl_.StencilMask(0xff);
        gl_.ClearDepth(1.0);
        gl_.ClearStencil(0);
        gl_.Clear(GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
        gl_.DepthFunc(GL_LESS);
        gl_.StencilFunc(GL_ALWAYS, 0, 0xff);
        for (const GroupRange& r : buffers_.ranges()) {
            const WindowObject& o = w_.objects[r.object];
            const PrimitiveGroup& pg = o.mesh->groups[r.group];
            if (withoutAlpha && pg.alphaTested) continue;
            gl_.FrontFace(o.flipsWinding ? GL_CW : GL_CCW);
            gl_.StencilOpSeparate(GL_FRONT, GL_INCR, GL_INCR, GL_INCR);
            if (pg.twoSided()) gl_.StencilOpSeparate(GL_BACK, GL_INCR, GL_INCR, GL_INCR);
            else gl_.StencilOpSeparate(GL_BACK, GL_KEEP, GL_KEEP, GL_KEEP);
            gl_.Uniform1i(uTerrainRule_, w_.hasTerrain && o.kind != ChunkObject::Kind::Terrain);
            gl_.DrawArrays(GL_TRIANGLES, r.first, r.count);
        }
    }

    // Queries over the centre chunk's undecided groups: lit (LEQUAL) with something
    // behind (stencil > 1). Issued all, read later (readPending).
    void queryGroups(int l, bool withoutAlpha) {
        gl_.DepthMask(GL_FALSE);
        gl_.DepthFunc(GL_LEQUAL);
        gl_.StencilMask(0);
        gl_.StencilOpSeparate(GL_FRONT_AND_BACK, GL_KEEP, GL_KEEP, GL_KEEP);
        for (const GroupRange& r : buffers_.ranges()) {
            const int oi = bits_.verdictObject[r.object];
            if (oi < 0) continue;
            auto it = bits_.countIndex.find({size_t(oi), int(r.group), l});
            if (it == bits_.countIndex.end()) continue;
            const WindowObject& o = w_.objects[r.object];
            const bool alpha = o.mesh->groups[r.group].alphaTested;
            // Without the alpha-tested groups in the count, an alpha-tested caster
            // is not counted at its own pixel: one fragment behind it suffices.
            gl_.StencilFunc(withoutAlpha && alpha ? GL_LEQUAL : GL_LESS, 1, 0xff);
            gl_.Uniform1i(uTerrainRule_, w_.hasTerrain && o.kind != ChunkObject::Kind::Terrain);
            GLuint q = 0;
            gl_.GenQueries(1, &q);
            gl_.BeginQuery(GL_SAMPLES_PASSED, q);
            gl_.DrawArrays(GL_TRIANGLES, r.first, r.count);
            gl_.EndQuery(GL_SAMPLES_PASSED);
            pending_.push_back({q, it->second});
        }
    }

    void readPending() {
        for (const Pending& p : pending_) {
            GLuint64 n = 0;
            gl_.GetQueryObjectui64v(p.query, GL_QUERY_RESULT, &n);
            counts_[p.count].samples += n;
        }
        std::vector<GLuint> ids;
        ids.reserve(pending_.size());
        for (const Pending& p : pending_) ids.push_back(p.query);
        if (!ids.empty()) gl_.DeleteQueries(GLsizei(ids.size()), ids.data());
        pending_.clear();
    }

    struct Pending {
        GLuint query;
        size_t count;  // index into the counts
    };
    const GlApi& gl_;
    const GLuint prog_;
    const BakeWindow& w_;
    const WindowBuffers& buffers_;
    const CountedBits& bits_;
    std::vector<BaselineCount>& counts_;
    StageStats& stats_;
    GLint uClip_ = -1, uTerrainRule_ = -1;
    std::vector<Pending> pending_;
};

// A bake keeps every decision to its end, so the reasons are shared: one per sample
// count (most bits of a world are "0 samples passed"), not a few hundred bytes per bit.
void decideBits(const std::vector<BaselineCount>& counts, int res, ChunkVerdicts& cv, StageStats& stats) {
    const std::string at = " at " + std::to_string(res) + " px";
    std::map<uint64_t, std::shared_ptr<const Evidence>> reasons;
    for (const BaselineCount& c : counts) {
        Decision& d = cv.at(c.object, c.group, c.light);
        ++stats.bitsExamined;
        std::shared_ptr<const Evidence>& reason = reasons[c.samples];
        if (!reason) reason = std::make_shared<const Evidence>(Evidence{formatCount(c.samples) + " samples passed" + at, {}, {}});
        decide(d, c.samples > 0 ? Verdict::Kept : Verdict::Culled, GpuBaselineMethod::kStageName, reason);
        ++(c.samples > 0 ? stats.provedKept : stats.provedCulled);
    }
}

}  // namespace

struct GpuBaselineMethod::Gl {
    std::unique_ptr<GlSession> session;
    GLuint program = 0;
    RenderTarget target;
};

GpuBaselineMethod::GpuBaselineMethod(GpuBaselineOptions options) : options_(options) {}
GpuBaselineMethod::~GpuBaselineMethod() = default;  // destroying the context frees its objects

std::string GpuBaselineMethod::glDescription() const { return gl_ ? gl_->session->context->report() : std::string(); }

Status GpuBaselineMethod::ensureGl(int res) {
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
    return gl_->session->makeCurrent();
}

Status GpuBaselineMethod::run(const BakeWindow& w, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    counts_.clear();
    const std::vector<bool> lights = lightsWithUndecided(cv);
    bool any = false;
    for (bool b : lights) any |= b;
    if (!any) return Status::ok();
    const int res = options_.resolution;
    if (res < 1) return makeError(ErrorKind::BadInput, "", 0, "GPU resolution must be at least 1");
    if (Status s = ensureGl(res); !s) return s;
    const GlApi& gl = gl_->session->gl;
    GpuTimer gpuTime(gl);

    const CountedBits bits = countedBits(w, cv, counts_);
    WindowTriangles tris(w);
    WindowBuffers buffers;
    TerrainHeightMap heights;
    if (Status s = uploadWindow(gl, w, tris, res, buffers, heights); !s) return s;
    BaselinePasses passes(gl, gl_->program, w, buffers, bits, counts_, stats);
    passes.setUp(heights, gl_->target.fbo, res);
    for (int l = 0; l < cv.lightCount; ++l)
        if (lights[size_t(l)]) passes.drawLight(l, res);
    passes.tearDown();
    if (heights.texture) gl.DeleteTextures(1, &heights.texture);
    buffers.destroy(gl);
    gpuTime.addTo(stats);
    if (Status s = gl.check("the baseline passes"); !s) return s;

    decideBits(counts_, res, cv, stats);
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

}  // namespace shadowcull::gpu

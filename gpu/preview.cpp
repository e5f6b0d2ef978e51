#include "gpu/preview.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>

#include <glm/geometric.hpp>

#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/preview_pixels.h"
#include "gpu/render_picture.h"
#include "gpu/window_draw.h"
#include "util/format.h"

namespace shadowcull::gpu {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxPcfRadius = 8;  // 289 taps: more reads no better and costs seconds

// Shadow pass: linear depth (directional: along the light, from w0; point/spot: distance
// from the light) and the caster's draw index, nearest caster per texel by the depth test
// (vertex shader: kWindowPositionVs).
const char* kDepthFs = R"(#version 430 core
in vec3 vPos;
uniform bool uPerspective;
uniform vec3 uEye;
uniform vec3 uW;
uniform float uW0;
uniform float uCaster;
layout(location = 0) out vec4 oDepth;
void main() {
    float d = uPerspective ? length(vPos - uEye) : dot(vPos, uW) - uW0;
    oDepth = vec4(d, uCaster, 0.0, 0.0);
}
)";

// Camera pass: the receiver point, both frames' PCF results and what decided a difference
// (the outputs: PreviewFrames in gpu/preview_pixels.h).
const char* kCameraFs = R"(#version 430 core
in vec3 vPos;
uniform int uType;          // 0 directional, 1 one perspective view, 2 cube
uniform vec3 uU[6];
uniform vec3 uV[6];
uniform vec3 uW[6];
uniform ivec2 uTile[6];     // texel offset of each view in the atlas
uniform vec4 uRect;         // directional: u0, v0, u1 - u0, v1 - v0
uniform float uW0;
uniform float uT;
uniform vec3 uEye;          // light position (point, spot)
uniform vec3 uLightDir;     // directional: travel; spot: axis
uniform int uRes;
uniform int uPcf;
uniform float uBias, uSlopeBias, uRange, uCosCone;
uniform float uNormalBias;  // metres along the front normal (semantics.md condition 5)
uniform vec3 uCamEye;
uniform bool uFlip, uTwoSided;
uniform float uKind, uReceiver;
uniform sampler2D uMapAll, uMapKept;
layout(location = 0) out vec4 oPos;
layout(location = 1) out vec4 oLit;
layout(location = 2) out vec4 oDiff;

// Continuous texel coordinates of a point in view k (perspective: false behind the eye).
bool texelCoords(int k, vec3 p, out vec2 f) {
    if (uType == 0) {
        f = (vec2(dot(p, uU[0]), dot(p, uV[0])) - uRect.xy) / uRect.zw * float(uRes);
        return true;
    }
    vec3 d = p - uEye;
    float z = dot(d, uW[k]);
    if (!(z > 0.0)) return false;
    f = (vec2(dot(d, uU[k]), dot(d, uV[k])) / (z * uT) + 1.0) * 0.5 * float(uRes);
    return true;
}

int cubeFace(vec3 d) {
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x >= 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y >= 0.0 ? 2 : 3;
    return d.z >= 0.0 ? 4 : 5;
}

// Unit direction of the centre ray of texel t of perspective view k.
vec3 centreRay(int k, ivec2 t) {
    vec2 xy = ((vec2(t) + 0.5) / float(uRes) * 2.0 - 1.0) * uT;
    return normalize(uU[k] * xy.x + uV[k] * xy.y + uW[k]);
}

void main() {
    vec3 n = normalize(cross(dFdx(vPos), dFdy(vPos)));
    if (dot(n, uCamEye - vPos) < 0.0) n = -n;       // the side the camera sees
    bool front = gl_FrontFacing != uFlip;            // mesh front towards the camera
    vec3 nFront = front ? n : -n;
    vec3 l = uType == 0 ? uLightDir : normalize(vPos - uEye);  // the way light travels
    float cosFront = dot(nFront, -l);
    bool receives = cosFront > 0.0 || (uTwoSided && cosFront != 0.0);
    float dist = length(vPos - uEye);
    if (uType != 0) {
        if (dist > uRange) receives = false;
        if (uCosCone > -2.0 && dot(l, uLightDir) < uCosCone) receives = false;
    }
    float c = abs(cosFront);
    float tanTheta = sqrt(max(0.0, 1.0 - c * c)) / max(c, 1e-7);
    float beta = uBias + uSlopeBias * tanTheta;
    // The lookup point: moved along the front normal, as engines do (three.js normalBias);
    // depth, texel and lateral distance are taken there, receiving (range, cone) at vPos.
    vec3 look = vPos + uNormalBias * nFront;
    float dq = uType == 0 ? dot(look, uW[0]) - uW0 : length(look - uEye);

    int k = uType == 2 ? cubeFace(look - uEye) : 0;
    vec2 f;
    float shadowedAll = 0.0, shadowedKept = 0.0, footprint = 0.0, caster = 0.0, margin = 0.0;
    if (receives && texelCoords(k, look, f)) {
        ivec2 t0 = ivec2(floor(f));
        for (int b = -uPcf; b <= uPcf; ++b)
            for (int a = -uPcf; a <= uPcf; ++a) {
                ivec2 t = t0 + ivec2(a, b);
                int kk = k;
                float lateral;
                if (uType == 2 && any(lessThan(t, ivec2(0))) || uType == 2 && any(greaterThanEqual(t, ivec2(uRes)))) {
                    // Across a cube edge: the texel of the neighbouring face that holds the
                    // direction of this (extrapolated) texel centre, as a cube map does.
                    vec3 d = centreRay(k, t);
                    kk = cubeFace(d);
                    vec2 g;
                    texelCoords(kk, uEye + d, g);
                    t = clamp(ivec2(floor(g)), ivec2(0), ivec2(uRes - 1));
                }
                if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(uRes)))) continue;  // off the map: lit
                if (uType == 0) {
                    vec2 cuv = uRect.xy + (vec2(t) + 0.5) / float(uRes) * uRect.zw;
                    lateral = length(vec2(dot(look, uU[0]), dot(look, uV[0])) - cuv);
                } else {
                    lateral = length(cross(look - uEye, centreRay(kk, t)));
                }
                footprint = max(footprint, lateral);
                vec2 all = texelFetch(uMapAll, uTile[kk] + t, 0).rg;
                float kept = texelFetch(uMapKept, uTile[kk] + t, 0).r;
                bool sAll = all.r + beta < dq, sKept = kept + beta < dq;
                shadowedAll += sAll ? 1.0 : 0.0;
                shadowedKept += sKept ? 1.0 : 0.0;
                if (sAll != sKept && caster == 0.0) {
                    caster = all.g + 1.0;
                    margin = dq - (all.r + beta);
                }
            }
    }
    oPos = vec4(vPos, uReceiver);
    oLit = vec4(shadowedAll, shadowedKept, receives ? c : -1.0, uKind);
    // The triangle within its draw, bit for bit (the pixel's exact receiver point is found
    // on it: gpu/preview_pixels.cpp).
    oDiff = vec4(footprint, caster, margin, intBitsToFloat(gl_PrimitiveID));
}
)";

// Column-major float matrix of a row-major double one.
std::array<float, 16> toGlMatrix(const double r[4][4]) {
    std::array<float, 16> m{};
    for (int row = 0; row < 4; ++row)
        for (int col = 0; col < 4; ++col) m[size_t(col * 4 + row)] = float(r[row][col]);
    return m;
}

// The camera's clip matrix (PreviewCamera's rays, from near to far metres ahead).
std::array<float, 16> cameraClip(const PreviewCamera& cam, double nearZ, double farZ) {
    const glm::dvec3 &f = cam.forward, &s = cam.side, &u = cam.up, &eye = cam.eye;
    const double A = -(farZ + nearZ) / (farZ - nearZ), B = -2 * farZ * nearZ / (farZ - nearZ);
    double r[4][4] = {};
    // x, y: along s and u over the half-widths; w_clip = f . (p - eye) (distance ahead);
    // z_clip = A * z_view + B with z_view = -f . (p - eye) (OpenGL's camera looks down -z).
    for (int k = 0; k < 3; ++k) {
        r[0][k] = s[k] / cam.tanHalfX;
        r[1][k] = u[k] / cam.tanHalfY;
        r[2][k] = -f[k] * A;
        r[3][k] = f[k];
    }
    r[0][3] = -glm::dot(s, eye) / cam.tanHalfX;
    r[1][3] = -glm::dot(u, eye) / cam.tanHalfY;
    r[2][3] = glm::dot(f, eye) * A + B;
    r[3][3] = -glm::dot(f, eye);
    return toGlMatrix(r);
}

double median(std::vector<double> v) {
    if (v.empty()) return -1;
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : (v[v.size() / 2 - 1] + v[v.size() / 2]) / 2;
}

std::string vecText(const glm::dvec3& v) {
    auto r = [](double x) { return formatNumber(std::round(x * 100) / 100 + 0.0); };
    return "(" + r(v.x) + ", " + r(v.y) + ", " + r(v.z) + ")";
}

std::string metres(double m) {
    char b[32];
    std::snprintf(b, sizeof b, "%.3g m", m);
    return b;
}

// Where the default camera looks: the chunk's centre at ground height, from above and
// a little to the south, so that relief and shadows read.
void defaultCamera(const BakeWindow& w, glm::dvec3& eye, glm::dvec3& target) {
    const double S = w.chunkSize;
    double y = 0;
    if (std::optional<double> h = w.lsTerrainHeight(S / 2, S / 2)) y = *h;
    else if (!w.lsCentreBounds.empty()) y = w.lsCentreBounds.min.y;
    target = glm::dvec3(S / 2, y, S / 2);
    eye = target + glm::dvec3(0, 0.85 * S, 0.55 * S);
}

// The engine's own run-time culling of a caster for one view of the shadow map: a point or
// spot light skips casters whose box lies wholly beyond its range, and each perspective view
// those wholly outside its frustum. (A directional view covers the whole window.)
bool engineDraws(const LightView& v, const Light& L, const Aabb& box, double nearZ) {
    if (box.empty()) return false;
    if (!v.perspective) return true;
    const glm::dvec3 nearest = glm::clamp(v.eye, box.min, box.max);
    if (glm::length(nearest - v.eye) > L.range) return false;
    bool allNear = true, allRight = true, allLeft = true, allUp = true, allDown = true;
    for (int c = 0; c < 8; ++c) {
        const glm::dvec3 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y, (c & 4) ? box.max.z : box.min.z);
        const glm::dvec3 q = v.toView(p);
        allNear &= q.z < nearZ;
        allRight &= q.x > v.t * q.z, allLeft &= q.x < -v.t * q.z;
        allUp &= q.y > v.t * q.z, allDown &= q.y < -v.t * q.z;
    }
    return !(allNear || allRight || allLeft || allUp || allDown);
}

std::vector<float> readRgba(const GlApi& gl, const RenderTarget& t, int attachment) {
    std::vector<float> v(size_t(t.width) * size_t(t.height) * 4);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, t.fbo);
    gl.ReadBuffer(GLenum(GL_COLOR_ATTACHMENT0 + attachment));
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, t.width, t.height, GL_RGBA, GL_FLOAT, v.data());
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    return v;
}

// Checks the request against the window; the light it names.
Status checkRequest(const BakeWindow& w, const PreviewRequest& rq) {
    if (rq.light < 0 || rq.light >= int(w.lsLights.size()))
        return makeError(ErrorKind::BadInput, "", 0,
                         "no light " + std::to_string(rq.light + 1) + " (the space has " +
                             std::to_string(w.lsLights.size()) + ")");
    if (rq.shadowResolution < 16 || rq.shadowResolution > 8192)
        return makeError(ErrorKind::BadInput, "", 0, "--shadow-resolution must be within 16..8192");
    if (rq.pcfRadius > kMaxPcfRadius)
        return makeError(ErrorKind::BadInput, "", 0, "--pcf-radius must be within 0.." + std::to_string(kMaxPcfRadius));
    if (rq.width < 16 || rq.height < 16 || rq.width > 4096 || rq.height > 4096)
        return makeError(ErrorKind::BadInput, "", 0, "preview frames must be within 16..4096 pixels per side");
    return Status::ok();
}

// The shadow map's views and sampling: texel size, PCF radius and the worst footprint.
struct ShadowMapPlan {
    std::vector<LightView> views;
    int type = 0;  // the camera shader's uType: 0 directional, 1 one perspective view, 2 cube
    int cols = 1, rows = 1;  // the views' tiles in one texture
    double nearZ = 0, farZ = 0;
};
Expected<ShadowMapPlan> planShadowMaps(const BakeWindow& w, const Light& L, const PreviewRequest& rq, PreviewReport& report) {
    const int res = rq.shadowResolution;
    ShadowMapPlan plan;
    // A directional light's view covers the whole window (every caster, every receiver).
    plan.views = lightViews(w, L, res);
    if (plan.views.empty()) return makeError(ErrorKind::BadInput, "", 0, "the window holds no triangles");
    const bool directional = L.type == LightType::Directional;
    plan.type = directional ? 0 : plan.views.size() == 1 ? 1 : 2;
    plan.cols = plan.views.size() > 1 ? 3 : 1, plan.rows = plan.views.size() > 1 ? 2 : 1;
    report.views = int(plan.views.size());
    // Texel diagonal at the worst receiver: directional everywhere the same; perspective at
    // the range (the lateral size of a texel grows with the distance, at most 2t/res per metre).
    double texelDiagonal;
    if (directional) {
        const double tu = (plan.views[0].u1 - plan.views[0].u0) / res, tv = (plan.views[0].v1 - plan.views[0].v0) / res;
        report.texelSize = std::max(tu, tv);
        texelDiagonal = std::hypot(tu, tv);
    } else {
        report.texelSize = 2 * plan.views[0].t / res * L.range;
        texelDiagonal = report.texelSize * std::sqrt(2.0);
    }
    report.pcfDefaulted = rq.pcfRadius < 0;
    report.pcfRadius = report.pcfDefaulted ? defaultPcfRadius(L.filterRadius, texelDiagonal) : rq.pcfRadius;
    report.worstFootprint = (report.pcfRadius + 0.5) * texelDiagonal;
    plan.nearZ = std::max(1e-3, 1e-4 * L.range), plan.farZ = L.range * 1.001 + plan.nearZ;
    return plan;
}

// The preview's GL objects (programs, the two shadow maps, the camera's targets, the
// window's vertex buffer), deleted with it; the session must outlive it.
struct PreviewGl {
    const GlApi& gl;
    GLuint depthProg = 0, camProg = 0;
    std::vector<RenderTarget> maps;  // [0] every caster, [1] kept casters
    std::optional<RenderTarget> camTarget;
    WindowBuffers buffers;
    explicit PreviewGl(const GlApi& g) : gl(g) {}
    PreviewGl(const PreviewGl&) = delete;
    PreviewGl& operator=(const PreviewGl&) = delete;
    ~PreviewGl() {
        buffers.destroy(gl);
        for (RenderTarget& r : maps) destroyRenderTarget(gl, r);
        if (camTarget) destroyRenderTarget(gl, *camTarget);
        if (depthProg) gl.DeleteProgram(depthProg);
        if (camProg) gl.DeleteProgram(camProg);
    }
    Status make(const BakeWindow& w, const WindowTriangles& tris, const ShadowMapPlan& plan, const PreviewRequest& rq) {
        Expected<GLuint> d = gl.program(kWindowPositionVs, nullptr, kDepthFs);
        if (!d) return d.error();
        depthProg = *d;
        Expected<GLuint> c = gl.program(kWindowPositionVs, nullptr, kCameraFs);
        if (!c) return c.error();
        camProg = *c;
        const int res = rq.shadowResolution;
        for (int m = 0; m < 2; ++m) {
            Expected<RenderTarget> t = makeRenderTarget(gl, plan.cols * res, plan.rows * res, {GL_RG32F}, true);
            if (!t) return t.error();
            maps.push_back(*t);
        }
        Expected<RenderTarget> cam = makeRenderTarget(gl, rq.width, rq.height, {GL_RGBA32F, GL_RGBA32F, GL_RGBA32F}, true);
        if (!cam) return cam.error();
        camTarget = *cam;
        return buffers.upload(gl, w, tris);
    }
};

// Which draws each frame's shadow pass issues, per group range: the engine's casters
// (castsShadow) in both, and of the centre chunk's only those whose bit is 1 (undecided
// bits are written 1) in the kept one; per view, what the engine itself culls at run time
// (range, view frustum) is left out of both, so that the difference between them is what
// the masks alone remove.
struct CasterSets {
    std::vector<int> verdictObject;  // per window object: its index in the verdicts, or -1
    std::vector<uint8_t> inAll, inKept;
    std::vector<std::vector<uint8_t>> inView;  // [view][range]
};
CasterSets chooseCasters(const BakeWindow& w, const ChunkVerdicts& cv, int light, const std::vector<GroupRange>& ranges,
                         const WindowTriangles& tris, const ShadowMapPlan& plan, PreviewReport& report) {
    CasterSets c;
    c.verdictObject.assign(w.objects.size(), -1);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].windowObject >= 0) c.verdictObject[size_t(cv.objects[oi].windowObject)] = int(oi);
    c.inAll.resize(ranges.size()), c.inKept.resize(ranges.size());
    for (size_t k = 0; k < ranges.size(); ++k) {
        const WindowObject& o = w.objects[ranges[k].object];
        c.inAll[k] = o.castsShadow;
        c.inKept[k] = c.inAll[k];
        const int oi = c.verdictObject[ranges[k].object];
        if (c.inAll[k] && o.centre && oi >= 0 && int(ranges[k].group) < cv.objects[size_t(oi)].groupCount &&
            light < cv.lightCount && cv.at(size_t(oi), int(ranges[k].group), light).verdict == Verdict::Culled)
            c.inKept[k] = 0;
    }
    const Light& L = w.lsLights[size_t(light)];
    c.inView.assign(plan.views.size(), std::vector<uint8_t>(ranges.size(), 0));
    std::vector<std::vector<Aabb>> boxes(w.objects.size());
    for (size_t o = 0; o < w.objects.size(); ++o) boxes[o] = groupBounds(w, tris, o);
    for (size_t v = 0; v < plan.views.size(); ++v)
        for (size_t k = 0; k < ranges.size(); ++k)
            c.inView[v][k] = engineDraws(plan.views[v], L, boxes[ranges[k].object][ranges[k].group], plan.nearZ);
    for (size_t k = 0; k < ranges.size(); ++k) {
        bool any = false;
        for (size_t v = 0; v < plan.views.size(); ++v) any |= c.inView[v][k] != 0;
        report.culledCasters += any && c.inAll[k] && !c.inKept[k];
    }
    return c;
}

// Both shadow passes, alternating (all, kept) so that both see the same machine state,
// `repeats` + 1 times (the first not counted: it compiles shaders and allocates, and a
// device's first timer query can return garbage: llvmpipe's did, 3.4e6 ms). Fills the
// report's pass costs (medians).
void drawShadowPasses(PreviewGl& g, const Light& L, const ShadowMapPlan& plan, const CasterSets& c, int res, int repeats,
                      PreviewReport& report) {
    const GlApi& gl = g.gl;
    const std::vector<GroupRange>& ranges = g.buffers.ranges();
    GLuint query = 0;
    gl.GetError();
    gl.GenQueries(1, &query);
    gl.UseProgram(g.depthProg);
    const GLint uClipD = gl.uniform(g.depthProg, "uClip"), uCaster = gl.uniform(g.depthProg, "uCaster");
    const LightView& v0 = plan.views[0];
    gl.Uniform1i(gl.uniform(g.depthProg, "uPerspective"), L.type != LightType::Directional);
    gl.Uniform3f(gl.uniform(g.depthProg, "uEye"), float(L.position.x), float(L.position.y), float(L.position.z));
    gl.Uniform3f(gl.uniform(g.depthProg, "uW"), float(v0.W.x), float(v0.W.y), float(v0.W.z));
    gl.Uniform1f(gl.uniform(g.depthProg, "uW0"), float(v0.w0));
    g.buffers.bind(gl);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    gl.Disable(GL_CULL_FACE);  // depth of the first surface on the ray, whichever side faces the light
    gl.Disable(GL_BLEND);
    std::vector<double> gpuMs[2], cpuMs[2];
    bool timerWorks = gl.GetError() == GL_NO_ERROR;
    for (int rep = 0; rep < std::max(1, repeats) + 1; ++rep)
        for (int m = 0; m < 2; ++m) {
            const std::vector<uint8_t>& drawn = m == 0 ? c.inAll : c.inKept;
            ShadowPassTiming& timing = m == 0 ? report.all : report.kept;
            gl.Finish();
            const auto start = std::chrono::steady_clock::now();
            if (timerWorks) gl.BeginQuery(GL_TIME_ELAPSED, query);
            gl.BindFramebuffer(GL_FRAMEBUFFER, g.maps[size_t(m)].fbo);
            gl.Viewport(0, 0, plan.cols * res, plan.rows * res);
            const float far[4] = {1e30f, -1.0f, 0, 0};
            gl.ClearBufferfv(GL_COLOR, 0, far);
            gl.Clear(GL_DEPTH_BUFFER_BIT);
            timing = ShadowPassTiming{};
            std::vector<uint8_t> counted(ranges.size(), 0);
            for (size_t v = 0; v < plan.views.size(); ++v) {
                const LightView& view = plan.views[v];
                gl.Viewport(int(v % 3) * res, int(v / 3) * res, res, res);
                const std::array<float, 16> clip = view.clipMatrix(plan.nearZ, plan.farZ, 1e-3 * (view.w1 - view.w0) + 1e-3);
                gl.UniformMatrix4fv(uClipD, 1, GL_FALSE, clip.data());
                for (size_t k = 0; k < ranges.size(); ++k) {
                    if (!drawn[k] || !c.inView[v][k]) continue;
                    gl.Uniform1f(uCaster, float(k));
                    timing.casters += !counted[k];
                    counted[k] = 1;
                    gl.DrawArrays(GL_TRIANGLES, ranges[k].first, ranges[k].count);
                    ++timing.drawCalls;
                    timing.triangles += uint64_t(ranges[k].count / 3);
                }
            }
            if (timerWorks) gl.EndQuery(GL_TIME_ELAPSED);
            gl.Finish();
            if (rep > 0)
                cpuMs[m].push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
            if (timerWorks) {
                GLuint64 ns = 0;
                gl.GetQueryObjectui64v(query, GL_QUERY_RESULT, &ns);
                if (gl.GetError() != GL_NO_ERROR) timerWorks = false;
                else if (rep > 0) gpuMs[m].push_back(double(ns) / 1e6);
            }
        }
    for (int m = 0; m < 2; ++m) {
        ShadowPassTiming& timing = m == 0 ? report.all : report.kept;
        timing.cpuMs = median(cpuMs[m]);
        timing.gpuMs = timerWorks ? median(gpuMs[m]) : -1;
    }
    gl.DeleteQueries(1, &query);
}

// The camera pass: every surface, shadowed against both maps at once (kCameraFs).
PreviewFrames drawCameraPass(PreviewGl& g, const BakeWindow& w, const Light& L, const ShadowMapPlan& plan,
                             const PreviewCamera& cam, const PreviewRequest& rq, int pcfRadius) {
    const GlApi& gl = g.gl;
    const std::vector<GroupRange>& ranges = g.buffers.ranges();
    const int res = rq.shadowResolution;
    const double span = glm::length(w.lsBounds.max - w.lsBounds.min) + glm::length(cam.target - cam.eye);
    const double camNear = std::max(0.02, 1e-5 * span), camFar = 2 * span + 1;
    gl.BindFramebuffer(GL_FRAMEBUFFER, g.camTarget->fbo);
    const GLenum drawBuffers[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    gl.DrawBuffers(3, drawBuffers);
    gl.Viewport(0, 0, rq.width, rq.height);
    const float zero[4] = {0, 0, 0, 0};
    for (int a = 0; a < 3; ++a) gl.ClearBufferfv(GL_COLOR, a, zero);
    gl.Clear(GL_DEPTH_BUFFER_BIT);
    const GLuint p = g.camProg;
    gl.UseProgram(p);
    const std::array<float, 16> camClip = cameraClip(cam, camNear, camFar);
    gl.UniformMatrix4fv(gl.uniform(p, "uClip"), 1, GL_FALSE, camClip.data());
    gl.Uniform1i(gl.uniform(p, "uType"), plan.type);
    for (size_t v = 0; v < plan.views.size(); ++v) {
        const LightView& view = plan.views[v];
        const std::string i = "[" + std::to_string(v) + "]";
        gl.Uniform3f(gl.uniform(p, ("uU" + i).c_str()), float(view.U.x), float(view.U.y), float(view.U.z));
        gl.Uniform3f(gl.uniform(p, ("uV" + i).c_str()), float(view.V.x), float(view.V.y), float(view.V.z));
        gl.Uniform3f(gl.uniform(p, ("uW" + i).c_str()), float(view.W.x), float(view.W.y), float(view.W.z));
        gl.Uniform2i(gl.uniform(p, ("uTile" + i).c_str()), GLint(v % 3) * res, GLint(v / 3) * res);
    }
    const LightView& v0 = plan.views[0];
    gl.Uniform4f(gl.uniform(p, "uRect"), float(v0.u0), float(v0.v0), float(v0.u1 - v0.u0), float(v0.v1 - v0.v0));
    gl.Uniform1f(gl.uniform(p, "uW0"), float(v0.w0));
    gl.Uniform1f(gl.uniform(p, "uT"), float(v0.t));
    gl.Uniform3f(gl.uniform(p, "uEye"), float(L.position.x), float(L.position.y), float(L.position.z));
    gl.Uniform3f(gl.uniform(p, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
    gl.Uniform1i(gl.uniform(p, "uRes"), res);
    gl.Uniform1i(gl.uniform(p, "uPcf"), pcfRadius);
    gl.Uniform1f(gl.uniform(p, "uBias"), float(L.bias));
    gl.Uniform1f(gl.uniform(p, "uSlopeBias"), float(L.slopeBias));
    gl.Uniform1f(gl.uniform(p, "uNormalBias"), float(L.normalBias));
    gl.Uniform1f(gl.uniform(p, "uRange"), float(L.range));
    gl.Uniform1f(gl.uniform(p, "uCosCone"),
                 L.type == LightType::Spot ? float(std::cos(L.coneHalfAngleDeg * kPi / 180.0)) : -3.0f);
    gl.Uniform3f(gl.uniform(p, "uCamEye"), float(cam.eye.x), float(cam.eye.y), float(cam.eye.z));
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, g.maps[0].colour[0]);
    gl.ActiveTexture(GL_TEXTURE1);
    gl.BindTexture(GL_TEXTURE_2D, g.maps[1].colour[0]);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.Uniform1i(gl.uniform(p, "uMapAll"), 0);
    gl.Uniform1i(gl.uniform(p, "uMapKept"), 1);
    const GLint uFlip = gl.uniform(p, "uFlip"), uTwoSided = gl.uniform(p, "uTwoSided"), uKind = gl.uniform(p, "uKind"),
                uReceiver = gl.uniform(p, "uReceiver");
    g.buffers.bind(gl);
    for (size_t k = 0; k < ranges.size(); ++k) {
        const WindowObject& o = w.objects[ranges[k].object];
        gl.Uniform1i(uFlip, o.flipsWinding);
        gl.Uniform1i(uTwoSided, o.mesh->groups[ranges[k].group].twoSided());
        gl.Uniform1f(uKind, o.kind == ChunkObject::Kind::Terrain ? 1.0f : o.centre ? 3.0f : 2.0f);
        gl.Uniform1f(uReceiver, float(k + 1));
        gl.DrawArrays(GL_TRIANGLES, ranges[k].first, ranges[k].count);
    }
    gl.BindVertexArray(0);
    gl.Finish();
    PreviewFrames fr;
    fr.width = rq.width, fr.height = rq.height;
    fr.pos = readRgba(gl, *g.camTarget, 0);
    fr.lit = readRgba(gl, *g.camTarget, 1);
    fr.diff = readRgba(gl, *g.camTarget, 2);
    return fr;
}

std::vector<std::string> pictureTitle(const BakeWindow& w, const Light& L, int light, const ShadowMapPlan& plan,
                                      const PreviewRequest& rq, const PreviewReport& report) {
    const int res = rq.shadowResolution;
    std::vector<std::string> title;
    title.push_back(chunkFileName(w.centre) + " - light " + std::to_string(light + 1) + " '" + L.name + "' (" +
                    lightTypeName(L.type) + ") - shadow mapping as an engine does it, with every caster and with the kept ones");
    title.push_back("shadow map " + std::to_string(res) + " x " + std::to_string(res) +
                    (plan.views.size() > 1 ? " x 6 faces" : "") + ", texel " + metres(report.texelSize) +
                    (L.type == LightType::Directional ? "" : " at range") + "; PCF radius " + std::to_string(report.pcfRadius) +
                    (report.pcfDefaulted ? " (default)" : "") + ", footprint " + metres(report.worstFootprint) +
                    " vs filterRadius " + metres(L.filterRadius) + "; bias " + metres(L.bias) + ", slope bias " +
                    metres(L.slopeBias) + ", normal bias " + metres(L.normalBias));
    title.push_back("camera " + vecText(report.wsEye) + " -> " + vecText(report.wsTarget) + "; " + report.device);
    return title;
}

}  // namespace

int defaultPcfRadius(double filterRadius, double texelDiagonal) {
    if (!(texelDiagonal > 0) || !(filterRadius > 0)) return 0;
    // (A hair of slack so that a footprint equal to the radius, up to rounding, fits.)
    const double r = std::floor(filterRadius / texelDiagonal - 0.5 + 1e-9);
    if (!(r >= 0)) return 0;
    return int(std::min<double>(r, kMaxPcfRadius));
}

Expected<PreviewReport> renderShadowPreview(const BakeWindow& w, const ChunkVerdicts& cv, const PreviewRequest& rq,
                                            const std::string& pngPath) {
    if (Status s = checkRequest(w, rq); !s) return s.error();
    const Light& L = w.lsLights[size_t(rq.light)];
    PreviewReport report;
    glm::dvec3 eye, target;
    defaultCamera(w, eye, target);
    if (rq.wsEye) eye = *rq.wsEye - w.wsOrigin;
    if (rq.wsTarget) target = *rq.wsTarget - w.wsOrigin;
    if (!(glm::length(target - eye) > 1e-6))
        return makeError(ErrorKind::BadInput, "", 0, "--camera: the eye and the target are the same point");
    report.wsEye = eye + w.wsOrigin, report.wsTarget = target + w.wsOrigin;
    const PreviewCamera camera(eye, target, rq.fovYDeg, double(rq.width) / rq.height);
    Expected<ShadowMapPlan> plan = planShadowMaps(w, L, rq, report);
    if (!plan) return plan.error();

    Expected<std::unique_ptr<GlSession>> session = openGlSession();
    if (!session) return session.error();
    report.device = (*session)->context->description();
    const WindowTriangles tris(w);
    PreviewFrames frames;
    std::vector<GroupRange> ranges;
    CasterSets casters;
    {
        PreviewGl g((*session)->gl);
        if (Status s = g.make(w, tris, *plan, rq); !s) return s.error();
        ranges = g.buffers.ranges();
        casters = chooseCasters(w, cv, rq.light, ranges, tris, *plan, report);
        drawShadowPasses(g, L, *plan, casters, rq.shadowResolution, rq.timingRepeats, report);
        frames = drawCameraPass(g, w, L, *plan, camera, rq, report.pcfRadius);
        if (Status drawn = g.gl.check("rendering the shadow preview"); !drawn) return drawn.error();
    }

    PreviewScene scene{w, cv, rq.light, ranges, {}, casters.verdictObject, tris, camera,
                       (2 * report.pcfRadius + 1) * (2 * report.pcfRadius + 1)};
    scene.culledRange.resize(ranges.size());
    for (size_t k = 0; k < ranges.size(); ++k) scene.culledRange[k] = casters.inAll[k] && !casters.inKept[k];
    const PreviewPanels panels = judgePixels(scene, frames, rq, report);
    const RgbImage pic =
        composePreviewPicture(panels, pictureTitle(w, L, rq.light, *plan, rq, report), report, rq.width, rq.height);
    report.pictureWidth = pic.width(), report.pictureHeight = pic.height();
    if (Status s = writePng(pngPath, pic); !s) return s.error();
    return report;
}

}  // namespace shadowcull::gpu

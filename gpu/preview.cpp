#include "gpu/preview.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/bitmap_font.h"
#include "core/format.h"
#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/render_picture.h"
#include "gpu/window_draw.h"

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

// Camera pass: the receiver point, both frames' PCF results and what decided a difference.
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
    float dq = uType == 0 ? dot(vPos, uW[0]) - uW0 : dist;

    int k = uType == 2 ? cubeFace(vPos - uEye) : 0;
    vec2 f;
    float shadowedAll = 0.0, shadowedKept = 0.0, footprint = 0.0, caster = 0.0, margin = 0.0;
    if (receives && texelCoords(k, vPos, f)) {
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
                    lateral = length(vec2(dot(vPos, uU[0]), dot(vPos, uV[0])) - cuv);
                } else {
                    lateral = length(cross(vPos - uEye, centreRay(kk, t)));
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
    oDiff = vec4(footprint, caster, margin, 0.0);
}
)";

// Column-major float matrix of a row-major double one.
std::array<float, 16> toGlMatrix(const double r[4][4]) {
    std::array<float, 16> m{};
    for (int row = 0; row < 4; ++row)
        for (int col = 0; col < 4; ++col) m[size_t(col * 4 + row)] = float(r[row][col]);
    return m;
}

// Perspective camera from eye to target, window-local; y up (z when looking straight down).
std::array<float, 16> cameraClip(const glm::dvec3& eye, const glm::dvec3& target, double fovYDeg, double aspect,
                                 double nearZ, double farZ) {
    const glm::dvec3 f = glm::normalize(target - eye);
    glm::dvec3 up(0, 1, 0);
    if (std::abs(glm::dot(f, up)) > 0.999) up = glm::dvec3(0, 0, -1);
    const glm::dvec3 s = glm::normalize(glm::cross(f, up)), u = glm::cross(s, f);
    const double ty = std::tan(fovYDeg * kPi / 360.0), tx = ty * aspect;
    const double A = -(farZ + nearZ) / (farZ - nearZ), B = -2 * farZ * nearZ / (farZ - nearZ);
    double r[4][4] = {};
    // x, y: along s and u over the half-widths; w_clip = f . (p - eye) (distance ahead);
    // z_clip = A * z_view + B with z_view = -f . (p - eye) (OpenGL's camera looks down -z).
    for (int k = 0; k < 3; ++k) {
        r[0][k] = s[k] / tx;
        r[1][k] = u[k] / ty;
        r[2][k] = -f[k] * A;
        r[3][k] = f[k];
    }
    r[0][3] = -glm::dot(s, eye) / tx;
    r[1][3] = -glm::dot(u, eye) / ty;
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

std::string msText(double ms) {
    if (ms < 0) return "n/a";
    char b[32];
    std::snprintf(b, sizeof b, "%.2f ms", ms);
    return b;
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

struct Frames {
    int width = 0, height = 0;
    std::vector<float> pos, lit, diff;  // RGBA each, rows bottom to top
};

std::vector<float> readRgba(const GlApi& gl, const RenderTarget& t, int attachment) {
    std::vector<float> v(size_t(t.width) * size_t(t.height) * 4);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, t.fbo);
    gl.ReadBuffer(GLenum(GL_COLOR_ATTACHMENT0 + attachment));
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl.ReadPixels(0, 0, t.width, t.height, GL_RGBA, GL_FLOAT, v.data());
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    return v;
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
    if (rq.light < 0 || rq.light >= int(w.lsLights.size()))
        return makeError(ErrorKind::BadInput, "", 0,
                         "no light " + std::to_string(rq.light + 1) + " (the space has " +
                             std::to_string(w.lsLights.size()) + ")");
    const int res = rq.shadowResolution;
    if (res < 16 || res > 8192) return makeError(ErrorKind::BadInput, "", 0, "--shadow-resolution must be within 16..8192");
    if (rq.pcfRadius > kMaxPcfRadius)
        return makeError(ErrorKind::BadInput, "", 0, "--pcf-radius must be within 0.." + std::to_string(kMaxPcfRadius));
    if (rq.width < 16 || rq.height < 16 || rq.width > 4096 || rq.height > 4096)
        return makeError(ErrorKind::BadInput, "", 0, "preview frames must be within 16..4096 pixels per side");
    const Light& L = w.lsLights[size_t(rq.light)];
    PreviewReport report;

    glm::dvec3 eye, target;
    defaultCamera(w, eye, target);
    if (rq.wsEye) eye = *rq.wsEye - w.wsOrigin;
    if (rq.wsTarget) target = *rq.wsTarget - w.wsOrigin;
    if (!(glm::length(target - eye) > 1e-6))
        return makeError(ErrorKind::BadInput, "", 0, "--camera: the eye and the target are the same point");
    report.wsEye = eye + w.wsOrigin, report.wsTarget = target + w.wsOrigin;

    // The light's views; a directional one covers the whole window (every caster, every receiver).
    std::vector<LightView> views = lightViews(w, L, res);
    if (views.empty()) return makeError(ErrorKind::BadInput, "", 0, "the window holds no triangles");
    const bool directional = L.type == LightType::Directional;
    const int type = directional ? 0 : views.size() == 1 ? 1 : 2;
    report.views = int(views.size());
    // Texel diagonal at the worst receiver: directional everywhere the same; perspective at
    // the range (the lateral size of a texel grows with the distance, at most 2t/res per metre).
    double texelDiagonal;
    if (directional) {
        const double tu = (views[0].u1 - views[0].u0) / res, tv = (views[0].v1 - views[0].v0) / res;
        report.texelSize = std::max(tu, tv);
        texelDiagonal = std::hypot(tu, tv);
    } else {
        report.texelSize = 2 * views[0].t / res * L.range;
        texelDiagonal = report.texelSize * std::sqrt(2.0);
    }
    report.pcfDefaulted = rq.pcfRadius < 0;
    report.pcfRadius = report.pcfDefaulted ? defaultPcfRadius(L.filterRadius, texelDiagonal) : rq.pcfRadius;
    report.worstFootprint = (report.pcfRadius + 0.5) * texelDiagonal;

    Expected<std::unique_ptr<GlSession>> session = openGlSession();
    if (!session) return session.error();
    const GlApi& gl = (*session)->gl;
    report.device = (*session)->context->description();
    Expected<GLuint> depthProg = gl.program(kWindowPositionVs, nullptr, kDepthFs);
    if (!depthProg) return depthProg.error();
    Expected<GLuint> camProg = gl.program(kWindowPositionVs, nullptr, kCameraFs);
    if (!camProg) {
        gl.DeleteProgram(*depthProg);
        return camProg.error();
    }
    const int cols = views.size() > 1 ? 3 : 1, rows = views.size() > 1 ? 2 : 1;
    std::vector<RenderTarget> maps;  // [0] every caster, [1] kept casters
    for (int m = 0; m < 2; ++m) {
        Expected<RenderTarget> t = makeRenderTarget(gl, cols * res, rows * res, {GL_RG32F}, true);
        if (!t) {
            for (RenderTarget& r : maps) destroyRenderTarget(gl, r);
            gl.DeleteProgram(*depthProg);
            gl.DeleteProgram(*camProg);
            return t.error();
        }
        maps.push_back(*t);
    }
    Expected<RenderTarget> camTarget = makeRenderTarget(gl, rq.width, rq.height, {GL_RGBA32F, GL_RGBA32F, GL_RGBA32F}, true);
    WindowTriangles tris(w);
    WindowBuffers buffers;
    Status uploaded = camTarget ? buffers.upload(gl, w, tris) : Status::ok();
    auto cleanup = [&] {
        buffers.destroy(gl);
        for (RenderTarget& r : maps) destroyRenderTarget(gl, r);
        if (camTarget) destroyRenderTarget(gl, *camTarget);
        gl.DeleteProgram(*depthProg);
        gl.DeleteProgram(*camProg);
    };
    if (!camTarget || !uploaded) {
        cleanup();
        return camTarget ? uploaded.error() : camTarget.error();
    }

    // Which draws each frame's shadow pass issues: the engine's casters (castsShadow), and of
    // the centre chunk's only those whose bit is 1 (undecided bits are written 1).
    std::vector<int> verdictObject(w.objects.size(), -1);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].windowObject >= 0) verdictObject[size_t(cv.objects[oi].windowObject)] = int(oi);
    const std::vector<GroupRange> ranges = buffers.ranges();  // a copy: kept after the buffers go
    std::vector<uint8_t> inAll(ranges.size()), inKept(ranges.size());
    for (size_t k = 0; k < ranges.size(); ++k) {
        const WindowObject& o = w.objects[ranges[k].object];
        inAll[k] = !o.source || o.source->castsShadow;
        inKept[k] = inAll[k];
        const int oi = verdictObject[ranges[k].object];
        if (inAll[k] && o.centre && oi >= 0 && int(ranges[k].group) < cv.objects[size_t(oi)].groupCount &&
            rq.light < cv.lightCount && cv.at(size_t(oi), int(ranges[k].group), rq.light).verdict == Verdict::Culled)
            inKept[k] = 0;
    }
    // What the engine itself culls at run time (range, view frustum) is left out of both
    // passes, so that the difference between them is what the masks alone remove.
    const double nearZ = std::max(1e-3, 1e-4 * L.range), farZ = L.range * 1.001 + nearZ;
    std::vector<std::vector<uint8_t>> inView(views.size(), std::vector<uint8_t>(ranges.size(), 0));
    {
        std::vector<std::vector<Aabb>> boxes(w.objects.size());
        for (size_t o = 0; o < w.objects.size(); ++o) boxes[o] = groupBounds(w, tris, o);
        for (size_t v = 0; v < views.size(); ++v)
            for (size_t k = 0; k < ranges.size(); ++k)
                inView[v][k] = engineDraws(views[v], L, boxes[ranges[k].object][ranges[k].group], nearZ);
    }
    for (size_t k = 0; k < ranges.size(); ++k) {
        bool any = false;
        for (size_t v = 0; v < views.size(); ++v) any |= inView[v][k] != 0;
        report.culledCasters += any && inAll[k] && !inKept[k];
    }
    auto rangeLabel = [&](size_t k) {
        const WindowObject& o = w.objects[ranges[k].object];
        const std::string& name = o.mesh->groups[ranges[k].group].name;
        return o.label + " group " + std::to_string(ranges[k].group) + (name.empty() ? "" : " (" + name + ")");
    };

    // Shadow passes, alternating (all, kept) so that both see the same machine state.
    GLuint query = 0;
    gl.GetError();
    gl.GenQueries(1, &query);
    gl.UseProgram(*depthProg);
    const GLint uClipD = gl.uniform(*depthProg, "uClip"), uCaster = gl.uniform(*depthProg, "uCaster");
    gl.Uniform1i(gl.uniform(*depthProg, "uPerspective"), !directional);
    gl.Uniform3f(gl.uniform(*depthProg, "uEye"), float(L.position.x), float(L.position.y), float(L.position.z));
    gl.Uniform3f(gl.uniform(*depthProg, "uW"), float(views[0].W.x), float(views[0].W.y), float(views[0].W.z));
    gl.Uniform1f(gl.uniform(*depthProg, "uW0"), float(views[0].w0));
    buffers.bind(gl);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    gl.Disable(GL_CULL_FACE);  // depth of the first surface on the ray, whichever side faces the light
    gl.Disable(GL_BLEND);
    std::vector<double> gpuMs[2], cpuMs[2];
    bool timerWorks = gl.GetError() == GL_NO_ERROR;
    // One round more than asked, the first not counted: it compiles shaders and allocates,
    // and a device's first timer query can return garbage (llvmpipe's did: 3.4e6 ms).
    const int repeats = std::max(1, rq.timingRepeats) + 1;
    for (int rep = 0; rep < repeats; ++rep)
        for (int m = 0; m < 2; ++m) {
            const std::vector<uint8_t>& drawn = m == 0 ? inAll : inKept;
            ShadowPassTiming& timing = m == 0 ? report.all : report.kept;
            gl.Finish();
            const auto start = std::chrono::steady_clock::now();
            if (timerWorks) gl.BeginQuery(GL_TIME_ELAPSED, query);
            gl.BindFramebuffer(GL_FRAMEBUFFER, maps[size_t(m)].fbo);
            gl.Viewport(0, 0, cols * res, rows * res);
            const float far[4] = {1e30f, -1.0f, 0, 0};
            gl.ClearBufferfv(GL_COLOR, 0, far);
            gl.Clear(GL_DEPTH_BUFFER_BIT);
            timing = ShadowPassTiming{};
            std::vector<uint8_t> counted(ranges.size(), 0);
            for (size_t v = 0; v < views.size(); ++v) {
                gl.Viewport(int(v % 3) * res, int(v / 3) * res, res, res);
                const std::array<float, 16> clip = views[v].clipMatrix(nearZ, farZ, 1e-3 * (views[v].w1 - views[v].w0) + 1e-3);
                gl.UniformMatrix4fv(uClipD, 1, GL_FALSE, clip.data());
                for (size_t k = 0; k < ranges.size(); ++k) {
                    if (!drawn[k] || !inView[v][k]) continue;
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

    // Camera pass: every surface, shadowed against both maps at once.
    const double span = glm::length(w.lsBounds.max - w.lsBounds.min) + glm::length(target - eye);
    const double camNear = std::max(0.02, 1e-5 * span), camFar = 2 * span + 1;
    gl.BindFramebuffer(GL_FRAMEBUFFER, camTarget->fbo);
    const GLenum drawBuffers[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    gl.DrawBuffers(3, drawBuffers);
    gl.Viewport(0, 0, rq.width, rq.height);
    const float zero[4] = {0, 0, 0, 0};
    for (int a = 0; a < 3; ++a) gl.ClearBufferfv(GL_COLOR, a, zero);
    gl.Clear(GL_DEPTH_BUFFER_BIT);
    gl.UseProgram(*camProg);
    const GLuint p = *camProg;
    const std::array<float, 16> camClip = cameraClip(eye, target, rq.fovYDeg, double(rq.width) / rq.height, camNear, camFar);
    gl.UniformMatrix4fv(gl.uniform(p, "uClip"), 1, GL_FALSE, camClip.data());
    gl.Uniform1i(gl.uniform(p, "uType"), type);
    for (size_t v = 0; v < views.size(); ++v) {
        const std::string i = "[" + std::to_string(v) + "]";
        gl.Uniform3f(gl.uniform(p, ("uU" + i).c_str()), float(views[v].U.x), float(views[v].U.y), float(views[v].U.z));
        gl.Uniform3f(gl.uniform(p, ("uV" + i).c_str()), float(views[v].V.x), float(views[v].V.y), float(views[v].V.z));
        gl.Uniform3f(gl.uniform(p, ("uW" + i).c_str()), float(views[v].W.x), float(views[v].W.y), float(views[v].W.z));
        const GLint tile = gl.uniform(p, ("uTile" + i).c_str());
        const GLint xy[2] = {GLint(v % 3) * res, GLint(v / 3) * res};
        gl.Uniform2i(tile, xy[0], xy[1]);
    }
    const LightView& v0 = views[0];
    gl.Uniform4f(gl.uniform(p, "uRect"), float(v0.u0), float(v0.v0), float(v0.u1 - v0.u0), float(v0.v1 - v0.v0));
    gl.Uniform1f(gl.uniform(p, "uW0"), float(v0.w0));
    gl.Uniform1f(gl.uniform(p, "uT"), float(v0.t));
    gl.Uniform3f(gl.uniform(p, "uEye"), float(L.position.x), float(L.position.y), float(L.position.z));
    gl.Uniform3f(gl.uniform(p, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
    gl.Uniform1i(gl.uniform(p, "uRes"), res);
    gl.Uniform1i(gl.uniform(p, "uPcf"), report.pcfRadius);
    gl.Uniform1f(gl.uniform(p, "uBias"), float(L.bias));
    gl.Uniform1f(gl.uniform(p, "uSlopeBias"), float(L.slopeBias));
    gl.Uniform1f(gl.uniform(p, "uRange"), float(L.range));
    gl.Uniform1f(gl.uniform(p, "uCosCone"),
                 L.type == LightType::Spot ? float(std::cos(L.coneHalfAngleDeg * kPi / 180.0)) : -3.0f);
    gl.Uniform3f(gl.uniform(p, "uCamEye"), float(eye.x), float(eye.y), float(eye.z));
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, maps[0].colour[0]);
    gl.ActiveTexture(GL_TEXTURE1);
    gl.BindTexture(GL_TEXTURE_2D, maps[1].colour[0]);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.Uniform1i(gl.uniform(p, "uMapAll"), 0);
    gl.Uniform1i(gl.uniform(p, "uMapKept"), 1);
    const GLint uFlip = gl.uniform(p, "uFlip"), uTwoSided = gl.uniform(p, "uTwoSided"), uKind = gl.uniform(p, "uKind"),
                uReceiver = gl.uniform(p, "uReceiver");
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
    Frames fr;
    fr.width = rq.width, fr.height = rq.height;
    fr.pos = readRgba(gl, *camTarget, 0);
    fr.lit = readRgba(gl, *camTarget, 1);
    fr.diff = readRgba(gl, *camTarget, 2);
    const Status drawn = gl.check("rendering the shadow preview");
    cleanup();
    if (!drawn) return drawn.error();

    // Count, list, and compose the three panels.
    const int W = rq.width, H = rq.height;
    const double taps = double((2 * report.pcfRadius + 1) * (2 * report.pcfRadius + 1));
    RgbImage frameAll(W, H), frameKept(W, H), frameDiff(W, H);
    std::vector<std::array<int, 3>> marks;  // x, y, covered
    std::vector<DifferingPixel> notCovered;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = (size_t(H - 1 - y) * size_t(W) + size_t(x)) * 4;
            const float kind = fr.lit[i + 3], cosine = fr.lit[i + 2];
            if (kind == 0) {
                const Rgb sky{150, 180, 215}, dim{60, 68, 80};
                frameAll.set(x, y, sky), frameKept.set(x, y, sky), frameDiff.set(x, y, dim);
                continue;
            }
            const Rgb albedo = kind == 1 ? Rgb{125, 150, 95} : kind == 3 ? Rgb{215, 200, 175} : Rgb{175, 170, 160};
            auto shade = [&](float shadowed) {
                const double lit = cosine > 0 ? cosine * (1.0 - shadowed / taps) : 0.0;
                const double f = 0.28 + 0.72 * lit;
                return Rgb{uint8_t(albedo.r * f), uint8_t(albedo.g * f), uint8_t(albedo.b * f)};
            };
            const Rgb a = shade(fr.lit[i]), k = shade(fr.lit[i + 1]);
            frameAll.set(x, y, a), frameKept.set(x, y, k);
            const uint8_t grey = uint8_t((a.r + a.g + a.b) / 3 * 0.45);
            frameDiff.set(x, y, {grey, grey, grey});
            if (!(cosine >= 0)) continue;
            ++report.receiverPixels;
            const double footprint = fr.diff[i];
            const bool covered = L.filterRadius > 0 && footprint <= L.filterRadius;
            report.coveredPixels += covered;
            if (fr.lit[i] == fr.lit[i + 1]) continue;
            ++report.differingPixels;
            report.differingCovered += covered;
            frameDiff.set(x, y, covered ? Rgb{255, 40, 40} : Rgb{255, 170, 0});
            marks.push_back({x, y, covered});
            const bool listCovered = covered && report.listed.size() < rq.maxListed;
            if (listCovered || (!covered && notCovered.size() < rq.maxListed)) {
                DifferingPixel d;
                d.x = x, d.y = y;
                d.wsReceiver = glm::dvec3(fr.pos[i], fr.pos[i + 1], fr.pos[i + 2]) + w.wsOrigin;
                const size_t rk = size_t(fr.pos[i + 3]);
                if (rk >= 1 && rk <= ranges.size()) d.receiver = rangeLabel(rk - 1);
                const size_t ck = size_t(fr.diff[i + 1]);
                if (ck >= 1 && ck <= ranges.size()) {
                    d.caster = rangeLabel(ck - 1);
                    const int oi = verdictObject[ranges[ck - 1].object];
                    if (oi >= 0 && rq.light < cv.lightCount) {
                        const Decision& dec = cv.at(size_t(oi), int(ranges[ck - 1].group), rq.light);
                        d.casterProof = std::string(dec.stage) + ": " + std::string(dec.reason());
                    }
                }
                d.footprint = footprint;
                d.covered = covered;
                (covered ? report.listed : notCovered).push_back(d);
            }
        }
    for (DifferingPixel& d : notCovered)
        if (report.listed.size() < rq.maxListed) report.listed.push_back(d);
    // Isolated differing pixels would vanish at a glance: ring them (up to a few hundred).
    if (marks.size() <= 400)
        for (const auto& m : marks) frameDiff.strokeRect(m[0] - 5, m[1] - 5, 11, 11, m[2] ? Rgb{255, 40, 40} : Rgb{255, 170, 0});

    // The picture: title, three labelled panels, a legend.
    const int scale = W >= 480 ? 2 : 1, gap = 12, lineH = kLineHeight * scale;
    const Rgb text{235, 235, 235}, background{28, 28, 32};
    std::vector<std::string> title;
    title.push_back(chunkFileName(w.centre) + " - light " + std::to_string(rq.light + 1) + " '" + L.name + "' (" +
                    lightTypeName(L.type) + ") - shadow mapping as an engine does it, with every caster and with the kept ones");
    title.push_back("shadow map " + std::to_string(res) + " x " + std::to_string(res) +
                    (views.size() > 1 ? " x 6 faces" : "") + ", texel " + metres(report.texelSize) +
                    (directional ? "" : " at range") + "; PCF radius " + std::to_string(report.pcfRadius) +
                    (report.pcfDefaulted ? " (default)" : "") + ", footprint " + metres(report.worstFootprint) +
                    " vs filterRadius " + metres(L.filterRadius) + "; bias " + metres(L.bias) + ", slope bias " +
                    metres(L.slopeBias));
    title.push_back("camera " + vecText(report.wsEye) + " -> " + vecText(report.wsTarget) + "; " + report.device);
    auto passText = [&](const ShadowPassTiming& t) {
        return std::to_string(t.casters) + " casters, " + std::to_string(t.triangles) + " tris, " +
               std::to_string(t.drawCalls) + " draws, GPU " + msText(t.gpuMs);
    };
    const int top = gap + int(title.size()) * lineH + gap, labelH = 2 * lineH + 4;
    const int pw = 3 * W + 4 * gap, ph = top + labelH + H + gap + 3 * lineH + gap;
    RgbImage pic(pw, ph, background);
    for (size_t k = 0; k < title.size(); ++k)
        drawText(pic, gap, gap + int(k) * lineH, title[k], text, k == 0 ? scale : std::max(1, scale));
    const std::string heads[3] = {"all casters", "kept casters (bit 1)", "difference"};
    const std::string subs[3] = {passText(report.all), passText(report.kept),
                                 "differing pixels: " + std::to_string(report.differingPixels) + " of " +
                                     std::to_string(report.receiverPixels) + " lit surface pixels"};
    const RgbImage* panels[3] = {&frameAll, &frameKept, &frameDiff};
    for (int k = 0; k < 3; ++k) {
        const int x = gap + k * (W + gap);
        drawText(pic, x, top, heads[k], text, scale);
        drawText(pic, x, top + lineH + 2, subs[k], Rgb{200, 200, 200}, 1);
        pic.blit(*panels[k], x, top + labelH);
        pic.strokeRect(x - 1, top + labelH - 1, W + 2, H + 2, Rgb{90, 90, 100});
    }
    // Legend under the panels, from the left (it must fit small frames too).
    const int ly = top + labelH + H + gap, sw = 10 * scale;
    drawText(pic, gap, ly, std::to_string(report.culledCasters) + " casters culled by the masks for this light", text, 1);
    pic.fillRect(gap, ly + lineH, sw, 7 * scale, Rgb{255, 40, 40});
    drawText(pic, gap + sw + 4, ly + lineH,
             "differs where filterRadius covers the footprint: " + std::to_string(report.differingCovered) + " (a false cull)",
             text, 1);
    pic.fillRect(gap, ly + 2 * lineH, sw, 7 * scale, Rgb{255, 170, 0});
    drawText(pic, gap + sw + 4, ly + 2 * lineH,
             "differs at texel scale, footprint beyond filterRadius: " +
                 std::to_string(report.differingPixels - report.differingCovered),
             text, 1);
    report.pictureWidth = pw, report.pictureHeight = ph;
    if (Status s = writePng(pngPath, pic); !s) return s.error();
    return report;
}

}  // namespace shadowcull::gpu

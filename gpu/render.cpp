#include "gpu/render.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/format.h"
#include "core/png_write.h"
#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/render_picture.h"
#include "gpu/window_draw.h"

namespace shadowcull::gpu {

namespace {

const char* kRenderFs = R"(#version 430 core
in vec3 vPos;
uniform vec3 uColour;
uniform bool uPoint;
uniform bool uFlat;
uniform vec3 uLightPos;
uniform vec3 uLightDir;
layout(location = 0) out vec4 oColour;
void main() {
    vec3 n = normalize(cross(dFdx(vPos), dFdy(vPos)));
    vec3 l = uPoint ? normalize(vPos - uLightPos) : uLightDir;
    float shade = uFlat ? 1.0 : 0.35 + 0.65 * abs(dot(n, l));
    oColour = vec4(uColour * shade, 1.0);
}
)";

glm::vec3 toGl(Rgb c) { return {c.r / 255.0f, c.g / 255.0f, c.b / 255.0f}; }

// Two decimals: a title, not a record (the results JSON has the exact numbers).
std::string vecText(const glm::dvec3& v) {
    auto r = [](double x) { return formatNumber(std::round(x * 100) / 100 + 0.0); };
    return "(" + r(v.x) + ", " + r(v.y) + ", " + r(v.z) + ")";
}

std::string groups(uint64_t n) { return std::to_string(n) + (n == 1 ? " group" : " groups"); }

// What frames a directional view: the baked chunk's ground square and what stands on it,
// window-local. Content far above the ground (a balloon 1 km up) would shrink the chunk to
// a corner of the picture, so it is left out (and counted as outside the frame).
Aabb chunkFrameBox(const BakeWindow& w) {
    const double S = w.chunkSize;
    double groundLo = 1e300, groundHi = -1e300;
    for (const WindowObject& o : w.objects)
        if (o.centre && o.kind == ChunkObject::Kind::Terrain && !o.lsBounds.empty()) {
            groundLo = std::min(groundLo, o.lsBounds.min.y);
            groundHi = std::max(groundHi, o.lsBounds.max.y);
        }
    if (groundLo > groundHi) {  // no terrain: the lowest centre object stands for the ground
        for (const WindowObject& o : w.objects)
            if (o.centre && !o.lsBounds.empty()) groundLo = std::min(groundLo, o.lsBounds.min.y);
        if (groundLo > 1e299) groundLo = 0;
        groundHi = groundLo;
    }
    Aabb box;
    box.extend(glm::dvec3(0, groundLo, 0));
    box.extend(glm::dvec3(S, groundHi, S));
    for (const WindowObject& o : w.objects) {
        if (!o.centre || o.lsBounds.empty() || o.lsBounds.min.y > groundHi + S / 4) continue;
        Aabb b = o.lsBounds;
        b.max.y = std::min(b.max.y, groundHi + S / 2);
        b.min = glm::max(b.min, glm::dvec3(-S / 4, -1e300, -S / 4));
        b.max = glm::min(b.max, glm::dvec3(S * 1.25, 1e300, S * 1.25));
        box.extend(b);
    }
    return box;
}

// Narrows an orthographic view to `box` (square pixels, a small margin); depths unchanged,
// so occluders outside the frame still cast nothing wrong: the view is only cropped.
void frameOn(LightView& v, const Aabb& box) {
    double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
    for (int c = 0; c < 8; ++c) {
        const glm::dvec3 p((c & 1) ? box.max.x : box.min.x, (c & 2) ? box.max.y : box.min.y,
                           (c & 4) ? box.max.z : box.min.z);
        const double q[2] = {glm::dot(p, v.U), glm::dot(p, v.V)};
        for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], q[k]), hi[k] = std::max(hi[k], q[k]);
    }
    const double side = std::max(hi[0] - lo[0], hi[1] - lo[1]) * 1.04 + 1e-3;
    const double cu = (lo[0] + hi[0]) / 2, cv = (lo[1] + hi[1]) / 2;
    v.u0 = cu - side / 2, v.u1 = cu + side / 2, v.v0 = cv - side / 2, v.v1 = cv + side / 2;
}

bool overlapsFrame(const LightView& v, const Aabb& b) {
    if (b.empty()) return false;
    double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
    for (int c = 0; c < 8; ++c) {
        const glm::dvec3 p((c & 1) ? b.max.x : b.min.x, (c & 2) ? b.max.y : b.min.y, (c & 4) ? b.max.z : b.min.z);
        const double q[2] = {glm::dot(p, v.U), glm::dot(p, v.V)};
        for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], q[k]), hi[k] = std::max(hi[k], q[k]);
    }
    return hi[0] >= v.u0 && lo[0] <= v.u1 && hi[1] >= v.v0 && lo[1] <= v.v1;
}

std::vector<std::string> titleLines(const BakeWindow& w, const Light& L, int light, const RenderRequest& rq,
                                    const LightView* framed) {
    std::vector<std::string> t;
    t.push_back(chunkFileName(w.centre) + " - light " + std::to_string(light + 1) + " '" + L.name + "' (" +
                lightTypeName(L.type) + ") - coloured by " + rq.colouredBy);
    const glm::dvec3 pos = L.position + w.wsOrigin;
    if (L.type == LightType::Directional) {
        std::string s = "light travels along " + vecText(L.direction) + "; the view looks along it";
        if (framed)
            s += ", framed on the chunk (" + formatNumber(std::round(framed->u1 - framed->u0)) + " m across)";
        t.push_back(s);
    } else if (L.type == LightType::Spot) {
        t.push_back("light at " + vecText(pos) + " pointing " + vecText(L.direction) + ", cone " +
                    formatNumber(L.coneHalfAngleDeg) + " deg, range " + formatNumber(L.range) + " m");
    } else {
        t.push_back("light at " + vecText(pos) + ", range " + formatNumber(L.range) +
                    " m; the six faces of a cube around it, looking out");
    }
    return t;
}

}  // namespace

Expected<RenderReport> renderLightView(const BakeWindow& w, const ChunkVerdicts& cv, const RenderRequest& rq,
                                       const std::string& pngPath) {
    const int light = rq.light, resolution = rq.resolution;
    if (light < 0 || light >= int(w.lsLights.size()))
        return makeError(ErrorKind::BadInput, "", 0,
                         "no light " + std::to_string(light + 1) + " (the space has " +
                             std::to_string(w.lsLights.size()) + ")");
    if (resolution < 1 || resolution > 8192)
        return makeError(ErrorKind::BadInput, "", 0, "render resolution must be within 1..8192");
    const Light& L = w.lsLights[size_t(light)];
    RenderedViews rv;
    rv.views = lightViews(w, L, resolution);
    const bool framed = L.type == LightType::Directional && !rv.views.empty();
    if (framed) frameOn(rv.views[0], chunkFrameBox(w));
    rv.tile = resolution;
    rv.cols = rv.views.size() > 1 ? 3 : 1, rv.rows = rv.views.size() > 1 ? 2 : 1;
    const int width = rv.cols * resolution, height = rv.rows * resolution;

    Expected<std::unique_ptr<GlSession>> session = openGlSession();
    if (!session) return session.error();
    const GlApi& gl = (*session)->gl;
    Expected<GLuint> prog = gl.program(kWindowPositionVs, nullptr, kRenderFs);
    if (!prog) return prog.error();
    Expected<RenderTarget> target = makeRenderTarget(gl, width, height, {GL_RGBA8}, true);
    if (!target) return target.error();
    WindowTriangles tris(w);
    WindowBuffers buffers;
    if (Status s = buffers.upload(gl, w, tris); !s) return s.error();

    RenderReport report;
    report.gl = (*session)->context->report();
    // Colour of each (window object, group), and the legend's counts.
    std::vector<int> verdictObject(w.objects.size(), -1);
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].windowObject >= 0) verdictObject[size_t(cv.objects[oi].windowObject)] = int(oi);
    auto verdictOf = [&](size_t oi, int group) {
        if (group >= cv.objects[oi].groupCount || light >= cv.lightCount) return Verdict::Undecided;
        return cv.at(oi, group, light).verdict;
    };
    auto colourOf = [&](const GroupRange& r) -> Rgb {
        const int oi = verdictObject[r.object];
        if (!w.objects[r.object].centre || oi < 0) return kNeighbourColour;
        switch (verdictOf(size_t(oi), int(r.group))) {
            case Verdict::Culled: return kCulledColour;
            case Verdict::Kept: return kKeptColour;
            case Verdict::Undecided: break;
        }
        return kUndecidedColour;
    };
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        if (ov.windowObject < 0) continue;
        const std::vector<Aabb> boxes = groupBounds(w, tris, size_t(ov.windowObject));
        for (int g = 0; g < ov.groupCount; ++g) {
            const Verdict v = verdictOf(oi, g);
            ++(v == Verdict::Culled ? report.culled : v == Verdict::Kept ? report.kept : report.undecided);
            if (framed && size_t(g) < boxes.size() && !overlapsFrame(rv.views[0], boxes[size_t(g)])) ++report.outsideFrame;
        }
    }

    gl.BindFramebuffer(GL_FRAMEBUFFER, target->fbo);
    gl.Viewport(0, 0, width, height);
    gl.ClearDepth(1.0);
    gl.DepthFunc(GL_LESS);
    gl.Disable(GL_CULL_FACE);
    gl.UseProgram(*prog);
    gl.Uniform1i(gl.uniform(*prog, "uPoint"), L.type != LightType::Directional);
    gl.Uniform3f(gl.uniform(*prog, "uLightPos"), float(L.position.x), float(L.position.y), float(L.position.z));
    gl.Uniform3f(gl.uniform(*prog, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
    const GLint uClip = gl.uniform(*prog, "uClip"), uColour = gl.uniform(*prog, "uColour"), uFlat = gl.uniform(*prog, "uFlat");
    buffers.bind(gl);
    const double nearZ = std::max(1e-3, 1e-4 * L.range), farZ = L.range * 1.001 + nearZ;
    // Draws the ranges `want` accepts into every tile (+x -x +y on the top row, -y +z -z below).
    auto drawViews = [&](auto want, auto colour) {
        for (size_t v = 0; v < rv.views.size(); ++v) {
            const int col = int(v) % rv.cols, row = rv.rows - 1 - int(v) / rv.cols;
            gl.Viewport(col * resolution, row * resolution, resolution, resolution);
            const std::array<float, 16> clip =
                rv.views[v].clipMatrix(nearZ, farZ, 1e-3 * (rv.views[v].w1 - rv.views[v].w0) + 1e-3);
            gl.UniformMatrix4fv(uClip, 1, GL_FALSE, clip.data());
            for (const GroupRange& r : buffers.ranges()) {
                if (!want(r)) continue;
                const glm::vec3 c = toGl(colour(r));
                gl.Uniform3f(uColour, c.x, c.y, c.z);
                gl.DrawArrays(GL_TRIANGLES, r.first, r.count);
            }
        }
    };
    std::vector<unsigned char> rgba(size_t(width) * size_t(height) * 4);
    auto readBack = [&]() {
        gl.BindFramebuffer(GL_READ_FRAMEBUFFER, target->fbo);
        gl.ReadBuffer(GL_COLOR_ATTACHMENT0);
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        gl.ReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    };
    gl.ClearColor(0, 0, 0, 1);
    gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    gl.Enable(GL_DEPTH_TEST);
    gl.Uniform1i(uFlat, 0);
    drawViews([](const GroupRange&) { return true; }, colourOf);
    readBack();
    rv.image = RgbImage(width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const unsigned char* p = &rgba[(size_t(height - 1 - y) * size_t(width) + size_t(x)) * 4];
            rv.image.set(x, y, {p[0], p[1], p[2]});
        }
    // One mask per outlined group, drawn through everything (a group hidden inside a house
    // is still shown where it is), outlined and let go. Bounded: a picture with more
    // outlines reads no better.
    std::vector<uint8_t> mask(size_t(width) * size_t(height));
    gl.Disable(GL_DEPTH_TEST);
    gl.Uniform1i(uFlat, 1);
    for (size_t k = 0; k < rq.outlined.size() && k < 64; ++k) {
        // Plain copies: a lambda may not capture a structured binding in C++17 (clang refuses).
        const size_t oi = size_t(rq.outlined[k].first);
        const int group = int(rq.outlined[k].second);
        if (oi >= cv.objects.size() || cv.objects[oi].windowObject < 0) continue;
        const uint32_t object = uint32_t(cv.objects[oi].windowObject);
        gl.Clear(GL_COLOR_BUFFER_BIT);
        drawViews([&](const GroupRange& r) { return r.object == object && int(r.group) == group; },
                  [](const GroupRange&) { return Rgb{255, 255, 255}; });
        readBack();
        bool any = false;
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const bool covered = rgba[(size_t(height - 1 - y) * size_t(width) + size_t(x)) * 4] > 127;
                mask[size_t(y) * size_t(width) + size_t(x)] = covered;
                any |= covered;
            }
        if (any) addOutline(rv, mask);
        if (!any) {
            // Thinner than a pixel (a 5 mm rod in a 100 m view): ring where its box's centre falls.
            const std::vector<Aabb> boxes = groupBounds(w, tris, object);
            if (size_t(group) < boxes.size() && !boxes[size_t(group)].empty()) {
                const glm::dvec3 c = (boxes[size_t(group)].min + boxes[size_t(group)].max) * 0.5;
                for (size_t v = 0; v < rv.views.size(); ++v) {
                    const glm::dvec3 q = rv.views[v].toView(c);
                    if (rv.views[v].perspective && !(q.z > 0)) continue;
                    const glm::dvec2 px = rv.views[v].viewToPixel(q);
                    if (!(px.x >= 0 && px.y >= 0 && px.x < resolution && px.y < resolution)) continue;
                    const int col = int(v) % rv.cols, row = int(v) / rv.cols;
                    rv.points.push_back({col * resolution + int(px.x), row * resolution + resolution - 1 - int(px.y)});
                    any = true;
                }
            }
        }
        report.outlined += any;
    }
    gl.BindVertexArray(0);
    if (Status s = gl.check("rendering the light view"); !s) return s.error();
    buffers.destroy(gl);
    destroyRenderTarget(gl, *target);
    gl.DeleteProgram(*prog);

    const std::string chunk = chunkFileName(w.centre);
    std::vector<LegendEntry> legend = {
        {"culled (proved 0): " + groups(report.culled), true, kCulledColour},
        {"kept (proved 1, a witness): " + groups(report.kept), true, kKeptColour},
        {"undecided (written 1, no proof): " + groups(report.undecided), true, kUndecidedColour},
        {"neighbour chunks (occluders and receivers, not baked)", true, kNeighbourColour},
        {"nothing loaded there", true, Rgb{0, 0, 0}}};
    if (!rq.outlined.empty())
        legend.push_back({"outlined: " + groups(rq.outlined.size()) + " " + rq.outlineMeaning +
                              (report.outlined < rq.outlined.size()
                                   ? " (" + std::to_string(rq.outlined.size() - report.outlined) + " not in view)"
                                   : ""),
                          true, kOutlineColour});
    if (report.outsideFrame)
        legend.push_back({groups(report.outsideFrame) + " of " + chunk +
                              " outside the frame (far above the ground): counted above, not shown",
                          false, {}});
    const RgbImage picture = composePicture(rv, titleLines(w, L, light, rq, framed ? &rv.views[0] : nullptr), legend, report);
    if (Status s = writePng(pngPath, picture); !s) return s.error();
    return report;
}

}  // namespace shadowcull::gpu

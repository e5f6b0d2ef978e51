#include "gpu/render.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <glm/geometric.hpp>

#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/render_picture.h"
#include "gpu/window_draw.h"
#include "io/png_write.h"
#include "util/format.h"

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

// The colour of each (window object, group) for one light: its verdict's for the centre
// chunk's groups, the neighbours' colour for the rest.
class GroupColours {
public:
    GroupColours(const BakeWindow& w, const ChunkVerdicts& cv, int light)
        : w_(w), cv_(cv), light_(light), verdictObject_(w.objects.size(), -1) {
        for (size_t oi = 0; oi < cv.objects.size(); ++oi)
            if (cv.objects[oi].windowObject >= 0) verdictObject_[size_t(cv.objects[oi].windowObject)] = int(oi);
    }
    Verdict verdictOf(size_t oi, int group) const {
        if (group >= cv_.objects[oi].groupCount || light_ >= cv_.lightCount) return Verdict::Undecided;
        return cv_.at(oi, group, light_).verdict;
    }
    Rgb colourOf(const GroupRange& r) const {
        const int oi = verdictObject_[r.object];
        if (!w_.objects[r.object].centre || oi < 0) return kNeighbourColour;
        switch (verdictOf(size_t(oi), int(r.group))) {
            case Verdict::Culled: return kCulledColour;
            case Verdict::Kept: return kKeptColour;
            case Verdict::Undecided: break;
        }
        return kUndecidedColour;
    }

private:
    const BakeWindow& w_;
    const ChunkVerdicts& cv_;
    const int light_;
    std::vector<int> verdictObject_;  // per window object: index into ChunkVerdicts::objects, or -1
};

// The legend's counts: the centre chunk's groups by verdict, and those a framed view crops.
void countGroups(const BakeWindow& w, const ChunkVerdicts& cv, const WindowTriangles& tris, const GroupColours& colours,
                 const LightView* framed, RenderReport& report) {
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        if (ov.windowObject < 0) continue;
        const std::vector<Aabb> boxes = groupBounds(w, tris, size_t(ov.windowObject));
        for (int g = 0; g < ov.groupCount; ++g) {
            const Verdict v = colours.verdictOf(oi, g);
            ++(v == Verdict::Culled ? report.culled : v == Verdict::Kept ? report.kept : report.undecided);
            if (framed && size_t(g) < boxes.size() && !overlapsFrame(*framed, boxes[size_t(g)])) ++report.outsideFrame;
        }
    }
}

// Draws the window into the views' tiles of one render target and reads the tiles back.
class ViewPainter {
public:
    ViewPainter(const GlApi& gl, GLuint program, const RenderTarget& target, const WindowBuffers& buffers,
                RenderedViews& rv, int width, int height)
        : gl_(gl), prog_(program), target_(target), buffers_(buffers), rv_(rv), width_(width), height_(height),
          rgba_(size_t(width) * size_t(height) * 4) {}

    // The state and the light's uniforms every drawing shares.
    void setUp(const Light& L) {
        gl_.BindFramebuffer(GL_FRAMEBUFFER, target_.fbo);
        gl_.Viewport(0, 0, width_, height_);
        gl_.ClearDepth(1.0);
        gl_.DepthFunc(GL_LESS);
        gl_.Disable(GL_CULL_FACE);
        gl_.UseProgram(prog_);
        gl_.Uniform1i(gl_.uniform(prog_, "uPoint"), L.type != LightType::Directional);
        gl_.Uniform3f(gl_.uniform(prog_, "uLightPos"), float(L.position.x), float(L.position.y), float(L.position.z));
        gl_.Uniform3f(gl_.uniform(prog_, "uLightDir"), float(L.direction.x), float(L.direction.y), float(L.direction.z));
        uClip_ = gl_.uniform(prog_, "uClip"), uColour_ = gl_.uniform(prog_, "uColour"), uFlat_ = gl_.uniform(prog_, "uFlat");
        buffers_.bind(gl_);
        nearZ_ = std::max(1e-3, 1e-4 * L.range), farZ_ = L.range * 1.001 + nearZ_;
    }

    // Every group in its colour, shaded, nearest surface in front: the views image.
    void paintVerdicts(const GroupColours& colours) {
        gl_.ClearColor(0, 0, 0, 1);
        gl_.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        gl_.Enable(GL_DEPTH_TEST);
        gl_.Uniform1i(uFlat_, 0);
        drawViews([](const GroupRange&) { return true; }, [&](const GroupRange& r) { return colours.colourOf(r); });
        readBack();
        rv_.image = RgbImage(width_, height_);
        for (int y = 0; y < height_; ++y)
            for (int x = 0; x < width_; ++x) {
                const unsigned char* p = &rgba_[(size_t(height_ - 1 - y) * size_t(width_) + size_t(x)) * 4];
                rv_.image.set(x, y, {p[0], p[1], p[2]});
            }
    }

    // The outlines' masks are drawn through everything, flat.
    void beginOutlines() {
        gl_.Disable(GL_DEPTH_TEST);
        gl_.Uniform1i(uFlat_, 1);
    }

    // One group's mask, drawn through everything (a group hidden inside a house is still
    // shown where it is), outlined. False when the group is nowhere in the views.
    bool outline(const BakeWindow& w, const WindowTriangles& tris, uint32_t object, int group) {
        gl_.Clear(GL_COLOR_BUFFER_BIT);
        drawViews([&](const GroupRange& r) { return r.object == object && int(r.group) == group; },
                  [](const GroupRange&) { return Rgb{255, 255, 255}; });
        readBack();
        bool any = false;
        for (int y = 0; y < height_; ++y)
            for (int x = 0; x < width_; ++x) {
                const bool covered = rgba_[(size_t(height_ - 1 - y) * size_t(width_) + size_t(x)) * 4] > 127;
                mask_[size_t(y) * size_t(width_) + size_t(x)] = covered;
                any |= covered;
            }
        if (any) addOutline(rv_, mask_);
        if (!any) any = ringCentre(w, tris, object, group);
        return any;
    }

private:
    // Thinner than a pixel (a 5 mm rod in a 100 m view): ring where its box's centre falls.
    bool ringCentre(const BakeWindow& w, const WindowTriangles& tris, uint32_t object, int group) {
        bool any = false;
        const int resolution = rv_.tile;
        const std::vector<Aabb> boxes = groupBounds(w, tris, object);
        if (size_t(group) < boxes.size() && !boxes[size_t(group)].empty()) {
            const glm::dvec3 c = (boxes[size_t(group)].min + boxes[size_t(group)].max) * 0.5;
            for (size_t v = 0; v < rv_.views.size(); ++v) {
                const glm::dvec3 q = rv_.views[v].toView(c);
                if (rv_.views[v].perspective && !(q.z > 0)) continue;
                const glm::dvec2 px = rv_.views[v].viewToPixel(q);
                if (!(px.x >= 0 && px.y >= 0 && px.x < resolution && px.y < resolution)) continue;
                const int col = int(v) % rv_.cols, row = int(v) / rv_.cols;
                rv_.points.push_back({col * resolution + int(px.x), row * resolution + resolution - 1 - int(px.y)});
                any = true;
            }
        }
        return any;
    }

    // Draws the ranges `want` accepts into every tile (+x -x +y on the top row, -y +z -z below).
    template <class Want, class Colour>
    void drawViews(Want want, Colour colour) {
        const int resolution = rv_.tile;
        for (size_t v = 0; v < rv_.views.size(); ++v) {
            const int col = int(v) % rv_.cols, row = rv_.rows - 1 - int(v) / rv_.cols;
            gl_.Viewport(col * resolution, row * resolution, resolution, resolution);
            const std::array<float, 16> clip =
                rv_.views[v].clipMatrix(nearZ_, farZ_, 1e-3 * (rv_.views[v].w1 - rv_.views[v].w0) + 1e-3);
            gl_.UniformMatrix4fv(uClip_, 1, GL_FALSE, clip.data());
            for (const GroupRange& r : buffers_.ranges()) {
                if (!want(r)) continue;
                const glm::vec3 c = toGl(colour(r));
                gl_.Uniform3f(uColour_, c.x, c.y, c.z);
                gl_.DrawArrays(GL_TRIANGLES, r.first, r.count);
            }
        }
    }

    void readBack() {
        gl_.BindFramebuffer(GL_READ_FRAMEBUFFER, target_.fbo);
        gl_.ReadBuffer(GL_COLOR_ATTACHMENT0);
        gl_.PixelStorei(GL_PACK_ALIGNMENT, 1);
        gl_.ReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, rgba_.data());
    }

    const GlApi& gl_;
    const GLuint prog_;
    const RenderTarget& target_;
    const WindowBuffers& buffers_;
    RenderedViews& rv_;
    const int width_, height_;
    std::vector<unsigned char> rgba_;  // the last read back, bottom row first
    std::vector<uint8_t> mask_ = std::vector<uint8_t>(size_t(width_) * size_t(height_));
    GLint uClip_ = -1, uColour_ = -1, uFlat_ = -1;
    double nearZ_ = 0, farZ_ = 0;  // metres, the clip matrices' depth range
};

std::vector<LegendEntry> legendLines(const BakeWindow& w, const RenderRequest& rq, const RenderReport& report) {
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
    return legend;
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
    const GroupColours colours(w, cv, light);
    countGroups(w, cv, tris, colours, framed ? &rv.views[0] : nullptr, report);

    ViewPainter painter(gl, *prog, *target, buffers, rv, width, height);
    painter.setUp(L);
    painter.paintVerdicts(colours);
    painter.beginOutlines();
    // One outline per group asked for. Bounded: a picture with more outlines reads no better.
    for (size_t k = 0; k < rq.outlined.size() && k < 64; ++k) {
        const size_t oi = size_t(rq.outlined[k].first);
        const int group = int(rq.outlined[k].second);
        if (oi >= cv.objects.size() || cv.objects[oi].windowObject < 0) continue;
        report.outlined += painter.outline(w, tris, uint32_t(cv.objects[oi].windowObject), group);
    }
    gl.BindVertexArray(0);
    if (Status s = gl.check("rendering the light view"); !s) return s.error();
    buffers.destroy(gl);
    destroyRenderTarget(gl, *target);
    gl.DeleteProgram(*prog);

    const std::vector<LegendEntry> legend = legendLines(w, rq, report);
    const RgbImage picture = composePicture(rv, titleLines(w, L, light, rq, framed ? &rv.views[0] : nullptr), legend, report);
    if (Status s = writePng(pngPath, picture); !s) return s.error();
    return report;
}

}  // namespace shadowcull::gpu

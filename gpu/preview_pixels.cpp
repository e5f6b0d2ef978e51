// Judging `shadowcull preview`'s pixels and drawing its picture (see preview_pixels.h).
#include "gpu/preview_pixels.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "gpu/preview_witness.h"
#include "util/float_mode.h"

namespace shadowcull::gpu {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The difference panel's colours, one per class (and the legend's swatches).
constexpr Rgb kFalseCullColour{255, 40, 40}, kOwnSurfaceColour{80, 150, 255}, kBandColour{255, 170, 0};

Rgb classColour(PixelClass c) {
    switch (c) {
        case PixelClass::FalseCull: return kFalseCullColour;
        case PixelClass::OwnSurface: return kOwnSurfaceColour;
        case PixelClass::Band: return kBandColour;
    }
    return kBandColour;
}

// Index of frame pixel (x, y), row 0 at the top, in the bottom-up RGBA arrays.
size_t pixelIndex(const PreviewFrames& f, int x, int y) { return (size_t(f.height - 1 - y) * size_t(f.width) + size_t(x)) * 4; }

// The receiver's triangle under a differing pixel: its range and mesh triangle.
struct PixelSurface {
    size_t range = 0;
    uint32_t triangle = 0;
};

// The mesh triangle drawn as primitive `primitive` of range r (WindowBuffers::upload draws a
// range's triangles in the order of WindowTriangles::Object::triangles, filtered by group).
class RangeTriangles {
public:
    RangeTriangles(const BakeWindow& w, const WindowTriangles& tris, const std::vector<GroupRange>& ranges)
        : w_(w), tris_(tris), ranges_(ranges), lists_(ranges.size()) {}
    std::optional<uint32_t> triangle(size_t r, uint32_t primitive) {
        std::vector<uint32_t>& list = lists_[r];
        if (list.empty()) {
            const GroupRange& gr = ranges_[r];
            const Mesh& m = *w_.objects[gr.object].mesh;
            for (uint32_t t : tris_.object(gr.object).triangles)
                if (m.triangleGroup[t] == gr.group) list.push_back(t);
        }
        if (primitive >= list.size()) return std::nullopt;
        return list[primitive];
    }

private:
    const BakeWindow& w_;
    const WindowTriangles& tris_;
    const std::vector<GroupRange>& ranges_;
    std::vector<std::vector<uint32_t>> lists_;
};

// One differing pixel, with the exact test's inputs made ready.
struct Differing {
    int x = 0, y = 0;
    size_t index = 0;            // into the frames' arrays
    std::optional<PixelSurface> surface;
    bool covered = false;
    std::optional<RayWitness> witness;
};

// The receiver point q under pixel (x, y) of triangle `tri` of window object `object`,
// exactly on the triangle's plane (the camera ray through the pixel's centre, in double),
// its unit front normal, and the bias the spec gives there. Nothing when the ray is
// (nearly) parallel to the plane.
struct ExactReceiver {
    glm::dvec3 q, nFront;
    double beta;
};
std::optional<ExactReceiver> exactReceiver(const PreviewScene& s, const Light& L, uint32_t object, uint32_t tri, int x,
                                           int y, int width, int height) {
    const WindowObject& o = s.window.objects[object];
    const auto [a, b, c] = o.lsTriangle(tri);
    glm::dvec3 n = glm::cross(b - a, c - a);
    const double len = glm::length(n);
    if (!(len > 0)) return std::nullopt;
    n /= len;
    const glm::dvec3 ray = s.camera.rayThrough(x, y, width, height);
    const double den = glm::dot(n, ray);
    if (!(std::abs(den) > 1e-9)) return std::nullopt;
    const glm::dvec3 q = s.camera.eye + ray * (glm::dot(n, a - s.camera.eye) / den);
    const glm::dvec3 nFront = o.flipsWinding ? -n : n;
    const glm::dvec3 l = L.type == LightType::Directional ? L.direction : glm::normalize(q - L.position);
    const double cosine = std::abs(glm::dot(nFront, l));
    const double tanTheta = cosine > 1e-7 ? std::sqrt(std::max(0.0, 1 - cosine * cosine)) / cosine : 1e7;
    return ExactReceiver{q, nFront, L.bias + L.slopeBias * tanTheta};
}

std::string rangeLabel(const PreviewScene& s, size_t k) {
    const WindowObject& o = s.window.objects[s.ranges[k].object];
    const std::string& name = o.mesh->groups[s.ranges[k].group].name;
    return o.label + " group " + std::to_string(s.ranges[k].group) + (name.empty() ? "" : " (" + name + ")");
}

std::string proofOf(const PreviewScene& s, uint32_t object, uint32_t group) {
    const int oi = s.verdictObject[object];
    if (oi < 0 || s.light >= s.verdicts.lightCount) return std::string();
    const Decision& dec = s.verdicts.at(size_t(oi), int(group), s.light);
    return std::string(dec.stage) + ": " + std::string(dec.reason());
}

// The range of (object, group), or ranges.size() when none.
size_t rangeOf(const PreviewScene& s, uint32_t object, uint32_t group) {
    for (size_t k = 0; k < s.ranges.size(); ++k)
        if (s.ranges[k].object == object && s.ranges[k].group == group) return k;
    return s.ranges.size();
}

// Paints the frames' pixel (all, kept, dimmed difference) and collects the differing ones.
std::vector<Differing> paintAndCollect(const PreviewScene& s, const PreviewFrames& f, const Light& L,
                                       PreviewReport& report, PreviewPanels& panels) {
    std::vector<Differing> out;
    for (int y = 0; y < f.height; ++y)
        for (int x = 0; x < f.width; ++x) {
            const size_t i = pixelIndex(f, x, y);
            const float kind = f.lit[i + 3], cosine = f.lit[i + 2];
            if (kind == 0) {
                const Rgb sky{150, 180, 215}, dim{60, 68, 80};
                panels.all.set(x, y, sky), panels.kept.set(x, y, sky), panels.diff.set(x, y, dim);
                continue;
            }
            const Rgb albedo = kind == 1 ? Rgb{125, 150, 95} : kind == 3 ? Rgb{215, 200, 175} : Rgb{175, 170, 160};
            auto shade = [&](float shadowed) {
                const double lit = cosine > 0 ? cosine * (1.0 - shadowed / s.taps) : 0.0;
                const double k = 0.28 + 0.72 * lit;
                return Rgb{uint8_t(albedo.r * k), uint8_t(albedo.g * k), uint8_t(albedo.b * k)};
            };
            const Rgb a = shade(f.lit[i]), k = shade(f.lit[i + 1]);
            panels.all.set(x, y, a), panels.kept.set(x, y, k);
            const uint8_t grey = uint8_t((a.r + a.g + a.b) / 3 * 0.45);
            panels.diff.set(x, y, {grey, grey, grey});
            if (!(cosine >= 0)) continue;
            ++report.receiverPixels;
            const bool covered = L.filterRadius > 0 && f.diff[i] <= L.filterRadius;
            report.coveredPixels += covered;
            if (f.lit[i] == f.lit[i + 1]) continue;
            Differing d;
            d.x = x, d.y = y, d.index = i, d.covered = covered;
            const size_t rk = size_t(f.pos[i + 3]);
            if (rk >= 1 && rk <= s.ranges.size()) {
                uint32_t primitive;
                std::memcpy(&primitive, &f.diff[i + 3], sizeof primitive);  // intBitsToFloat in the shader
                d.surface = PixelSurface{rk - 1, primitive};
            }
            out.push_back(d);
        }
    return out;
}

// The exact light ray through each differing pixel's lookup point, in parallel.
void findWitnesses(const PreviewScene& s, const PreviewFrames& f, const Light& L, std::vector<Differing>& pixels) {
    std::vector<std::vector<uint8_t>> culled(s.window.objects.size());
    for (size_t k = 0; k < s.window.objects.size(); ++k) culled[k].assign(s.window.objects[k].mesh->groups.size(), 0);
    for (size_t r = 0; r < s.ranges.size(); ++r)
        if (s.culledRange[r]) culled[s.ranges[r].object][s.ranges[r].group] = 1;
    const ExactLightRays rays(s.window, L, std::move(culled));
    RangeTriangles rangeTriangles(s.window, s.triangles, s.ranges);
    // The triangle lists first (sequentially: they are made on first use), then the rays.
    std::vector<std::optional<uint32_t>> tri(pixels.size());
    for (size_t k = 0; k < pixels.size(); ++k)
        if (pixels[k].surface) tri[k] = rangeTriangles.triangle(pixels[k].surface->range, pixels[k].surface->triangle);
    tbb::parallel_for(size_t(0), pixels.size(), [&](size_t k) {
        const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);
        Differing& d = pixels[k];
        if (!d.surface || !tri[k]) return;
        const uint32_t object = s.ranges[d.surface->range].object;
        const std::optional<ExactReceiver> r = exactReceiver(s, L, object, *tri[k], d.x, d.y, f.width, f.height);
        if (r) d.witness = rays.culledCasterShadowing(object, r->q, r->nFront, r->beta);
    });
}

// Classifies, counts and lists the differing pixels; names the casters of the false culls.
void classify(const PreviewScene& s, const PreviewFrames& f, const PreviewRequest& rq, const std::vector<Differing>& pixels,
              PreviewReport& report, PreviewPanels& panels) {
    std::map<std::pair<uint32_t, uint32_t>, uint64_t> falseCullPixels;  // (object, group) -> pixels
    std::vector<DifferingPixel> others;
    for (const Differing& d : pixels) {
        ++report.differingPixels;
        report.differingCovered += d.covered;
        // The caster: the witness's, else the first differing texel's.
        std::optional<std::pair<uint32_t, uint32_t>> caster;
        if (d.witness) caster = std::pair{d.witness->object, d.witness->group};
        const size_t ck = size_t(f.diff[d.index + 1]);
        if (!caster && ck >= 1 && ck <= s.ranges.size()) caster = std::pair{s.ranges[ck - 1].object, s.ranges[ck - 1].group};
        // Its own surface: the caster shadows itself there (self-shadowing).
        const bool own = d.surface && caster && s.ranges[d.surface->range].object == caster->first &&
                         s.ranges[d.surface->range].group == caster->second;
        const bool falseCull = d.covered || d.witness.has_value();
        const PixelClass cls = falseCull ? PixelClass::FalseCull : own ? PixelClass::OwnSurface : PixelClass::Band;
        if (falseCull) (own ? report.falseCullsOnOwnSurfaces : report.differingOnKeptSurfaces) += 1;
        else (own ? report.differingOnOwnSurfaces : report.differingInBand) += 1;
        panels.diff.set(d.x, d.y, classColour(cls));
        panels.marks.push_back({d.x, d.y, int(cls)});
        if (falseCull && caster) ++falseCullPixels[*caster];
        std::vector<DifferingPixel>& list = falseCull ? report.listed : others;
        if (list.size() >= rq.maxListed) continue;
        DifferingPixel p;
        p.x = d.x, p.y = d.y;
        p.wsReceiver = glm::dvec3(f.pos[d.index], f.pos[d.index + 1], f.pos[d.index + 2]) + s.window.wsOrigin;
        if (d.surface) p.receiver = rangeLabel(s, d.surface->range);
        if (caster) {
            const size_t r = rangeOf(s, caster->first, caster->second);
            if (r < s.ranges.size()) p.caster = rangeLabel(s, r);
            p.casterProof = proofOf(s, caster->first, caster->second);
        }
        p.footprint = f.diff[d.index];
        p.covered = d.covered;
        p.cls = cls;
        p.exactWitness = d.witness.has_value();
        if (d.witness) p.wsP = d.witness->lsP + s.window.wsOrigin;
        list.push_back(p);
    }
    for (DifferingPixel& d : others)
        if (report.listed.size() < rq.maxListed) report.listed.push_back(d);
    for (const auto& [caster, n] : falseCullPixels) {
        const size_t r = rangeOf(s, caster.first, caster.second);
        report.falseCulls.push_back({r < s.ranges.size() ? rangeLabel(s, r) : s.window.objects[caster.first].label,
                                     proofOf(s, caster.first, caster.second), n});
    }
    std::stable_sort(report.falseCulls.begin(), report.falseCulls.end(),
                     [](const FalseCullCaster& a, const FalseCullCaster& b) { return a.pixels > b.pixels; });
}

std::string countText(uint64_t n) { return std::to_string(n); }

}  // namespace

const char* pixelClassName(PixelClass c) {
    switch (c) {
        case PixelClass::FalseCull: return "false cull";
        case PixelClass::OwnSurface: return "culled caster's own surface";
        case PixelClass::Band: return "texel-edge band";
    }
    return "?";
}

PreviewCamera::PreviewCamera(const glm::dvec3& e, const glm::dvec3& t, double fovYDeg, double aspect) : eye(e), target(t) {
    forward = glm::normalize(target - eye);
    glm::dvec3 worldUp(0, 1, 0);
    if (std::abs(glm::dot(forward, worldUp)) > 0.999) worldUp = glm::dvec3(0, 0, -1);
    side = glm::normalize(glm::cross(forward, worldUp));
    up = glm::cross(side, forward);
    tanHalfY = std::tan(fovYDeg * kPi / 360.0);
    tanHalfX = tanHalfY * aspect;
}

glm::dvec3 PreviewCamera::rayThrough(int x, int y, int width, int height) const {
    const double nx = (x + 0.5) / width * 2 - 1, ny = (height - 1 - y + 0.5) / height * 2 - 1;
    return glm::normalize(forward + side * (nx * tanHalfX) + up * (ny * tanHalfY));
}

PreviewPanels judgePixels(const PreviewScene& s, const PreviewFrames& f, const PreviewRequest& rq, PreviewReport& report) {
    const Light& L = s.window.lsLights[size_t(s.light)];
    PreviewPanels panels{RgbImage(f.width, f.height), RgbImage(f.width, f.height), RgbImage(f.width, f.height), {}};
    std::vector<Differing> pixels = paintAndCollect(s, f, L, report, panels);
    findWitnesses(s, f, L, pixels);
    classify(s, f, rq, pixels, report, panels);
    return panels;
}

RgbImage composePreviewPicture(const PreviewPanels& panels, const std::vector<std::string>& title,
                               const PreviewReport& report, int W, int H) {
    const int scale = W >= 480 ? 2 : 1, gap = 12, lineH = kLineHeight * scale;
    const Rgb text{235, 235, 235}, background{28, 28, 32};
    auto passText = [&](const ShadowPassTiming& t) {
        const std::string gpu = t.gpuMs < 0 ? "n/a" : [&] {
            char b[32];
            std::snprintf(b, sizeof b, "%.2f ms", t.gpuMs);
            return std::string(b);
        }();
        return std::to_string(t.casters) + " casters, " + std::to_string(t.triangles) + " tris, " +
               std::to_string(t.drawCalls) + " draws, GPU " + gpu;
    };
    const int legendLines = 5;
    const int top = gap + int(title.size()) * lineH + gap, labelH = 2 * lineH + 4;
    const int pw = 3 * W + 4 * gap, ph = top + labelH + H + gap + legendLines * lineH + gap;
    RgbImage pic(pw, ph, background);
    for (size_t k = 0; k < title.size(); ++k) drawText(pic, gap, gap + int(k) * lineH, title[k], text, scale);
    const std::string heads[3] = {"all casters", "kept casters (bit 1)", "difference"};
    const std::string subs[3] = {passText(report.all), passText(report.kept),
                                 "differing pixels: " + countText(report.differingPixels) + " of " +
                                     countText(report.receiverPixels) + " lit surface pixels"};
    const RgbImage* frames[3] = {&panels.all, &panels.kept, &panels.diff};
    for (int k = 0; k < 3; ++k) {
        const int x = gap + k * (W + gap);
        drawText(pic, x, top, heads[k], text, scale);
        drawText(pic, x, top + lineH + 2, subs[k], Rgb{200, 200, 200}, 1);
        pic.blit(*frames[k], x, top + labelH);
        pic.strokeRect(x - 1, top + labelH - 1, W + 2, H + 2, Rgb{90, 90, 100});
    }
    // Isolated differing pixels would vanish at a glance: ring them (up to a few hundred;
    // false culls always).
    const int x0 = gap + 2 * (W + gap), y0 = top + labelH;
    for (const auto& m : panels.marks)
        if (panels.marks.size() <= 400 || m[2] == int(PixelClass::FalseCull))
            pic.strokeRect(x0 + m[0] - 5, y0 + m[1] - 5, 11, 11, classColour(PixelClass(m[2])));
    // Legend under the panels, from the left (it must fit small frames too).
    const int ly = top + labelH + H + gap, sw = 10 * scale;
    drawText(pic, gap, ly, std::to_string(report.culledCasters) + " casters culled by the masks for this light", text, 1);
    const std::pair<PixelClass, std::string> rows[3] = {
        {PixelClass::FalseCull, "differing on kept surfaces: " + countText(report.differingOnKeptSurfaces) +
                                    ", self-shadows with a witness: " + countText(report.falseCullsOnOwnSurfaces) +
                                    " (a false cull: a shadow the engine draws is missing; must be 0)"},
        {PixelClass::OwnSurface, "on the culled caster's own surface: " + countText(report.differingOnOwnSurfaces) +
                                     " (its self-shadowing as the bias draws it: acne, no witness)"},
        {PixelClass::Band, "texel-edge band on kept surfaces: " + countText(report.differingInBand) +
                               " (a texel's centre ray meets a culled caster that the receiver's own ray does not)"}};
    for (int k = 0; k < 3; ++k) {
        pic.fillRect(gap, ly + (k + 1) * lineH, sw, 7 * scale, classColour(rows[k].first));
        drawText(pic, gap + sw + 4, ly + (k + 1) * lineH, rows[k].second, text, 1);
    }
    if (!report.falseCulls.empty())
        drawText(pic, gap, ly + 4 * lineH,
                 "false cull: " + report.falseCulls[0].caster + " (" + countText(report.falseCulls[0].pixels) + " px)" +
                     (report.falseCulls.size() > 1 ? " and " + std::to_string(report.falseCulls.size() - 1) + " more" : ""),
                 kFalseCullColour, 1);
    return pic;
}

}  // namespace shadowcull::gpu

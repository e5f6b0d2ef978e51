// One light of the conservative confirmation, up to the passes (confirm_light.h): the
// bits, the views, the casters' cells, the surfaces near them and each view's pieces.

#include "gpu/confirm_light.h"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <optional>

#include <tbb/parallel_for.h>

#include <glm/geometric.hpp>

#include "core/light_reach.h"
#include "util/float_mode.h"

namespace shadowcull::gpu {

GpuConfirmStage::LightRun::LightRun(GpuConfirmStage& stage, const BakeWindow& w, ChunkVerdicts& cv, int l,
                                    LightWork& work, StageStats& stats)
    : stage(stage),
      gpu(*stage.gl_),
      gl(stage.gl_->session->gl),
      w(w),
      cv(cv),
      l(l),
      L(w.lsLights[size_t(l)]),
      persp(L.type != LightType::Directional),
      res(stage.closeUp_ ? std::min(stage.options_.closeUpResolution, stage.options_.resolution)
                         : stage.options_.resolution),
      work(work),
      stats(stats) {}

bool GpuConfirmStage::LightRun::selectBits() {
    // The bits to examine: undecided (group, light l) of the centre chunk. Query id = index.
    queryOf.resize(w.objects.size());
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        if (ov.windowObject < 0) continue;
        if (ov.terrain && !stage.options_.includeTerrain) {
            // Said on the bit, so that a terrain left undecided is not read as a failed proof.
            for (int g = 0; g < ov.groupCount; ++g)
                addNote(cv.at(oi, g, l), stage.name(),
                        "not examined: terrains are left to the other stages (a continuous surface never passes this "
                        "stage's test; --gpu-terrain examines them)");
            continue;
        }
        for (int g = 0; g < ov.groupCount; ++g) {
            if (cv.at(oi, g, l).verdict != Verdict::Undecided) continue;
            auto& q = queryOf[size_t(ov.windowObject)];
            if (q.empty()) q.assign(size_t(ov.groupCount), -1);
            q[size_t(g)] = int(queries.size());
            GroupPixels gp;
            gp.object = oi;
            gp.group = g;
            gp.light = l;
            queries.push_back(gp);
        }
    }
    return !queries.empty();
}

bool GpuConfirmStage::LightRun::frameViews() {
    // A directional light's view frames what the window holds within one chunk of the centre
    // chunk's content (the original 3 x 3 window's), not the whole window: only the casters'
    // pixels are read, every ray through them is in the view (lightViews, lsFocus), and a
    // window many chunks long under a low sun does not spread the pixels. A close-up frames
    // the examined casters alone (runCloseUp).
    Aabb lsFrame{glm::max(w.lsBounds.min, w.lsCentreBounds.min - glm::dvec3(w.chunkSize, 0.0, w.chunkSize)),
                 glm::min(w.lsBounds.max, w.lsCentreBounds.max + glm::dvec3(w.chunkSize, 0.0, w.chunkSize))};
    if (stage.closeUp_) {
        lsFrame = Aabb{};
        for (size_t k = 0; k < queryOf.size(); ++k)
            if (!queryOf[k].empty()) lsFrame.extend(w.objects[k].lsBounds);
    }
    views = lightViews(w, L, res, lsFrame.empty() ? nullptr : &lsFrame);
    if (views.empty()) return false;
    if (persp && !findNearPlane()) return false;
    // With a filter radius in perspective, a normal bias (the lookup point moves off the
    // receiver, sideways and for two-sided receivers deeper: not drawn here), or skipped
    // objects, receivers are not bounded: only "never lit" can be proved.
    anyReceiver = w.skippedObjects > 0 || (persp && L.filterRadius > 0) || L.normalBias > 0;
    const double t = views[0].t;
    biasEff = persp ? L.bias / std::sqrt(1 + 2 * t * t) : L.bias;
    return true;
}

// Perspective: a near plane below all geometry, so clipping there loses nothing of the
// frustum. Points of the guard frustum (|x|,|y| <= 2tz) with z < near lie within
// near * sqrt(1 + 8t^2) of the light, less than half the nearest geometry's distance.
// False when geometry touches the light: no near plane is below it (the bits stay undecided).
bool GpuConfirmStage::LightRun::findNearPlane() {
    // The nearest triangle, through each mesh's tree: a node no nearer than the nearest
    // triangle so far holds none nearer (its box holds its triangles with room to spare).
    double dmin = 1e300;
    for (size_t k = 0; k < w.objects.size(); ++k) {
        if (distanceToBox(L.position, w.objects[k].lsBounds) >= dmin) continue;
        const WindowObject& o = w.objects[k];
        const auto& mt = o.mesh->triangles;
        work.treeOf(o.mesh).visit(
            [&](const Aabb& box) { return distanceToBox(L.position, placedBounds(box, o.lsTransform)) < dmin; },
            [&](uint32_t t) {
                dmin = std::min(dmin, pointTriangleDistance(L.position, position(uint32_t(k), mt[t][0]),
                                                            position(uint32_t(k), mt[t][1]), position(uint32_t(k), mt[t][2])));
            });
    }
    if (!(dmin > 1e-6 * (L.range + glm::length(L.position) + 1.0))) return false;
    const double g = 2 * views[0].t;
    nearZ = dmin / (2 * std::sqrt(1 + 2 * g * g));
    return true;
}

// Casters: every triangle of a group examined here, per view with the pixels (8 x 8
// cells) they reach. The query reads the other passes only at those pixels, so
// everything is drawn within their bounding rectangle (scissor), and pieces that cannot
// touch a cell the casters reach are dropped. Other pixels are never read.
// Point and spot lights: only the triangles with a point within range and cone (p lies
// there, semantics.md; exact, with the reach margins), found down the mesh's tree. A
// dense group the range sphere cuts is otherwise drawn whole, and its parts beyond
// range pass where no shadow can be.
void GpuConfirmStage::LightRun::findCasters() {
    const bool reachLimited = L.type != LightType::Directional;
    std::vector<uint32_t> inReach;
    for (size_t k = 0; k < w.objects.size(); ++k) {
        if (queryOf[k].empty()) continue;
        const WindowObject& o = w.objects[k];
        const Mesh& mesh = *o.mesh;
        const std::vector<uint32_t>* triangles = &work.treeOf(&mesh).triangles();
        if (reachLimited) {
            inReach.clear();
            work.treeOf(&mesh).visit([&](const Aabb& box) { return !boxOutOfReach(L, placedBounds(box, o.lsTransform)); },
                                     [&](uint32_t tr) {
                                         const auto& t = mesh.triangles[tr];
                                         Aabb tb;
                                         for (int c = 0; c < 3; ++c) tb.extend(position(uint32_t(k), t[c]));
                                         if (!boxOutOfReach(L, tb)) inReach.push_back(tr);
                                     });
            std::sort(inReach.begin(), inReach.end());
            triangles = &inReach;
        }
        for (uint32_t tr : *triangles) {
            const int id = queryOf[k][mesh.triangleGroup[tr]];
            if (id >= 0) casters.push_back({uint32_t(k), tr, uint32_t(id)});
        }
    }
}

void GpuConfirmStage::LightRun::maskViews() {
    preps.reserve(views.size());
    for (const LightView& view : views) maskView(view, preps.emplace_back(view, nearZ, stage.options_.collectViewStats));
}

// One view's casters: their pieces, the cells they reach and the rectangle around those.
void GpuConfirmStage::LightRun::maskView(const LightView& view, ViewPrep& vp) {
    // Absolute depth margin (metres): far above float rounding of the view's depths.
    const double depthScale = persp ? L.range + glm::length(w.lsBounds.max - w.lsBounds.min) +
                                          glm::length(L.position - 0.5 * (w.lsBounds.min + w.lsBounds.max))
                                    : (view.w1 - view.w0);
    vp.depthEps = 1e-6 * depthScale + 1e-6;
    if (!persp && L.filterRadius > 0)
        vp.dilatePx = float(L.filterRadius * std::max(view.width / (view.u1 - view.u0), view.height / (view.v1 - view.v0)));
    // A caster triangle in a tree node whose reach lies outside the view gives no
    // fragment there (a cube face of a point light sees a sixth of the casters).
    std::vector<char> inView;
    uint32_t flagged = UINT32_MAX;
    vp.casterPieces.reserve(casters.size());  // about one piece a triangle: no regrowth (dense groups)
    for (const Caster& c : casters) {
        const WindowObject& o = w.objects[c.object];
        if (c.object != flagged) {
            flagged = c.object;
            inView.assign(o.mesh->triangles.size(), 0);
            work.treeOf(o.mesh).visit(
                [&](const Aabb& box) {
                    const std::array<glm::dvec3, 8> corners = placedCorners(box, o.lsTransform);
                    if (vp.pb.clipsAway(corners.data(), 8)) return false;
                    const std::optional<PixelRect> r = hullReach(corners.data(), 8, vp.pb, 0.0f);
                    return !r || !r->isEmpty();
                },
                [&](uint32_t t) { inView[t] = 1; });
        }
        if (!inView[c.triangle]) continue;
        const auto& tri = o.mesh->triangles[c.triangle];
        vp.pb.triangle(position(c.object, tri[0]), position(c.object, tri[1]), position(c.object, tri[2]), 0.0f, c.id,
                       vp.casterPieces);
    }
    vp.roi = PixelRect{0, 0, view.width, view.height};
    if (!stage.options_.collectViewStats) {
        vp.skip = vp.casterPieces.empty();  // the bits' groups are not in this view
        vp.roi = PixelRect::empty();
        for (const RasterPiece& r : vp.casterPieces) {
            vp.roi.add(reachOf(r, view));
            vp.mask.mark(reachOf(r, view), double(r.plane2[1]), double(r.plane2[2]));
        }
    }
    vp.mask.finish();
}

// The triangles that can reach a caster cell in some view, per object: an object whose
// bounds reach none is left out whole, the others are walked down their mesh's tree
// (a node whose placed box reaches no caster cell holds no triangle whose pieces
// keepTouching would keep). So only what lies over the examined pixels is classified,
// and the pieces drawn are the same as from every triangle. Then their occluder sheets
// and receivers for this light (in parallel over objects; the order of sheets and
// receivers is the objects' order).
void GpuConfirmStage::LightRun::findSurfaces() {
    auto reachesCasters = [&](const std::array<glm::dvec3, 8>& corners) {
        return std::any_of(preps.begin(), preps.end(),
                           [&](const ViewPrep& vp) { return !vp.skip && !vp.misses(corners.data(), 8, vp.dilatePx); });
    };
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        if (o.mesh->triangles.empty() || o.lsBounds.empty() || !reachesCasters(o.lsBounds.corners())) continue;
        std::vector<uint32_t> selected;
        if (stage.options_.treeSelection)
            work.treeOf(o.mesh).visit([&](const Aabb& box) { return reachesCasters(placedCorners(box, o.lsTransform)); },
                                      [&](uint32_t t) { selected.push_back(t); });
        else
            selected = work.treeOf(o.mesh).triangles();
        if (selected.empty()) continue;
        std::sort(selected.begin(), selected.end());
        near.push_back(uint32_t(k));
        stage.trianglesClassified_ += selected.size();
        nearTriangles.push_back(std::move(selected));
        work.edgesOf(o.mesh);  // built here: read in parallel below
    }
    surfaces.resize(near.size());
    const SurfaceLight surfaceLight{&L, anyReceiver};
    tbb::parallel_for(size_t(0), near.size(), [&](size_t i) {
        const FloatModeScope taskMode(FloatModeScope::Underflow::Gradual);  // as run() (see there)
        surfaces[i] = objectSurfaces(w, near[i], surfaceLight, *work.edges.at(w.objects[near[i]].mesh), nearTriangles[i]);
    });
}

// Per object, in parallel: its occluder sheets, each with the pixel rectangle its
// fragments can reach, and its receivers' pieces.
std::vector<GpuConfirmStage::LightRun::ObjectPieces> GpuConfirmStage::LightRun::viewPieces(size_t vi) const {
    std::vector<ObjectPieces> pieces(near.size());
    tbb::parallel_for(size_t(0), near.size(), [&](size_t i) {
        const FloatModeScope taskMode(FloatModeScope::Underflow::Gradual);  // as run()
        objectPieces(i, preps[vi], views[vi], pieces[i]);
    });
    return pieces;
}

void GpuConfirmStage::LightRun::objectPieces(size_t i, const ViewPrep& vp, const LightView& view,
                                             ObjectPieces& out) const {
    const std::array<glm::dvec3, 8> corners = w.objects[near[i]].lsBounds.corners();
    if (vp.misses(corners.data(), 8, vp.dilatePx)) return;  // nothing of it reaches this view's casters
    for (const Sheet& s : surfaces[i].sheets) {
        SheetPieces p;
        if (sheetPieces(s, vp, view, p)) out.sheets.push_back(std::move(p));
    }
    for (const TriRef& tr : surfaces[i].receivers) {
        const auto& tri = w.objects[tr.object].mesh->triangles[tr.triangle];
        const glm::dvec3 &a = position(tr.object, tri[0]), &b = position(tr.object, tri[1]),
                         &c = position(tr.object, tri[2]);
        if (vp.missesTriangle(a, b, c, vp.dilatePx)) continue;
        const size_t before = out.receivers.size();
        vp.pb.triangle(a, b, c, vp.dilatePx, 0, out.receivers);
        keepTouching(out.receivers, before, vp.mask, view, !anyReceiver, biasEff, vp.depthEps);
    }
}

// A sheet's pieces (its triangles', then its cracks') that touch a caster cell, and their
// pixel rectangle within the view's. False: the sheet blocks no caster in this view.
bool GpuConfirmStage::LightRun::sheetPieces(const Sheet& s, const ViewPrep& vp, const LightView& view,
                                            SheetPieces& p) const {
    const CellMask& mask = vp.mask;
    p.pieces.reserve(s.triangles.size() + s.cracks.size());  // about one piece each: no regrowth
    for (const TriRef& tr : s.triangles) {
        const auto& tri = w.objects[tr.object].mesh->triangles[tr.triangle];
        const glm::dvec3 &a = position(tr.object, tri[0]), &b = position(tr.object, tri[1]),
                         &c = position(tr.object, tri[2]);
        if (vp.missesTriangle(a, b, c, 0.0f)) continue;
        vp.pb.triangle(a, b, c, 0.0f, 0, p.pieces);
    }
    keepTouching(p.pieces, 0, mask, view);
    if (p.pieces.empty()) return false;  // no triangle of the sheet reaches the casters
    if (stage.options_.dropSliverSheets && !holdsWholePixel(p.pieces)) return false;  // it blocks no pixel
    for (const TriRef& cr : s.cracks) {
        const auto& ends = work.edges.at(w.objects[cr.object].mesh)->ends[cr.triangle];
        vp.pb.segment(position(cr.object, ends[0]), position(cr.object, ends[1]), p.pieces);
    }
    keepTouching(p.pieces, 0, mask, view);
    p.rect = PixelRect::empty();
    for (const RasterPiece& r : p.pieces) p.rect.add(reachOf(r, view));
    p.rect = p.rect.intersect(vp.roi);
    if (p.rect.isEmpty()) return false;
    // A sheet wholly behind every caster it overlaps blocks none of them; leaving
    // an occluder out only ever admits more.
    double sheetNear = 1e300, casterFar, casterNear;
    for (const RasterPiece& r : p.pieces)
        if (r.misc[2] == 0.0f) sheetNear = std::min(sheetNear, double(r.plane2[1]));
    mask.depthRange(p.rect, casterNear, casterFar);
    if (sheetNear > casterFar + 1e-3 * (1 + std::abs(casterFar))) return false;
    // Likewise piece by piece, for sheets too large for one depth range.
    return !behindCasters(p.pieces, mask, view);
}

}  // namespace shadowcull::gpu

// Conservative GPU confirmation (see confirm_stage.h for what is proved and what is left).
//
// The idea is the original tool's: occlusion-query shadow caster culling (D. Bittner,
// O. Mattausch, A. Silvennoinen, M. Wimmer, "Shadow Caster Culling for Efficient Shadow
// Mapping", I3D 2011) - draw the receivers' depth and count, then query each caster. Here
// every per-pixel quantity is a bound instead of a sample, so that "no sample passed" is a
// proof. Conservative rasterisation (over-estimation by the half pixel diagonal: a quad
// per triangle and a separating-axis test per pixel; depth bounds from the triangle's
// plane over the pixel square)
// follows J. Hasselgren, T. Akenine-Moller, L. Ohlsson, "Conservative Rasterization",
// GPU Gems 2, ch. 42, 2005.
//
// Why a pass that counts zero samples proves the bit is 0. Take any ray from the light
// with a lit point p on group g and a receiver point q behind it (semantics.md); it runs
// through some pixel square S of some view (views of a light cover every ray that can
// reach a point within range and cone; pixel squares are closed, so a ray on a border
// belongs to both pixels and to both cube faces). Then at S:
//  1. g's fragment exists: S touches p's triangle, and the quad drawn for the triangle with
//     the fragment shader's separating-axis test admits every pixel whose square (widened
//     by a margin above float rounding) touches the triangle.
//  2. zlo(S) <= depth(p): zlo is the minimum over S of the triangle's depth plane (an
//     affine function of pixel position: the depth itself orthographically, 1/z in
//     perspective), clamped by the vertices' depth range, minus margins.
//  3. zlo(S) <= D_occ(S): an occluder sheet P is recorded at S only when (a) a point of S
//     lies robustly inside one of P's triangles and (b) none of P's "crack" edges
//     touches S. A crack edge is one not shared by exactly two of P's triangles running it
//     in opposite directions; P's triangles all face the same way, so across any other
//     edge they lie on both sides, and the boundary of P's projected union lies on crack
//     edges. S is connected and meets no boundary, so it lies wholly inside the union:
//     the ray meets P within S, at a depth at most the maximum over P's triangles touching
//     S of their farthest depth over S. That maximum (plus margins) is what P records, and
//     D_occ is the minimum over sheets. No opaque hit on the ray comes before p (p is lit;
//     ties do not block), so D_occ(S) >= depth(p) >= zlo(S). g's own triangles may be part
//     of a sheet: the same holds. Alpha-tested groups and objects that cast no shadow
//     (light passes them, semantics.md condition 1) are never part of a sheet.
//  4. R_max(S) > zlo(S) + bias': q's triangle is a receiver triangle (faces the light or is
//     two-sided, not wholly out of range, not wholly under the terrain), touches S and
//     has a farthest depth over S of at least depth(q) > depth(p) + bias. In perspective,
//     depth is axial z and along one ray z differences are the distance differences times
//     cos(angle to the axis) >= 1/sqrt(1 + 2 t^2), so bias' = bias / sqrt(1 + 2 t^2).
// Hence the fragment passes. Zero passed fragments in every view means no such ray.

#include "gpu/confirm_stage.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <numeric>
#include <optional>
#include <unordered_map>

#include <tbb/parallel_for.h>

#include <glm/geometric.hpp>

#include "core/float_mode.h"
#include "core/format.h"
#include "core/stop_request.h"
#include "core/light_reach.h"
#include "gpu/confirm_gl.h"
#include "gpu/confirm_surfaces.h"
#include "gpu/conservative.h"
#include "gpu/gl_api.h"
#include "gpu/light_view.h"
#include "gpu/selection_tree.h"
#include "gpu/pixel_cells.h"

namespace shadowcull::gpu {

namespace {

constexpr float kBig = 1e30f;

struct Caster {
    uint32_t object, triangle, id;
};

// One light view's set-up: the casters' pieces and the cells they reach.
struct ViewPrep {
    PieceBuilder pb;
    CellMask mask;
    std::vector<RasterPiece> casterPieces;
    PixelRect roi = PixelRect::empty();
    double depthEps = 0;  // metres, the shader's absolute depth margin
    float dilatePx = 0;   // receivers' dilation (directional light with a filter radius)
    bool skip = false;    // no caster in this view
    ViewPrep(const LightView& view, double nearZ, bool all) : pb(view, nearZ), mask(view.width, view.height, all) {}
    // No piece made from anything within the hull of pts can reach a caster cell (so
    // keepTouching would drop them all).
    bool misses(const glm::dvec3* pts, size_t n, float dilate) const {
        if (pb.clipsAway(pts, n)) return true;
        const std::optional<PixelRect> r = hullReach(pts, n, pb, dilate);
        return r && !mask.touches(*r);
    }
};

// An occluder sheet's pieces in one view, with the pixel rectangle its fragments can reach.
struct SheetPieces {
    std::vector<RasterPiece> pieces;
    PixelRect rect;
};

// One object's pieces in one view.
struct ObjectPieces {
    std::vector<SheetPieces> sheets;
    std::vector<RasterPiece> receivers;
};

}  // namespace

// Per run: the stage's trees and edges per mesh.
struct GpuConfirmStage::LightWork {
    std::unordered_map<const Mesh*, std::unique_ptr<SelectionTree>>& trees;
    std::unordered_map<const Mesh*, std::unique_ptr<MeshEdges>>& edges;
    const SelectionTree& treeOf(const Mesh* mesh) {
        auto& t = trees[mesh];
        if (!t) t = std::make_unique<SelectionTree>(*mesh);
        return *t;
    }
    const MeshEdges& edgesOf(const Mesh* mesh) {
        auto& e = edges[mesh];
        if (!e) e = std::make_unique<MeshEdges>(*mesh, treeOf(mesh).triangles());
        return *e;
    }
};

GpuConfirmStage::GpuConfirmStage(GpuConfirmOptions options) : options_(options) {}
GpuConfirmStage::~GpuConfirmStage() = default;  // destroying the context frees its objects

void GpuConfirmStage::forgetMeshes(const std::unordered_set<const Mesh*>& meshes) {
    for (const Mesh* m : meshes) edges_.erase(m), trees_.erase(m);
}

std::string GpuConfirmStage::glDescription() const { return gl_ ? gl_->session->context->report() : std::string(); }

Status GpuConfirmStage::run(const BakeWindow& w, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    groups_.clear();
    viewStats_.clear();
    trianglesClassified_ = 0;
    // Lights with an undecided bit this stage looks at.
    std::vector<bool> lights(size_t(cv.lightCount), false);
    for (const ObjectVerdicts& ov : cv.objects) {
        if (ov.terrain && !options_.includeTerrain) continue;
        for (size_t k = 0; k < ov.decisions.size(); ++k)
            if (ov.decisions[k].verdict == Verdict::Undecided) lights[k % size_t(cv.lightCount)] = true;
    }
    if (closeUp_)  // a close-up frames directional views only (local lights' views are fixed)
        for (size_t l = 0; l < lights.size(); ++l) lights[l] = lights[l] && w.lsLights[l].type == LightType::Directional;
    if (std::none_of(lights.begin(), lights.end(), [](bool b) { return b; })) return Status::ok();
    // The pieces are computed on this thread and on TBB's workers, which Embree's builds
    // leave with flush-to-zero and denormals-are-zero: one mode everywhere, so that the GL
    // input does not depend on which thread made which piece (nor on the thread count).
    const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);
    if (Status s = ensureGl(); !s) return s;
    GpuTimer gpuTime(gl_->session->gl);
    // The window slid: keep the edges of the meshes still loaded, drop the others (the
    // terrains of the chunks left behind), so that memory follows the window, not the world.
    const std::unordered_set<const Mesh*> loaded = w.meshes();
    for (auto it = edges_.begin(); it != edges_.end();) it = loaded.count(it->first) ? std::next(it) : edges_.erase(it);
    for (auto it = trees_.begin(); it != trees_.end();) it = loaded.count(it->first) ? std::next(it) : trees_.erase(it);
    LightWork work{trees_, edges_};
    for (int l = 0; l < cv.lightCount; ++l) {
        if (!lights[size_t(l)]) continue;
        const size_t first = groups_.size();
        if (Status s = runLight(w, cv, l, work, stats); !s) return s;
        for (size_t k = first; k < groups_.size(); ++k) {
            ++stats.bitsExamined;
            if (cv.at(groups_[k].object, groups_[k].group, l).stage == name()) ++stats.provedCulled;
        }
    }
    gpuTime.addTo(stats);
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

Status GpuConfirmStage::runCloseUp(const BakeWindow& w, ChunkVerdicts& cv, StageStats& stats) {
    closeUp_ = true;
    const Status s = run(w, cv, stats);
    closeUp_ = false;
    return s;
}

Status GpuConfirmStage::runLight(const BakeWindow& w, ChunkVerdicts& cv, int l, LightWork& work, StageStats& stats) {
    const Light& L = w.lsLights[size_t(l)];
    const bool persp = L.type != LightType::Directional;
    const int res = closeUp_ ? std::min(options_.closeUpResolution, options_.resolution) : options_.resolution;

    // The bits to examine: undecided (group, light l) of the centre chunk. Query id = index.
    std::vector<std::vector<int>> queryOf(w.objects.size());
    std::vector<GroupPixels> queries;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        if (ov.windowObject < 0) continue;
        if (ov.terrain && !options_.includeTerrain) {
            // Said on the bit, so that a terrain left undecided is not read as a failed proof.
            for (int g = 0; g < ov.groupCount; ++g)
                addNote(cv.at(oi, g, l), name(),
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
    if (queries.empty()) return Status::ok();

    // A directional light's view frames what the window holds within one chunk of the centre
    // chunk's content (the original 3 x 3 window's), not the whole window: only the casters'
    // pixels are read, every ray through them is in the view (lightViews, lsFocus), and a
    // window many chunks long under a low sun does not spread the pixels. A close-up frames
    // the examined casters alone (runCloseUp).
    Aabb lsFrame{glm::max(w.lsBounds.min, w.lsCentreBounds.min - glm::dvec3(w.chunkSize, 0.0, w.chunkSize)),
                 glm::min(w.lsBounds.max, w.lsCentreBounds.max + glm::dvec3(w.chunkSize, 0.0, w.chunkSize))};
    if (closeUp_) {
        lsFrame = Aabb{};
        for (size_t k = 0; k < queryOf.size(); ++k)
            if (!queryOf[k].empty()) lsFrame.extend(w.objects[k].lsBounds);
    }
    const std::vector<LightView> views = lightViews(w, L, res, lsFrame.empty() ? nullptr : &lsFrame);
    if (views.empty()) return Status::ok();
    // Perspective: a near plane below all geometry, so clipping there loses nothing of the
    // frustum. Points of the guard frustum (|x|,|y| <= 2tz) with z < near lie within
    // near * sqrt(1 + 8t^2) of the light, less than half the nearest geometry's distance.
    // Window-local vertices, computed where they are needed (the same bits as
    // WindowTriangles): the stage looks at few of a dense neighbour's triangles.
    auto position = [&](uint32_t object, uint32_t vertex) {
        const WindowObject& o = w.objects[object];
        return o.lsTransform.apply(o.mesh->positions[vertex]);
    };
    double nearZ = 0;
    if (persp) {
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
        // Geometry touching the light: no near plane is below it. Leave the bits undecided.
        if (!(dmin > 1e-6 * (L.range + glm::length(L.position) + 1.0))) return Status::ok();
        const double g = 2 * views[0].t;
        nearZ = dmin / (2 * std::sqrt(1 + 2 * g * g));
    }
    // With a filter radius in perspective, a normal bias (the lookup point moves off the
    // receiver, sideways and for two-sided receivers deeper: not drawn here), or skipped
    // objects, receivers are not bounded: only "never lit" can be proved.
    const bool anyReceiver = w.skippedObjects > 0 || (persp && L.filterRadius > 0) || L.normalBias > 0;
    const double t = views[0].t;
    const double biasEff = persp ? L.bias / std::sqrt(1 + 2 * t * t) : L.bias;


    // Casters: every triangle of a group examined here, per view with the pixels (8 x 8
    // cells) they reach. The query reads the other passes only at those pixels, so
    // everything is drawn within their bounding rectangle (scissor), and pieces that cannot
    // touch a cell the casters reach are dropped. Other pixels are never read.
    // Point and spot lights: only the triangles with a point within range and cone (p lies
    // there, semantics.md; exact, with the reach margins), found down the mesh's tree. A
    // dense group the range sphere cuts is otherwise drawn whole, and its parts beyond
    // range pass where no shadow can be.
    const bool reachLimited = L.type != LightType::Directional;
    std::vector<Caster> casters;  // by object, then by triangle
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
    std::vector<ViewPrep> preps;
    preps.reserve(views.size());
    std::vector<char> inView;
    for (const LightView& view : views) {
        ViewPrep& vp = preps.emplace_back(view, nearZ, options_.collectViewStats);
        // Absolute depth margin (metres): far above float rounding of the view's depths.
        const double depthScale = persp ? L.range + glm::length(w.lsBounds.max - w.lsBounds.min) +
                                              glm::length(L.position - 0.5 * (w.lsBounds.min + w.lsBounds.max))
                                        : (view.w1 - view.w0);
        vp.depthEps = 1e-6 * depthScale + 1e-6;
        if (!persp && L.filterRadius > 0)
            vp.dilatePx = float(L.filterRadius *
                                std::max(view.width / (view.u1 - view.u0), view.height / (view.v1 - view.v0)));
        // A caster triangle in a tree node whose reach lies outside the view gives no
        // fragment there (a cube face of a point light sees a sixth of the casters).
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
            vp.pb.triangle(position(c.object, tri[0]), position(c.object, tri[1]), position(c.object, tri[2]), 0.0f,
                           c.id, vp.casterPieces);
        }
        vp.roi = PixelRect{0, 0, view.width, view.height};
        if (!options_.collectViewStats) {
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
    // and the pieces drawn are the same as from every triangle.
    auto reachesCasters = [&](const std::array<glm::dvec3, 8>& corners) {
        return std::any_of(preps.begin(), preps.end(),
                           [&](const ViewPrep& vp) { return !vp.skip && !vp.misses(corners.data(), 8, vp.dilatePx); });
    };
    std::vector<uint32_t> near;
    std::vector<std::vector<uint32_t>> nearTriangles;  // per near object, ascending
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        if (o.mesh->triangles.empty() || o.lsBounds.empty() || !reachesCasters(o.lsBounds.corners())) continue;
        std::vector<uint32_t> selected;
        if (options_.treeSelection)
            work.treeOf(o.mesh).visit([&](const Aabb& box) { return reachesCasters(placedCorners(box, o.lsTransform)); },
                                      [&](uint32_t t) { selected.push_back(t); });
        else
            selected = work.treeOf(o.mesh).triangles();
        if (selected.empty()) continue;
        std::sort(selected.begin(), selected.end());
        near.push_back(uint32_t(k));
        trianglesClassified_ += selected.size();
        nearTriangles.push_back(std::move(selected));
        work.edgesOf(o.mesh);  // built here: read in parallel below
    }

    // Their occluder sheets and receivers for this light (in parallel over objects; the
    // order of sheets and receivers is the objects' order).
    std::vector<ObjectSurfaces> surfaces(near.size());
    const SurfaceLight surfaceLight{&L, anyReceiver};
    tbb::parallel_for(size_t(0), near.size(), [&](size_t i) {
        const FloatModeScope taskMode(FloatModeScope::Underflow::Gradual);  // as run() (see there)
        surfaces[i] = objectSurfaces(w, near[i], surfaceLight, *work.edges.at(w.objects[near[i]].mesh), nearTriangles[i]);
    });

    // Storage for the query results, accumulated over the views.
    const GlApi& gl = gl_->session->gl;
    const size_t Q = queries.size();
    // Pixels kept per group: as asked, within the storage block limit (the counts are
    // exact whatever the cap).
    const uint64_t fit = uint64_t(std::min<GLint64>(gl_->maxStorageBlock, GLint64(256) << 20)) / (16 * uint64_t(Q));
    const uint32_t cap = uint32_t(std::max<uint64_t>(1, std::min<uint64_t>(uint64_t(std::max(1, options_.maxPixelsPerGroup)), fit)));
    if (uint64_t(Q) * 2 * 4 > uint64_t(gl_->maxStorageBlock) || fit == 0)
        return makeError(ErrorKind::Internal, "", 0,
                         "too many undecided groups (" + std::to_string(Q) + ") for one GPU storage block");
    {
        std::vector<uint32_t> zeros(2 * Q, 0);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[0]);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(zeros.size() * 4), zeros.data(), GL_DYNAMIC_COPY);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[1]);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(Q * cap * 16), nullptr, GL_DYNAMIC_COPY);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    }
    // Which passed pixels are recorded (Slots in kConfirmRasterFs). The shader's atomics hand out
    // record slots in the order the rasteriser's threads run the fragments, so when a
    // query's fragments do not all fit, "the first ones" would differ from run to run (and
    // with them the dense witness search and the results JSON). Instead, per view, every
    // passed pixel is recorded while they fit in the query's free records; when they do
    // not, the records are written again for the pixels whose hash is under a threshold,
    // lowered until they fit: a set that depends on the pixels alone.
    struct Slot {
        uint32_t threshold, base, room, offered;
    };
    static_assert(sizeof(Slot) == 16, "one uvec4 per query");
    constexpr uint32_t kAllPixels = 0xffffffffu;
    std::vector<Slot> slots(Q);
    std::vector<uint32_t> recordsWritten(Q, 0);  // per query, over the views so far
    auto uploadSlots = [&] {
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[2]);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(Q * sizeof(Slot)), slots.data(), GL_DYNAMIC_COPY);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    };
    // After a caster pass: the queries whose offered pixels fit are done for this view;
    // the others get a lower threshold. False when every query is done.
    auto settleSlots = [&] {
        gl.MemoryBarrier(GL_ALL_BARRIER_BITS);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[2]);
        gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(Q * sizeof(Slot)), slots.data());
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
        bool again = false;
        for (size_t q = 0; q < Q; ++q) {
            Slot& sl = slots[q];
            if (sl.offered <= sl.room) {
                recordsWritten[q] += sl.offered;
                sl = {0, recordsWritten[q], 0, 0};  // nothing more in this view
            } else {
                // Aim at three quarters of the room (a pixel's fragments come and go
                // together); the threshold strictly falls, so this ends.
                const uint64_t span = sl.threshold == kAllPixels ? (uint64_t(1) << 32) : uint64_t(sl.threshold);
                sl.threshold = uint32_t(span * 3 * sl.room / (4 * uint64_t(sl.offered)));
                sl.offered = 0;
                again = true;
            }
        }
        return again;
    };

    for (size_t vi = 0; vi < views.size(); ++vi) {
        // A point light's six views take seconds on a large window: a signal stops between them.
        if (Status s = stopStatus(); !s) return s;
        const LightView& view = views[vi];
        const ViewPrep& vp = preps[vi];
        if (vp.skip) continue;
        const PieceBuilder& pb = vp.pb;
        const CellMask& mask = vp.mask;
        const PixelRect& roi = vp.roi;
        const double depthEps = vp.depthEps;
        const float dilatePx = vp.dilatePx;
        auto misses = [&](const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, float dilate) {
            const glm::dvec3 pts[3] = {a, b, c};
            return vp.misses(pts, 3, dilate);
        };
        // Per object, in parallel: its occluder sheets, each with the pixel rectangle its
        // fragments can reach, and its receivers' pieces.
        std::vector<ObjectPieces> pieces(near.size());
        tbb::parallel_for(size_t(0), near.size(), [&](size_t i) {
            const FloatModeScope taskMode(FloatModeScope::Underflow::Gradual);  // as run()
            ObjectPieces& out = pieces[i];
            const std::array<glm::dvec3, 8> corners = w.objects[near[i]].lsBounds.corners();
            if (vp.misses(corners.data(), 8, dilatePx)) return;  // nothing of it reaches this view's casters
            for (const Sheet& s : surfaces[i].sheets) {
                SheetPieces p;
                p.pieces.reserve(s.triangles.size() + s.cracks.size());  // about one piece each: no regrowth
                for (const TriRef& tr : s.triangles) {
                    const auto& tri = w.objects[tr.object].mesh->triangles[tr.triangle];
                    const glm::dvec3 &a = position(tr.object, tri[0]), &b = position(tr.object, tri[1]),
                                     &c = position(tr.object, tri[2]);
                    if (misses(a, b, c, 0.0f)) continue;
                    pb.triangle(a, b, c, 0.0f, 0, p.pieces);
                }
                keepTouching(p.pieces, 0, mask, view);
                if (p.pieces.empty()) continue;  // no triangle of the sheet reaches the casters
                if (options_.dropSliverSheets && !holdsWholePixel(p.pieces)) continue;  // it blocks no pixel
                for (const TriRef& cr : s.cracks) {
                    const auto& ends = work.edges.at(w.objects[cr.object].mesh)->ends[cr.triangle];
                    pb.segment(position(cr.object, ends[0]), position(cr.object, ends[1]), p.pieces);
                }
                keepTouching(p.pieces, 0, mask, view);
                p.rect = PixelRect::empty();
                for (const RasterPiece& r : p.pieces) p.rect.add(reachOf(r, view));
                p.rect = p.rect.intersect(roi);
                if (p.rect.isEmpty()) continue;
                // A sheet wholly behind every caster it overlaps blocks none of them; leaving
                // an occluder out only ever admits more.
                double sheetNear = 1e300, casterFar, casterNear;
                for (const RasterPiece& r : p.pieces)
                    if (r.misc[2] == 0.0f) sheetNear = std::min(sheetNear, double(r.plane2[1]));
                mask.depthRange(p.rect, casterNear, casterFar);
                if (sheetNear > casterFar + 1e-3 * (1 + std::abs(casterFar))) continue;
                // Likewise piece by piece, for sheets too large for one depth range.
                if (behindCasters(p.pieces, mask, view)) continue;
                out.sheets.push_back(std::move(p));
            }
            for (const TriRef& tr : surfaces[i].receivers) {
                const auto& tri = w.objects[tr.object].mesh->triangles[tr.triangle];
                const glm::dvec3 &a = position(tr.object, tri[0]), &b = position(tr.object, tri[1]),
                                 &c = position(tr.object, tri[2]);
                if (misses(a, b, c, dilatePx)) continue;
                const size_t before = out.receivers.size();
                pb.triangle(a, b, c, dilatePx, 0, out.receivers);
                keepTouching(out.receivers, before, mask, view, !anyReceiver, biasEff, depthEps);
            }
        });
        std::vector<SheetPieces> sp;
        for (ObjectPieces& op : pieces)
            for (SheetPieces& s : op.sheets) sp.push_back(std::move(s));
        // Batches: sheets whose rectangles are disjoint cannot touch the same pixel, so
        // they share one work pass and one resolve.
        std::vector<std::vector<size_t>> batches;
        for (size_t s = 0; s < sp.size(); ++s) {
            bool placed = false;
            for (auto& b : batches) {
                bool clash = false;
                for (size_t o : b)
                    if (sp[o].rect.overlaps(sp[s].rect)) {
                        clash = true;
                        break;
                    }
                if (!clash) {
                    b.push_back(s);
                    placed = true;
                    break;
                }
            }
            if (!placed) batches.push_back({s});
        }
        // One allocation, kept from view to view: growing by doubling copied millions of
        // 148-byte pieces per view on windows of dense meshes (and faulted in each new block).
        std::vector<RasterPiece>& all = gl_->all;
        all.clear();
        {
            size_t total = vp.casterPieces.size();
            for (const SheetPieces& s : sp) total += s.pieces.size();
            for (const ObjectPieces& op : pieces) total += op.receivers.size();
            all.reserve(total);
        }
        std::vector<std::pair<GLint, GLsizei>> batchRange, batchRects;  // pieces; rectangle vertices
        std::vector<float> rects;
        for (const auto& b : batches) {
            const GLint first = GLint(all.size()), firstRect = GLint(rects.size() / 2);
            for (size_t s : b) {
                all.insert(all.end(), sp[s].pieces.begin(), sp[s].pieces.end());
                const PixelRect& r = sp[s].rect;
                const float x0 = float(r.x0), y0 = float(r.y0), x1 = float(r.x1), y1 = float(r.y1);
                rects.insert(rects.end(), {x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1});
            }
            batchRange.push_back({first, GLsizei(all.size()) - first});
            batchRects.push_back({firstRect, GLsizei(rects.size() / 2) - firstRect});
        }
        const GLint recvFirst = GLint(all.size());
        for (const ObjectPieces& op : pieces) all.insert(all.end(), op.receivers.begin(), op.receivers.end());
        const GLint castFirst = GLint(all.size());
        all.insert(all.end(), vp.casterPieces.begin(), vp.casterPieces.end());
        const GLint end = GLint(all.size());

        // Upload and draw.
        // The buffer holds the view's pieces and, after them, room for the caster pieces drawn
        // again (those that passed).
        gl.BindBuffer(GL_ARRAY_BUFFER, gl_->vbo);
        const size_t needed = all.size() + vp.casterPieces.size();
        if (needed > gl_->vboPieces) {
            gl_->vboPieces = needed + needed / 4;
            gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(gl_->vboPieces * sizeof(RasterPiece)), nullptr, GL_STREAM_DRAW);
        }
        gl.BufferSubData(GL_ARRAY_BUFFER, 0, GLsizeiptr(all.size() * sizeof(RasterPiece)), all.data());
        gl.BindBuffer(GL_ARRAY_BUFFER, gl_->rectVbo);
        gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(rects.size() * sizeof(float)), rects.data(), GL_STREAM_DRAW);
        for (GLuint p : {gl_->resolve, gl_->clear}) {
            gl.UseProgram(p);
            gl.Uniform2f(gl.uniform(p, "uSize"), float(view.width), float(view.height));
        }
        const GLuint prog = gl_->raster;
        gl.UseProgram(prog);
        gl.Uniform2f(gl.uniform(prog, "uSize"), float(view.width), float(view.height));
        gl.Uniform1f(gl.uniform(prog, "uSizeMax"), float(std::max(view.width, view.height)));
        gl.Uniform1i(gl.uniform(prog, "uPerspective"), persp ? 1 : 0);
        gl.Uniform1f(gl.uniform(prog, "uDepthEps"), float(depthEps));
        gl.Uniform1f(gl.uniform(prog, "uBias"), float(biasEff));
        gl.Uniform1i(gl.uniform(prog, "uAnyReceiver"), anyReceiver ? 1 : 0);
        gl.Uniform1ui(gl.uniform(prog, "uRecordCap"), cap);
        gl.Uniform1ui(gl.uniform(prog, "uView"), uint32_t(vi));
        const GLint uMode = gl.uniform(prog, "uMode");
        auto drawPieces = [&](GLint first, GLsizei count) {
            if (count > 0) gl.DrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, count, GLuint(first));
        };
        gl.Viewport(0, 0, view.width, view.height);
        gl.Enable(GL_SCISSOR_TEST);
        gl.Scissor(roi.x0, roi.y0, roi.x1 - roi.x0, roi.y1 - roi.y0);
        gl.Disable(GL_DEPTH_TEST);
        gl.Disable(GL_STENCIL_TEST);
        gl.Disable(GL_CULL_FACE);
        gl.Enable(GL_BLEND);
        gl.BlendFunc(GL_ONE, GL_ONE);

        // 1. Occluders: D_occ = min over sheets of the sheet's bound, where it is valid.
        // Per batch: draw its sheets into the work buffer (max), resolve their rectangles
        // into D_occ (min), and reset those rectangles for the next batch.
        gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->occ.fbo);
        const float far[4] = {kBig, 0, 0, 0};
        gl.ClearBufferfv(GL_COLOR, 0, far);
        gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->work.fbo);
        const float none[4] = {-kBig, 0, 0, 0};
        gl.ClearBufferfv(GL_COLOR, 0, none);
        for (size_t b = 0; b < batchRange.size(); ++b) {
            gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->work.fbo);
            gl.Enable(GL_BLEND);
            gl.BlendEquation(GL_MAX);
            gl.UseProgram(prog);
            gl.Uniform1i(uMode, 0);
            gl.BindVertexArray(gl_->vao);
            drawPieces(batchRange[b].first, batchRange[b].second);
            gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->occ.fbo);
            gl.BlendEquation(GL_MIN);
            gl.UseProgram(gl_->resolve);
            gl.ActiveTexture(GL_TEXTURE0);
            gl.BindTexture(GL_TEXTURE_2D, gl_->work.colour[0]);
            gl.BindVertexArray(gl_->rectVao);
            gl.DrawArrays(GL_TRIANGLES, batchRects[b].first, batchRects[b].second);
            gl.BindTexture(GL_TEXTURE_2D, 0);
            if (b + 1 < batchRange.size()) {
                gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->work.fbo);
                gl.Disable(GL_BLEND);
                gl.UseProgram(gl_->clear);
                gl.DrawArrays(GL_TRIANGLES, batchRects[b].first, batchRects[b].second);
            }
        }
        gl.Enable(GL_BLEND);
        // 2. Receivers: R_max = max over receiver triangles of their farthest depth.
        gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->recv.fbo);
        const float nothing[4] = {-kBig, 0, 0, 0};
        gl.ClearBufferfv(GL_COLOR, 0, nothing);
        gl.BlendEquation(GL_MAX);
        gl.UseProgram(prog);
        gl.Uniform1i(uMode, 1);
        gl.BindVertexArray(gl_->vao);
        drawPieces(recvFirst, castFirst - recvFirst);
        // 3. Casters: count lit fragments and those with a receiver behind, and record the
        // pixels that passed (see Slot above).
        for (size_t q = 0; q < Q; ++q)
            slots[q] = {recordsWritten[q] < cap ? kAllPixels : 0u, recordsWritten[q], cap - recordsWritten[q], 0};
        uploadSlots();
        gl.Disable(GL_BLEND);
        gl.BlendEquation(GL_FUNC_ADD);
        gl.BindFramebuffer(GL_FRAMEBUFFER, gl_->work.fbo);
        gl.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        gl.Uniform1i(uMode, 2);
        gl.ActiveTexture(GL_TEXTURE0);
        gl.BindTexture(GL_TEXTURE_2D, gl_->occ.colour[0]);
        gl.ActiveTexture(GL_TEXTURE1);
        gl.BindTexture(GL_TEXTURE_2D, gl_->recv.colour[0]);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, gl_->ssbo[0]);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, gl_->ssbo[1]);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, gl_->ssbo[2]);
        {
            const std::vector<uint32_t> zeros(size_t(end - castFirst), 0u);
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[3]);
            gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(std::max<size_t>(1, zeros.size()) * 4),
                          zeros.empty() ? nullptr : zeros.data(), GL_DYNAMIC_COPY);
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
        }
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, gl_->ssbo[3]);
        drawPieces(castFirst, end - castFirst);
        gl.Uniform1i(uMode, 3);  // again if needed: records only, the counts are complete
        GLsizei again = -1;      // caster pieces that passed, copied after the view's pieces
        while (settleSlots()) {
            if (again < 0) {
                // Only a piece with a fragment that passed can record one: the same
                // fragments, the same tests (mode 3 reads what mode 2 read).
                std::vector<uint32_t> passed(size_t(end - castFirst));
                gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[3]);
                gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(passed.size() * 4), passed.data());
                gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
                std::vector<RasterPiece> redraw;
                for (size_t i = 0; i < passed.size(); ++i)
                    if (passed[i]) redraw.push_back(all[size_t(castFirst) + i]);
                gl.BindBuffer(GL_ARRAY_BUFFER, gl_->vbo);
                gl.BufferSubData(GL_ARRAY_BUFFER, GLintptr(size_t(end) * sizeof(RasterPiece)),
                                 GLsizeiptr(redraw.size() * sizeof(RasterPiece)), redraw.data());
                again = GLsizei(redraw.size());
            }
            uploadSlots();
            drawPieces(end, again);
            ++stats.gpuPasses;
        }
        gl.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        gl.Disable(GL_SCISSOR_TEST);
        gl.MemoryBarrier(GL_ALL_BARRIER_BITS);
        gl.ActiveTexture(GL_TEXTURE1);
        gl.BindTexture(GL_TEXTURE_2D, 0);
        gl.ActiveTexture(GL_TEXTURE0);
        gl.BindTexture(GL_TEXTURE_2D, 0);
        gl.BindVertexArray(0);
        gl.UseProgram(0);
        gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
        if (Status s = gl.check("the confirmation passes"); !s) return s;
        stats.gpuPasses += batches.size() + 2;  // occluder batches (each drawn and resolved), receivers, casters

        if (options_.collectViewStats) {
            ConfirmViewStats vs;
            vs.light = l;
            vs.view = int(vi);
            vs.occluderSheets = int(sp.size());
            vs.batches = int(batches.size());
            for (float v : readFloatPixels(gl, gl_->occ, 0, 1, 0)) vs.occluderPixels += v < 1e29f;
            for (float v : readFloatPixels(gl, gl_->recv, 0, 1, 0)) vs.receiverPixels += v > -1e29f;
            viewStats_.push_back(vs);
        }
    }

    // Read the counts and the pixels that passed.
    std::vector<uint32_t> counts(2 * Q);
    std::vector<uint32_t> records(Q * cap * 4);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[0]);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(counts.size() * 4), counts.data());
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, gl_->ssbo[1]);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(records.size() * 4), records.data());
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    if (Status s = gl.check("reading the confirmation results"); !s) return s;

    const std::string at = std::to_string(res) + " px" + (views.size() > 1 ? " per view, " + std::to_string(views.size()) + " views" : "") +
                           (closeUp_ ? " framed on the casters" : "");
    for (size_t q = 0; q < Q; ++q) {
        GroupPixels& gp = queries[q];
        gp.litSamples = counts[2 * q];
        gp.passedSamples = counts[2 * q + 1];
        const uint32_t n = recordsWritten[q];
        std::map<std::tuple<int, int, int>, float> nearest;  // (view, px, py) -> nearest depth
        for (uint32_t k = 0; k < n; ++k) {
            const uint32_t* r = &records[(q * cap + k) * 4];
            float z;
            std::memcpy(&z, &r[2], 4);
            auto key = std::make_tuple(int(r[3]), int(r[0]), int(r[1]));
            auto it = nearest.find(key);
            if (it == nearest.end() || z < it->second) nearest[key] = z;
        }
        for (const auto& [key, z] : nearest) {
            const auto [v, px, py] = key;
            if (v < 0 || size_t(v) >= views.size()) continue;
            const LightView& view = views[size_t(v)];
            PassedPixel p;
            p.view = v, p.px = px, p.py = py;
            const double cx = px + 0.5, cy = py + 0.5, depth = std::max(double(z), view.perspective ? nearZ : -1e300);
            p.lsPoint = view.pointAt(cx, cy, depth);
            p.lsDirection = view.rayDirection(cx, cy);
            p.footprint = view.pixelSize(depth);
            gp.pixels.push_back(p);
        }
        if (gp.passedSamples == 0) {
            Decision& d = cv.at(gp.object, gp.group, l);
            if (gp.litSamples == 0)
                decide(d, Verdict::Culled, name(),
                       "never lit: wherever the group is, an opaque sheet covering the whole pixel lies nearer the "
                       "light (conservative rasterisation, " + at + ")");
            else
                decide(d, Verdict::Culled, name(),
                       "nothing behind: no receiver deeper than the bias behind any pixel where the group may be lit "
                       "(conservative rasterisation, " + at + ")");
        }
        if (gp.passedSamples > 0) {
            // Left undecided: say what passed and where (the raycast stage then searches there).
            std::string seen = std::to_string(gp.passedSamples) + " of " + std::to_string(gp.litSamples) +
                               " samples where the group may be lit had a receiver possibly more than the bias behind (" +
                               at + ")";
            if (!gp.pixels.empty()) {
                const PassedPixel& p = gp.pixels.front();
                const glm::dvec3 ws = p.lsPoint + w.wsOrigin;
                seen += "; e.g. view " + std::to_string(p.view) + " pixel (" + std::to_string(p.px) + ", " +
                        std::to_string(p.py) + "): the light's ray through (" + formatNumber(ws.x) + " " + formatNumber(ws.y) +
                        " " + formatNumber(ws.z) + ") along (" + formatNumber(p.lsDirection.x) + " " +
                        formatNumber(p.lsDirection.y) + " " + formatNumber(p.lsDirection.z) + "), " +
                        std::to_string(gp.pixels.size()) + " such pixels kept";
            }
            addNote(cv.at(gp.object, gp.group, l), name(), std::move(seen));
        }
        groups_.push_back(std::move(gp));
    }
    return Status::ok();
}

}  // namespace shadowcull::gpu

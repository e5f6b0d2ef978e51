// Occluder sheets and receivers of one object for one light (see confirm_surfaces.h).
#include "gpu/confirm_surfaces.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/geometric.hpp>

#include "core/light_reach.h"
#include "gpu/conservative.h"

namespace shadowcull::gpu {

namespace {

// One object's triangles for one light, classified when first asked: +1 counter-clockwise
// on screen, -1 clockwise, 0 in no sheet; and its edges, whether they join a sheet.
class TriangleClasses {
public:
    static constexpr int8_t kUnknown = 2;  // not classified yet

    TriangleClasses(const BakeWindow& w, uint32_t k, const SurfaceLight& sl, const MeshEdges& edges)
        : w_(w), sl_(sl), L_(*sl.light), persp_(L_.type != LightType::Directional), W_(glm::normalize(L_.direction)),
          o_(w.objects[k]), mesh_(*o_.mesh), edges_(edges),
          terrainRule_(w.hasTerrain && o_.kind != ChunkObject::Kind::Terrain),
          cls_(mesh_.triangles.size(), kUnknown), good_(edges.count(), 0xff) {}

    // Classifies triangle tr; with `receiver`, also says whether it may receive.
    void classify(uint32_t tr, bool* receiver) {
        const auto& tri = mesh_.triangles[tr];
        const glm::dvec3 a = position(tri[0]), b = position(tri[1]), c = position(tri[2]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        const glm::dvec3 rd = persp_ ? a - L_.position : W_;
        // The facing sign is certain beyond this: the cross product's rounding is relative
        // to |b-a||c-a|, not to |n| (which is small for slivers).
        const double f = glm::dot(n, rd), tol = 1e-9 * glm::length(b - a) * glm::length(c - a) * glm::length(rd);
        const PrimitiveGroup& pg = mesh_.groups[mesh_.triangleGroup[tr]];
        // Screen orientation: U x V = -W, so a triangle is counter-clockwise exactly when its
        // geometric normal points against the light's travel. Triangles of one class have
        // one orientation; edge-on ones are in no sheet.
        // Surfaces that let light pass (alpha-tested groups, objects that cast no shadow)
        // are in no sheet: they block nothing.
        cls_[tr] = o_.blocksLight(mesh_.triangleGroup[tr]) && std::abs(f) > tol ? (f < 0 ? 1 : -1) : 0;
        if (!receiver) return;
        *receiver = false;
        if (sl_.anyReceiver) return;
        const double front = o_.flipsWinding ? -f : f;
        if (!pg.twoSided() && front > tol) return;  // certainly facing away
        Aabb tb;
        tb.extend(a), tb.extend(b), tb.extend(c);
        bool excluded = persp_ && distanceToBox(L_.position, tb) > L_.range * (1 + 1e-6) + 1e-6;
        if (!excluded && terrainRule_) {
            const std::optional<double> h = w_.lsTerrainMinOver(tb.min.x, tb.min.z, tb.max.x, tb.max.z);
            excluded = h && tb.max.y < *h - w_.terrainTolerance - 1e-6 * (std::abs(*h) + 1.0);
        }
        *receiver = !excluded;
    }

    // The class so far (kUnknown when never asked).
    int8_t known(uint32_t tr) const { return cls_[tr]; }

    int8_t classOf(uint32_t tr) {
        if (cls_[tr] == kUnknown) classify(tr, nullptr);
        return cls_[tr];
    }

    // Edges that join a sheet: per class, exactly two of its triangles use the edge, in
    // opposite directions. Bit 0: class +1, bit 1: class -1.
    uint8_t joins(uint32_t e) {
        if (good_[e] != 0xff) return good_[e];
        uint8_t g = 0;
        for (int c = 0; c < 2; ++c) {
            const int8_t want = c == 0 ? 1 : -1;
            int count = 0;
            bool f1 = false, f2 = false;
            for (uint32_t u = edges_.start[e]; u < edges_.start[e + 1]; ++u) {
                const MeshEdges::Use& use = edges_.uses[u];
                if (classOf(use.triangle) != want) continue;
                (count == 0 ? f1 : f2) = use.forward;
                ++count;
            }
            if (count == 2 && f1 != f2) g |= uint8_t(1u << c);
        }
        return good_[e] = g;
    }

private:
    // Window-local vertices as WindowTriangles computes them (the same bits), on demand.
    glm::dvec3 position(uint32_t v) const { return o_.lsTransform.apply(mesh_.positions[v]); }

    const BakeWindow& w_;
    const SurfaceLight& sl_;
    const Light& L_;
    const bool persp_;
    const glm::dvec3 W_;  // unit, the way a directional light travels
    const WindowObject& o_;
    const Mesh& mesh_;
    const MeshEdges& edges_;
    const bool terrainRule_;  // receivers wholly under the terrain are excluded
    std::vector<int8_t> cls_;  // per mesh triangle
    std::vector<uint8_t> good_;  // per edge, joins(); 0xff until asked
};

// Sheets: walk each selected triangle's component (the whole of it) across joining edges,
// then list its selected triangles and their cracks, in the order a pass over the whole
// mesh gives.
void walkSheets(TriangleClasses& tc, const MeshEdges& edges, uint32_t k, size_t triangleCount,
                const std::vector<uint32_t>& selected, std::vector<Sheet>& sheets) {
    constexpr uint32_t kNone = UINT32_MAX;
    std::vector<uint32_t> sheetOf(triangleCount, kNone);
    std::vector<char> isSelected(triangleCount, 0);
    for (uint32_t tr : selected) isSelected[tr] = 1;
    std::vector<uint32_t> stack;
    for (uint32_t start : selected) {
        const int8_t want = tc.known(start);
        if (want == 0 || sheetOf[start] != kNone) continue;
        const uint32_t id = uint32_t(sheets.size());
        Sheet& s = sheets.emplace_back();
        s.firstTriangle = start;
        const uint8_t bit = uint8_t(want > 0 ? 1 : 2);
        sheetOf[start] = id;
        stack.assign(1, start);
        while (!stack.empty()) {
            const uint32_t tr = stack.back();
            stack.pop_back();
            s.firstTriangle = std::min(s.firstTriangle, tr);
            for (int kk = 0; kk < 3; ++kk) {
                const uint32_t e = edges.edgeOf[3 * size_t(tr) + size_t(kk)];
                if (!(tc.joins(e) & bit)) {
                    if (isSelected[tr]) s.cracks.push_back({k, e});
                    continue;
                }
                for (uint32_t u = edges.start[e]; u < edges.start[e + 1]; ++u) {
                    const uint32_t other = edges.uses[u].triangle;
                    if (other == tr || tc.known(other) != want || sheetOf[other] != kNone) continue;
                    sheetOf[other] = id;
                    stack.push_back(other);
                }
            }
        }
    }
    for (uint32_t tr : selected)
        if (sheetOf[tr] != kNone) sheets[sheetOf[tr]].triangles.push_back({k, tr});
    for (Sheet& s : sheets) {
        auto byEdge = [](const TriRef& a, const TriRef& b) { return a.triangle < b.triangle; };
        std::sort(s.cracks.begin(), s.cracks.end(), byEdge);
        s.cracks.erase(std::unique(s.cracks.begin(), s.cracks.end(),
                                   [](const TriRef& a, const TriRef& b) { return a.triangle == b.triangle; }),
                       s.cracks.end());
    }
    // The order a pass over the whole mesh gives: by each component's first triangle.
    std::stable_sort(sheets.begin(), sheets.end(),
                     [](const Sheet& a, const Sheet& b) { return a.firstTriangle < b.firstTriangle; });
}

}  // namespace

ObjectSurfaces objectSurfaces(const BakeWindow& w, uint32_t k, const SurfaceLight& sl, const MeshEdges& edges,
                              const std::vector<uint32_t>& selected) {
    ObjectSurfaces out;
    TriangleClasses tc(w, k, sl, edges);
    for (uint32_t tr : selected) {
        bool receiver = false;
        tc.classify(tr, &receiver);
        if (receiver) out.receivers.push_back({k, tr});
    }
    walkSheets(tc, edges, k, w.objects[k].mesh->triangles.size(), selected, out.sheets);
    return out;
}

}  // namespace shadowcull::gpu

// Occluder sheets and receivers of one object for one light (see confirm_surfaces.h).
#include "gpu/confirm_surfaces.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/light_reach.h"
#include "gpu/conservative.h"

namespace shadowcull::gpu {

ObjectSurfaces objectSurfaces(const BakeWindow& w, uint32_t k, const SurfaceLight& sl, const MeshEdges& edges,
                              const std::vector<uint32_t>& selected) {
    const Light& L = *sl.light;
    const bool persp = L.type != LightType::Directional;
    const glm::dvec3 W = glm::normalize(L.direction);
    const WindowObject& o = w.objects[k];
    const Mesh& mesh = *o.mesh;
    const bool terrainRule = w.hasTerrain && o.kind != ChunkObject::Kind::Terrain;
    ObjectSurfaces out;

    // Window-local vertices as WindowTriangles computes them (the same bits), on demand.
    auto position = [&](uint32_t v) { return o.lsTransform.apply(mesh.positions[v]); };
    // Per triangle, when asked: +1 counter-clockwise on screen, -1 clockwise, 0 not in a
    // sheet; kUnknown until then.
    constexpr int8_t kUnknown = 2;
    std::vector<int8_t> cls(mesh.triangles.size(), kUnknown);
    auto classify = [&](uint32_t tr, bool* receiver) {
        const auto& tri = mesh.triangles[tr];
        const glm::dvec3 a = position(tri[0]), b = position(tri[1]), c = position(tri[2]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        const glm::dvec3 rd = persp ? a - L.position : W;
        // The facing sign is certain beyond this: the cross product's rounding is relative
        // to |b-a||c-a|, not to |n| (which is small for slivers).
        const double f = glm::dot(n, rd), tol = 1e-9 * glm::length(b - a) * glm::length(c - a) * glm::length(rd);
        const PrimitiveGroup& pg = mesh.groups[mesh.triangleGroup[tr]];
        // Screen orientation: U x V = -W, so a triangle is counter-clockwise exactly when its
        // geometric normal points against the light's travel. Triangles of one class have
        // one orientation; edge-on ones are in no sheet.
        // Surfaces that let light pass (alpha-tested groups, objects that cast no shadow)
        // are in no sheet: they block nothing.
        cls[tr] = o.blocksLight(mesh.triangleGroup[tr]) && std::abs(f) > tol ? (f < 0 ? 1 : -1) : 0;
        if (!receiver) return;
        *receiver = false;
        if (sl.anyReceiver) return;
        const double front = o.flipsWinding ? -f : f;
        if (!pg.twoSided() && front > tol) return;  // certainly facing away
        Aabb tb;
        tb.extend(a), tb.extend(b), tb.extend(c);
        bool excluded = persp && distanceToBox(L.position, tb) > L.range * (1 + 1e-6) + 1e-6;
        if (!excluded && terrainRule) {
            const std::optional<double> h = w.lsTerrainMinOver(tb.min.x, tb.min.z, tb.max.x, tb.max.z);
            excluded = h && tb.max.y < *h - w.terrainTolerance - 1e-6 * (std::abs(*h) + 1.0);
        }
        *receiver = !excluded;
    };
    auto classOf = [&](uint32_t tr) {
        if (cls[tr] == kUnknown) classify(tr, nullptr);
        return cls[tr];
    };
    for (uint32_t tr : selected) {
        bool receiver = false;
        classify(tr, &receiver);
        if (receiver) out.receivers.push_back({k, tr});
    }

    // Edges that join a sheet: per class, exactly two of its triangles use the edge, in
    // opposite directions. Bit 0: class +1, bit 1: class -1; 0xff until asked.
    std::vector<uint8_t> good(edges.count(), 0xff);
    auto goodOf = [&](uint32_t e) {
        if (good[e] != 0xff) return good[e];
        uint8_t g = 0;
        for (int c = 0; c < 2; ++c) {
            const int8_t want = c == 0 ? 1 : -1;
            int count = 0;
            bool f1 = false, f2 = false;
            for (uint32_t u = edges.start[e]; u < edges.start[e + 1]; ++u) {
                const MeshEdges::Use& use = edges.uses[u];
                if (classOf(use.triangle) != want) continue;
                (count == 0 ? f1 : f2) = use.forward;
                ++count;
            }
            if (count == 2 && f1 != f2) g |= uint8_t(1u << c);
        }
        return good[e] = g;
    };

    // Sheets: walk each selected triangle's component (the whole of it) across joining edges.
    constexpr uint32_t kNone = UINT32_MAX;
    std::vector<uint32_t> sheetOf(mesh.triangles.size(), kNone);
    std::vector<char> isSelected(mesh.triangles.size(), 0);
    for (uint32_t tr : selected) isSelected[tr] = 1;
    std::vector<uint32_t> stack;
    for (uint32_t start : selected) {
        const int8_t want = cls[start];
        if (want == 0 || sheetOf[start] != kNone) continue;
        const uint32_t id = uint32_t(out.sheets.size());
        Sheet& s = out.sheets.emplace_back();
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
                if (!(goodOf(e) & bit)) {
                    if (isSelected[tr]) s.cracks.push_back({k, e});
                    continue;
                }
                for (uint32_t u = edges.start[e]; u < edges.start[e + 1]; ++u) {
                    const uint32_t other = edges.uses[u].triangle;
                    if (other == tr || cls[other] != want || sheetOf[other] != kNone) continue;
                    sheetOf[other] = id;
                    stack.push_back(other);
                }
            }
        }
    }
    for (uint32_t tr : selected)
        if (sheetOf[tr] != kNone) out.sheets[sheetOf[tr]].triangles.push_back({k, tr});
    for (Sheet& s : out.sheets) {
        auto byEdge = [](const TriRef& a, const TriRef& b) { return a.triangle < b.triangle; };
        std::sort(s.cracks.begin(), s.cracks.end(), byEdge);
        s.cracks.erase(std::unique(s.cracks.begin(), s.cracks.end(),
                                   [](const TriRef& a, const TriRef& b) { return a.triangle == b.triangle; }),
                       s.cracks.end());
    }
    // The order a pass over the whole mesh gives: by each component's first triangle.
    std::stable_sort(out.sheets.begin(), out.sheets.end(),
                     [](const Sheet& a, const Sheet& b) { return a.firstTriangle < b.firstTriangle; });
    return out;
}

}  // namespace shadowcull::gpu

// A glTF 2.0 file as one mesh (a model resource that names a .gltf/.glb): every node of
// the default scene that draws a mesh contributes its primitives, placed by the composed
// node transforms. Decoding and validation live in io/gltf_document.cpp and
// io/gltf_meshes.cpp.

#include <algorithm>
#include <cmath>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>

#include "core/limits.h"
#include "core/mesh.h"
#include "io/gltf_document.h"
#include "io/mesh_load.h"
#include "util/format.h"

namespace shadowcull {

Expected<Mesh> loadGltf(const std::string& path) {
    Expected<GltfDocument> opened = GltfDocument::open(path);
    if (!opened) return opened.error();
    GltfDocument& doc = *opened;
    Expected<std::vector<size_t>> roots = doc.sceneRoots();
    if (!roots) return roots.error();

    Mesh mesh;
    // One group per primitive of every mesh, in document order, whether drawn or not.
    std::vector<size_t> firstGroup(doc.meshCount());
    for (size_t m = 0; m < doc.meshCount(); ++m) {
        Expected<std::vector<PrimitiveGroup>> groups = doc.groups(m);
        if (!groups) return groups.error();
        firstGroup[m] = mesh.groups.size();
        mesh.groups.insert(mesh.groups.end(), groups->begin(), groups->end());
    }

    // Depth-first, iterative so that deep hierarchies cannot overflow the call stack (the
    // document has checked that the nodes form a forest).
    std::vector<std::pair<size_t, glm::dmat4>> stack;
    for (auto r = roots->rbegin(); r != roots->rend(); ++r) stack.emplace_back(*r, glm::dmat4(1.0));
    while (!stack.empty()) {
        auto [n, parentWorld] = stack.back();
        stack.pop_back();
        const GltfNode& node = doc.nodes()[n];
        const glm::dmat4 world = parentWorld * node.local;
        for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world);
        if (!node.mesh) continue;
        const std::string where = gltfPath("nodes", n);
        // Decoded on first use: a mesh no node draws is never decoded.
        Expected<const std::vector<GltfPrimitive>*> decoded = doc.mesh(*node.mesh, where);
        if (!decoded) return decoded.error();
        const std::vector<GltfPrimitive>& prims = **decoded;
        // A mirroring transform turns counter-clockwise into clockwise; swap two corners so
        // that the front side stays the front side.
        const bool flip = glm::determinant(glm::dmat3(world)) < 0;
        for (size_t p = 0; p < prims.size(); ++p) {
            const GltfPrimitive& lp = prims[p];
            if (lp.triangles.empty()) continue;
            const size_t base = mesh.positions.size();
            if (base + lp.positions.size() > UINT32_MAX)
                return makeError(ErrorKind::BadInput, path, 0, "too many vertices for 32-bit indices");
            for (const glm::dvec3& q : lp.positions) {
                const glm::dvec3 w(world * glm::dvec4(q, 1.0));
                // e.g. a node scale of 1e20; the NaN test also catches inf.
                const double lim = limits::kMaxLocalCoordinate;
                if (!(std::abs(w.x) <= lim && std::abs(w.y) <= lim && std::abs(w.z) <= lim))
                    return makeError(ErrorKind::BadInput, path, 0,
                                     where + ": placed by the node transforms, a position reaches " +
                                         formatNumber(std::max({std::abs(w.x), std::abs(w.y), std::abs(w.z)})) +
                                         " m, beyond the accepted " + formatNumber(lim) +
                                         " m (docs/format.md, accepted ranges)");
                mesh.positions.push_back(w);
            }
            const uint32_t group = uint32_t(firstGroup[*node.mesh] + p);
            for (const auto& t : lp.triangles) {
                const uint32_t a = uint32_t(base + t[0]), b = uint32_t(base + t[1]), c = uint32_t(base + t[2]);
                mesh.triangles.push_back(flip ? std::array<uint32_t, 3>{a, c, b} : std::array<uint32_t, 3>{a, b, c});
                mesh.triangleGroup.push_back(group);
            }
        }
    }
    mesh.sourceFiles = doc.sourceFiles();
    return mesh;
}

}  // namespace shadowcull

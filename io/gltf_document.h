// A glTF 2.0 document (.gltf with external or data: URI buffers, or binary .glb), read
// only as far as shadow culling needs: the node forest, node transforms, meshes decoded to
// triangles with their two material flags, and the JSON itself for what callers read on
// their own (KHR_lights_punctual, extras). Used by the mesh loader (io/mesh_gltf.cpp:
// a whole file as one mesh) and by `shadowcull import` (gltf/: one model per node).
//
// Every range is checked against the real data, so a truncated or inconsistent file is an
// Error naming the file and the JSON path (and the line, for JSON syntax), never a wrong
// mesh. Decoding happens on first use of a mesh and is cached.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json_fwd.hpp>

#include "core/mesh.h"
#include "core/scene.h"
#include "util/status.h"

namespace shadowcull {

// One mesh primitive, decoded, in mesh-local coordinates (metres as the file states them;
// quantized positions already dequantized). Triangles are counter-clockwise from their
// front as glTF defines it; strips and fans are converted. Points and lines have no
// triangles (a warning says so).
struct GltfPrimitive {
    PrimitiveGroup group;  // name "mesh<m>/primitive<p>", alphaTested, doubleSided
    std::vector<glm::dvec3> positions;
    std::vector<std::array<uint32_t, 3>> triangles;
};

// One node as the file states it. `local` is column-major (glm): the node's `matrix`, or
// T * R * S of its TRS properties, in double precision. Finite; not checked for
// singularity (only a node that draws or lights something needs an invertible world).
struct GltfNode {
    std::string name;  // may be empty
    glm::dmat4 local{1.0};
    std::optional<size_t> mesh;
    std::optional<size_t> light;  // extensions.KHR_lights_punctual.light
    std::vector<size_t> children;
    long parent = -1;
};

class GltfDocument {
public:
    // Reads the container and the JSON and checks the required extensions (each one the
    // reader implements), the node forest (every node has at most one parent and is its
    // child once, no node is its own ancestor, indices in range) and every node's transform
    // (an affine `matrix` or TRS, not both). Buffers are read when a mesh first needs them.
    static Expected<GltfDocument> open(const std::string& path);

    GltfDocument(GltfDocument&&) noexcept;
    GltfDocument& operator=(GltfDocument&&) noexcept;
    ~GltfDocument();

    const std::string& path() const;
    const nlohmann::json& json() const;
    bool isGlb() const;
    const std::vector<GltfNode>& nodes() const;
    size_t meshCount() const;

    // Root nodes of scene `scene`, else of the default scene (`scene`, else scenes[0]),
    // else every node that is nobody's child when the file has no scenes. An index out of
    // range, a listed node that has a parent, or one listed twice is an error.
    Expected<std::vector<size_t>> sceneRoots(std::optional<size_t> scene = std::nullopt) const;

    // Mesh `m`'s primitive groups (names and material flags) without decoding geometry.
    Expected<std::vector<PrimitiveGroup>> groups(size_t m) const;

    // Mesh `m`'s primitives, decoded on first use. The pointer stays valid as long as the
    // document. `referrer` names who asked (e.g. "nodes[3]") for the error message.
    Expected<const std::vector<GltfPrimitive>*> mesh(size_t m, const std::string& referrer);

    // Every file read so far: the document, then external buffers in order of first use.
    std::vector<std::string> sourceFiles() const;
    // Things decoding skipped but did not fail on (points and lines), with the JSON path.
    std::vector<Diagnostic> warnings() const;

private:
    struct Impl;
    explicit GltfDocument(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

// "nodes[3]" style JSON paths for messages.
std::string gltfPath(const std::string& array, size_t index);

}  // namespace shadowcull

// Triangle meshes with primitive groups, as loaded from OBJ+MTL and glTF 2.0 files.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/mesh_index.h"
#include "util/status.h"

namespace shadowcull {

// One primitive group (spec: OBJ: one per material in order of first `usemtl`, a file
// without `usemtl` is group 0; glTF: one per mesh primitive in document order).
struct PrimitiveGroup {
    std::string name;          // material name (OBJ) or "mesh<i>/primitive<j>" (glTF); for messages only
    bool alphaTested = false;  // light passes it (glTF alphaMode MASK/BLEND, MTL map_d, or .model override)
    bool doubleSided = false;  // two-sided receiver (glTF doubleSided or .model override); alphaTested implies two-sided
    bool twoSided() const { return alphaTested || doubleSided; }
    // Set when the file cannot say whether the group is alpha-tested (an OBJ `usemtl`
    // naming a material no library defines): the group must not be baked as opaque on a
    // guess, so loading the model fails with this error unless a .model override states
    // `alphaTest` for the group.
    std::optional<Error> alphaUnknown;
};

// Mesh in model-local coordinates (metres, Y up, right-handed). Triangles are
// counter-clockwise when seen from their front. Degenerate triangles are kept here (the
// stages skip them); vertices are finite (loaders reject NaN/Inf with file and line).
struct Mesh {
    std::vector<glm::dvec3> positions;
    std::vector<std::array<uint32_t, 3>> triangles;  // indices into positions
    std::vector<uint32_t> triangleGroup;             // per triangle: index into groups
    std::vector<PrimitiveGroup> groups;              // every group, also those without triangles
    std::vector<std::string> sourceFiles;            // every file read to build it (.model, mesh, MTL, buffers)
    // Vertex trees for placed boxes, built on first use (vertexIndex, core/mesh_index.h);
    // a copy starts without them.
    LazyMeshIndex index;
};

}  // namespace shadowcull

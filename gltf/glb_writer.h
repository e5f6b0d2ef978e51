// Writes one decoded glTF mesh as a self-contained binary glTF (.glb): the mesh resources
// `shadowcull import` writes, one per unique mesh of the scene.
#pragma once

#include <string>
#include <vector>

#include "io/gltf_document.h"

namespace shadowcull::gltf {

// A GLB holding exactly `primitives` as one mesh drawn by one node (identity transform):
// positions as FLOAT (mesh-local metres, rounded to float as glTF stores them), triangles
// as UNSIGNED_INT indices, one material per primitive with its alphaMode (MASK when
// alpha-tested) and doubleSided flag. A primitive without triangles is written as one
// point, so that primitive group numbers stay those of the source mesh.
std::string meshGlb(const std::vector<GltfPrimitive>& primitives, const std::string& meshName);

// Wraps a JSON text and a binary chunk into GLB 2.0 container bytes (chunks padded to 4
// bytes: JSON with spaces, BIN with zeros, as the specification asks). `otherChunks` are
// appended after BIN unchanged (type, bytes), e.g. an extension's chunks kept on re-export.
std::string glbContainer(const std::string& jsonText, const std::string* bin,
                         const std::vector<std::pair<uint32_t, std::string>>& otherChunks = {});

}  // namespace shadowcull::gltf

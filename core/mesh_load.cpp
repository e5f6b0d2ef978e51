// Mesh file dispatch by extension (scene-format spec: OBJ+MTL and glTF 2.0 at least).

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "core/mesh.h"

namespace shadowcull {

Expected<Mesh> loadMeshFile(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".obj") return loadObj(path);
    if (ext == ".gltf" || ext == ".glb") return loadGltf(path);
    return makeError(ErrorKind::BadInput, path, 0,
                     "unsupported mesh format '" + ext + "' (expected .obj, .gltf or .glb)");
}

}  // namespace shadowcull

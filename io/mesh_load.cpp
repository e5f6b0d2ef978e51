// Mesh file dispatch by extension (scene-format spec: OBJ+MTL and glTF 2.0 at least).

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "core/mesh.h"
#include "io/mesh_load.h"

namespace shadowcull {

Expected<Mesh> loadMeshFile(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    Expected<Mesh> mesh = ext == ".obj"                      ? loadObj(path)
                          : ext == ".gltf" || ext == ".glb" ? loadGltf(path)
                                                            : Expected<Mesh>(makeError(ErrorKind::BadInput, path, 0,
                                                                                       "unsupported mesh format '" + ext +
                                                                                           "' (expected .obj, .gltf or .glb)"));
    // A mesh without a single triangle casts, occludes and receives nothing: most likely a
    // file the loader could not make sense of (binary junk read as an OBJ with no faces,
    // a glTF whose primitives are empty). Its object is skipped, never baked as "nothing".
    if (mesh && mesh->triangles.empty())
        return makeError(ErrorKind::BadInput, path, 0,
                         "the mesh has no triangles (" + std::to_string(mesh->positions.size()) +
                             " vertices); an empty or unreadable mesh is not baked");
    return mesh;
}

}  // namespace shadowcull

// The mesh file readers: Wavefront OBJ (+ MTL) and glTF 2.0. Errors name the file and
// line (JSON) or byte offset (binary data).
#pragma once

#include <string>

#include "core/mesh.h"
#include "util/status.h"

namespace shadowcull {

// Loads a Wavefront OBJ file (+ the MTL libraries it names, relative to the OBJ file).
// Polygons are fan-triangulated; negative (relative) indices are supported; `o`/`g`/`s`
// lines do not start groups. Errors name the file and line.
Expected<Mesh> loadObj(const std::string& path);

// Loads a glTF 2.0 file (.gltf with external or data: URI buffers, or binary .glb).
// Node transforms of the default scene (or of every root node when there is no scene)
// are applied; a primitive drawn by several nodes contributes all of its placements to
// its one group. Triangle modes 4/5/6 are read; points and lines add no triangles.
// Errors name the file and, for JSON, the line; for binary data, the byte offset.
Expected<Mesh> loadGltf(const std::string& path);

// Dispatches by extension (.obj, .gltf, .glb; case-insensitive).
Expected<Mesh> loadMeshFile(const std::string& path);

}  // namespace shadowcull

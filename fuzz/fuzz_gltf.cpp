// Fuzz target: glTF 2.0 (loadGltf). Input: the main file, then b.bin (an external buffer
// it may name), split by kFuzzSeparator (fuzz_support.h). The main file is m.glb when it
// starts with the GLB magic "glTF", else m.gltf (data: URIs live inside it).

#include <cstring>

#include "fuzz/fuzz_support.h"
#include "io/mesh_load.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const bool glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
    const std::string path = writeInputFiles(data, size, {glb ? "m.glb" : "m.gltf", "b.bin"})[0];
    if (shadowcull::Expected<shadowcull::Mesh> mesh = shadowcull::loadGltf(path)) checkMesh(*mesh);
    return 0;
}

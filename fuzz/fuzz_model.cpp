// Fuzz target: a .model resource (loadModelResource) with the mesh files it may name beside
// it. Input: a.model, then m.obj, m.mtl and m.gltf, split by kFuzzSeparator
// (fuzz_support.h); <visual> picks the mesh.

#include "fuzz/fuzz_support.h"
#include "io/scene_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = writeInputFiles(data, size, {"a.model", "m.obj", "m.mtl", "m.gltf"})[0];
    if (shadowcull::Expected<shadowcull::Mesh> mesh = shadowcull::loadModelResource(path)) checkMesh(*mesh);
    return 0;
}

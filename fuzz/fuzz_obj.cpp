// Fuzz target: a Wavefront OBJ and the MTL it names (loadMeshFile, which dispatches to
// loadObj). Input: m.obj, then m.mtl, split by kFuzzSeparator (fuzz_support.h).

#include "fuzz/fuzz_support.h"
#include "io/mesh_load.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = writeInputFiles(data, size, {"m.obj", "m.mtl"})[0];
    if (shadowcull::Expected<shadowcull::Mesh> mesh = shadowcull::loadMeshFile(path)) checkMesh(*mesh);
    return 0;
}

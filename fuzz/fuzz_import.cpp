// Fuzz target: `shadowcull import` (gltf::importScene). Input: the scene file, then b.bin
// (an external buffer it may name), split by kFuzzSeparator (fuzz_support.h). The scene
// is m.glb when it starts with the GLB magic "glTF", else m.gltf. A successful import must
// give a space the scene reader loads without error.

#include <cstring>
#include <filesystem>

#include "fuzz/fuzz_support.h"
#include "gltf/gltf_import.h"
#include "io/scene_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const bool glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
    const std::string path = writeInputFiles(data, size, {glb ? "m.glb" : "m.gltf", "b.bin"})[0];
    const std::string out = scratchDir() + "/space";
    std::error_code ec;
    std::filesystem::remove_all(out, ec);
    shadowcull::gltf::ImportOptions opt;
    opt.scenePath = path;
    opt.outDir = out;
    opt.sun = shadowcull::gltf::SunAngles{30, 40};  // scenes without lights still import
    if (shadowcull::Expected<shadowcull::gltf::ImportReport> r = shadowcull::gltf::importScene(opt)) {
        shadowcull::Expected<shadowcull::Space> space = shadowcull::loadSpace(out, "");
        if (!space) __builtin_trap();  // import wrote a space the tool cannot read
        for (const auto& [coord, chunk] : space->chunks)
            for (const shadowcull::ChunkObject& o : chunk.objects)
                if (o.skipped) __builtin_trap();  // a model import wrote is refused by the bake
    }
    std::filesystem::remove_all(out, ec);
    return 0;
}

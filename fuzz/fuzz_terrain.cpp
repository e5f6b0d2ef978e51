// Fuzz target: a .terrain resource and its 16-bit PNG (loadTerrainResource). Input:
// t.terrain, then h.png, split by kFuzzSeparator (fuzz_support.h). The PNG's chunk CRCs
// are made right before it is written (withPngCrcsFixed), so mutations of its header
// reach the reader.

#include "fuzz/fuzz_support.h"
#include "io/scene_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 2);
    if (parts.size() == 2) parts[1] = withPngCrcsFixed(std::move(parts[1]));
    const std::string path = writeFiles(parts, {"t.terrain", "h.png"})[0];
    if (shadowcull::Expected<shadowcull::Heightfield> hf = shadowcull::loadTerrainResource(path, 100.0))
        checkHeightfield(*hf);
    return 0;
}

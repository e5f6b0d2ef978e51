// Fuzz target: space.xml as `bake` reads it (readSpaceSettings). The input is the file.

#include "fuzz/fuzz_support.h"
#include "io/scene_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    writeInputFiles(data, size, {"space.xml"});
    (void)shadowcull::readSpaceSettings(scratchDir(), "");
    return 0;
}

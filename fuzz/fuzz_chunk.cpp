// Fuzz target: a chunk file, read as the bake reads it (readChunkFile) and, when that
// succeeds, rewritten with new <shadow> masks as the bake writes it (rewriteChunkShadows):
// the writer scans the original bytes itself, so it is a second reader of the same file.
// The input is the file.

#include <string>

#include "fuzz/fuzz_support.h"
#include "io/chunk_writer.h"
#include "io/scene_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = writeInputFiles(data, size, {"00000000o.chunk"})[0];
    std::vector<shadowcull::Diagnostic> diagnostics;
    shadowcull::Expected<shadowcull::ChunkFile> chunk = shadowcull::readChunkFile(path, {0, 0}, diagnostics);
    if (!chunk) return 0;
    // One write per object, as the bake makes them; masks and group counts vary with the
    // object so that both the replace and the insert paths see several layouts.
    std::vector<shadowcull::ShadowWrite> writes;
    for (const shadowcull::ChunkObject& o : chunk->objects) {
        shadowcull::ShadowWrite w;
        w.write = !o.skipped;
        w.terrain = o.kind == shadowcull::ChunkObject::Kind::Terrain;
        for (int g = 0; !w.terrain && g <= o.elementIndex % 3; ++g) w.groupMasks.push_back(uint32_t(g + o.line));
        for (uint32_t m : w.groupMasks) w.mask |= m;
        writes.push_back(w);
    }
    (void)shadowcull::rewriteChunkShadows(std::string(reinterpret_cast<const char*>(data), size), path, writes);
    return 0;
}

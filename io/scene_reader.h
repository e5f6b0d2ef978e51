// The readers of a space's files: space.xml, chunk files, .model and .terrain resources
// (../shared/spec/scene-format.md, docs/format.md). Every error names the file and line.
#pragma once

#include <string>
#include <vector>

#include "core/scene.h"
#include "util/status.h"

namespace shadowcull {

// Reads space.xml. `resourceRootOverride` (from --res) wins over <resourceRoot>.
Expected<SpaceSettings> readSpaceSettings(const std::string& spaceDir, const std::string& resourceRootOverride);

// Reads one chunk file's model/terrain elements. Malformed XML is an error (the bake stops:
// a file it cannot parse is a file it cannot safely rewrite); a bad object (transform,
// missing resource element) is marked skipped with a diagnostic.
Expected<ChunkFile> readChunkFile(const std::string& path, ChunkCoord coord, std::vector<Diagnostic>& diagnostics);

// Loads a model resource: a .model XML (visual mesh + primitiveGroup overrides) or a mesh
// file named directly. Errors name the file and line. `warnings` gets what was ignored (an
// unknown element that is not a misspelling: docs/format.md).
Expected<Mesh> loadModelResource(const std::string& path, std::vector<Diagnostic>* warnings = nullptr);

// Loads a .terrain file and its 16-bit grey PNG. 8-bit, non-square or N < 2 maps are errors.
// `warnings` as for loadModelResource.
Expected<Heightfield> loadTerrainResource(const std::string& path, double chunkSize,
                                          std::vector<Diagnostic>* warnings = nullptr);

// Reads space.xml and every chunk file of the space (or only those in `only` plus their
// neighbours), loading each resource once. Files named *.chunk that are not valid chunk
// names are reported and ignored.
Expected<Space> loadSpace(const std::string& spaceDir, const std::string& resourceRootOverride,
                          const std::vector<ChunkCoord>* only = nullptr);

}  // namespace shadowcull

// Shared by every fuzz target. The readers take paths, so each target writes its input into
// files in a scratch directory of its own process and hands the reader the path.
//
// Multi-file inputs (OBJ + MTL, glTF + .bin, .terrain + PNG, space + chunks + mesh) are the
// files one after the other, separated by the line kFuzzSeparator:
//
//   <file 0 bytes>\n--- next file ---\n<file 1 bytes>\n--- next file ---\n<file 2 bytes>
//
// The separator (its two newlines included) belongs to neither file. A file with no part
// in the input is removed, so that nothing of an earlier input leaks into this one. The
// last named file takes the rest of the input, separators and all.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/scene.h"

inline constexpr char kFuzzSeparator[] = "\n--- next file ---\n";

// This process's scratch directory (under $SHADOWCULL_FUZZ_TMPDIR, else /dev/shm, else the
// system temporary directory), made on first use and removed at normal exit.
const std::string& scratchDir();

// Splits the input as above into at most `count` parts.
std::vector<std::string> splitInput(const uint8_t* data, size_t size, size_t count);
// Writes parts[i] to scratchDir()/names[i] and removes the named files that have no part.
// Returns the paths, one per name.
std::vector<std::string> writeFiles(const std::vector<std::string>& parts, const std::vector<std::string>& names);
// Both: the usual first line of a target.
std::vector<std::string> writeInputFiles(const uint8_t* data, size_t size, const std::vector<std::string>& names);

// A PNG with every chunk's CRC made right, so that a mutated header or size reaches the
// terrain reader instead of stopping at libpng's CRC check (a real file can carry any
// header with a correct CRC). Other bytes are kept.
std::string withPngCrcsFixed(std::string png);

// What the loaders promise (core/mesh.h, core/scene.h): indices in range, one group per
// triangle, finite vertices and heights. A broken promise aborts with a message, so that a
// reader that hands later stages bad data is found even where it does not crash itself.
void checkMesh(const shadowcull::Mesh& mesh);
// Aborts with "fuzz: broken promise: <what>" (a promise of the tool, not of a loader).
[[noreturn]] void brokenPromise(const char* what);
void checkHeightfield(const shadowcull::Heightfield& hf);

// Reading input files without trusting what the path names: a FIFO, device or directory
// named like a chunk or a mesh must be reported, never block the bake or read as empty.
#pragma once

#include <string>

#include "util/status.h"

namespace shadowcull {

// strerror(err) as the middle of a sentence: "no such file or directory", "permission
// denied", "is a directory".
std::string errnoText(int err);

// Reads the whole file at `path`. The file is opened without blocking (O_NONBLOCK, so a
// FIFO with no writer cannot stall the open) and refused unless fstat says it is a regular
// file; the size is checked against `maxBytes` before anything is read. Errors name the
// file: MissingResource (`missingKind`) when it does not exist or cannot be opened,
// BadInput when it is not a regular file or too large, Io when reading fails midway.
// `what` names the file's role in messages ("chunk file", "OBJ file", ...).
Expected<std::string> readRegularFile(const std::string& path, const std::string& what,
                                      ErrorKind missingKind = ErrorKind::MissingResource,
                                      size_t maxBytes = size_t(1) << 32);

}  // namespace shadowcull

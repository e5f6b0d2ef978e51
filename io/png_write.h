// Writing an RGB picture as PNG (render, check pictures). libpng's default handlers print
// "libpng error: ..." and "libpng warning: ..." lines of their own on stderr; this writer
// installs handlers that turn both into the tool's messages instead.
#pragma once

#include <string>
#include <vector>

#include "util/status.h"

namespace shadowcull {

// Writes `rgbTopDown` (width * height * 3 bytes, rows from the top) to `path`. An error
// names the file and says why in a user's words (the system's reason for an open that
// failed, libpng's reason for an encoding that failed); nothing reaches stderr. A failed
// write leaves no half-written picture behind.
Status writeRgbPng(const std::string& path, int width, int height, const std::vector<unsigned char>& rgbTopDown);

// The libpng this program runs with ("1.6.39"), for --version.
std::string libpngVersion();

// What libpng warned about in this thread's last writeRgbPng (kept for tests; the writer
// itself goes on after a warning, as libpng does).
const std::vector<std::string>& lastPngWarnings();

}  // namespace shadowcull

// `shadowcull import` and `shadowcull export`: the glTF way in and out (gltf/), with the
// CLI's messages and exit codes.
#pragma once

#include <ostream>
#include <string>

#include "gltf/gltf_export.h"
#include "gltf/gltf_import.h"

namespace shadowcull::cli {

// `sun`: "AZIMUTH,ELEVATION" in degrees, or empty.
int runImport(gltf::ImportOptions opt, const std::string& sun, std::ostream& out, std::ostream& err);
int runExport(const gltf::ExportOptions& opt, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli

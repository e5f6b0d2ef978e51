// Outputs never replace inputs: every command that writes a file (bake --results, render
// --out, check --pictures, sweep --csv/--svg, diff --html/--json) checks its output path
// against the files it read before writing anything.
#pragma once

#include <string>
#include <vector>

#include "util/status.h"

namespace shadowcull::cli {

// BadInput when `output` is one of `inputs`: the same file by device and inode, so a
// symlink or hard link to an input, or another spelling of its path, is caught too; or a
// directory (a file is to be written there). An output that does not exist yet cannot be
// an input. `option` names the option in the
// message ("--results"). A directory among `inputs` stands for every file directly in it
// (a baked space given to diff).
Status refuseInputAsOutput(const std::string& output, const std::vector<std::string>& inputs, const std::string& option);

}  // namespace shadowcull::cli

#include "cli/staged_outputs.h"

#include <algorithm>
#include <filesystem>

#include "io/chunk_writer.h"
#include "util/stop_request.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

Status StagedOutputs::makeDirectory(const std::string& dir) {
    // The missing ones, outermost first: what discard() may remove again.
    std::vector<std::string> missing;
    std::error_code ec;
    for (fs::path p = fs::path(dir).lexically_normal(); !p.empty() && !fs::exists(fs::symlink_status(p, ec)); p = p.parent_path()) {
        missing.push_back(p.string());
        if (p == p.parent_path()) break;
    }
    std::reverse(missing.begin(), missing.end());
    fs::create_directories(dir, ec);
    if (ec) return makeError(ErrorKind::Io, dir, 0, "cannot create the directory: " + ec.message());
    madeDirs_.insert(madeDirs_.end(), missing.begin(), missing.end());
    return Status::ok();
}

std::string StagedOutputs::stage(const std::string& path) {
    files_.push_back({tempPathFor(path), path});
    return files_.back().temp;
}

Status StagedOutputs::commit() {
    if (Status stop = stopStatus(); !stop) {
        discard();
        return stop;
    }
    for (size_t k = 0; k < files_.size(); ++k) {
        std::error_code ec;
        if (!fs::exists(files_[k].temp, ec)) continue;  // staged, but never written (a failed render)
        if (Status s = commitStagedFile(files_[k].temp, files_[k].path); !s) {
            files_.erase(files_.begin(), files_.begin() + std::ptrdiff_t(k + 1));
            discard();
            return s;
        }
    }
    files_.clear();
    madeDirs_.clear();
    return Status::ok();
}

void StagedOutputs::discard() {
    std::error_code ec;
    for (const File& f : files_) fs::remove(f.temp, ec);
    files_.clear();
    // Innermost first; fs::remove leaves a directory that is not empty.
    for (auto d = madeDirs_.rbegin(); d != madeDirs_.rend(); ++d) fs::remove(*d, ec);
    madeDirs_.clear();
}

}  // namespace shadowcull::cli

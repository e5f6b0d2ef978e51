#include "cli/output_guard.h"

#include <sys/stat.h>

#include <filesystem>

namespace fs = std::filesystem;

namespace shadowcull::cli {

Status refuseInputAsOutput(const std::string& output, const std::vector<std::string>& inputs, const std::string& option) {
    struct stat out {};
    if (output.empty() || ::stat(output.c_str(), &out) != 0) return Status::ok();  // nothing there to replace
    // A file is written here: a directory (".", the space, --out) would only fail at the
    // final rename, after everything else was written.
    if (S_ISDIR(out.st_mode))
        return makeError(ErrorKind::BadInput, output, 0, option + " names a directory; give the path of the file to write");
    auto same = [&](const std::string& input) {
        struct stat in {};
        return ::stat(input.c_str(), &in) == 0 && in.st_dev == out.st_dev && in.st_ino == out.st_ino;
    };
    auto refuse = [&](const std::string& input) {
        return makeError(ErrorKind::BadInput, output, 0,
                         option + " names an input of this command (" + input + "); refusing to overwrite it");
    };
    for (const std::string& input : inputs) {
        if (same(input)) return refuse(input);
        std::error_code ec;
        if (fs::is_directory(input, ec))
            for (const fs::directory_entry& de : fs::directory_iterator(input, ec))
                if (same(de.path().string())) return refuse(de.path().string());
    }
    return Status::ok();
}

}  // namespace shadowcull::cli

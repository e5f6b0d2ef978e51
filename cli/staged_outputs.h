// Files a command writes after a long computation (check's pictures, render's and
// preview's PNG), staged beside their names and renamed into place only once the command
// has completed: an error or a signal (cli/interrupt.h) leaves none of them, nor a
// directory the command made for them. As bake stages its chunk files.
#pragma once

#include <string>
#include <vector>

#include "util/status.h"

namespace shadowcull::cli {

class StagedOutputs {
public:
    StagedOutputs() = default;
    ~StagedOutputs() { discard(); }
    StagedOutputs(const StagedOutputs&) = delete;
    StagedOutputs& operator=(const StagedOutputs&) = delete;

    // Makes `dir` (and its missing parents); those it made are removed again by discard()
    // when they are left empty.
    Status makeDirectory(const std::string& dir);
    // The name to write `path` under until commit() (tempPathFor(path): a temporary of a
    // killed command is cleared as a bake's are).
    std::string stage(const std::string& path);
    // Unless a signal arrived (then everything is discarded: Interrupted), renames every
    // staged file over its name (commitStagedFile). Not interrupted once begun.
    Status commit();
    // Removes the staged files and the directories made for them.
    void discard();

private:
    struct File {
        std::string temp, path;
    };
    std::vector<File> files_;
    std::vector<std::string> madeDirs_;  // outermost first
};

}  // namespace shadowcull::cli

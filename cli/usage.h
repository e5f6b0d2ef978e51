// What the command line says to a person: option checks whose messages give the accepted
// values and the value given (CLI11's own say "not in range 0.000000 to 1797693134862..."),
// the exit codes under each command's --help, the parse-error format and --version.
#pragma once

#include <initializer_list>
#include <string>

#include <CLI/CLI.hpp>

namespace shadowcull::cli {

// A whole number of at least `min`: "must be 1 or more (got 0)".
CLI::Validator atLeast(long long min);
// A number within [lo, hi]: "must be from 16 to 16384 (got 5)". `whole`: integers only.
CLI::Validator within(double lo, double hi, bool whole = true);
// A number more than 0: "must be more than 0 (got -1)".
CLI::Validator positiveNumber();
// One of `names`: "must be analytic or gpu (got 'fast')".
CLI::Validator oneOf(std::initializer_list<const char*> names);
// Paths that must exist: "no such directory: spce", "is a file, not a directory: x".
CLI::Validator existingDirectory();
CLI::Validator existingFile();
CLI::Validator existingPath();

// The exit codes of each command, as printed at the end of its --help (docs/cli.md).
extern const char* const kBakeExitCodes;
extern const char* const kCheckExitCodes;
extern const char* const kDiffExitCodes;
extern const char* const kImportExitCodes;
extern const char* const kExportExitCodes;
extern const char* const kSavingsExitCodes;  // report
extern const char* const kMergeExitCodes;
extern const char* const kPlanExitCodes;
extern const char* const kReportExitCodes;  // explain, render, sweep
extern const char* const kPreviewExitCodes;
extern const char* const kTopFooter;

// Parse errors as "shadowcull: error: --light: must be 1 or more (got 0)" and where to read
// more ("shadowcull render --help").
std::string formatParseFailure(const CLI::App* app, const CLI::Error& e);

// `shadowcull --version`: the tool and the libraries that decide its results (Embree, CGAL,
// TBB, libpng, tinyxml2) and the OpenGL renderer the GPU stages would use, or why none.
std::string versionText();

}  // namespace shadowcull::cli

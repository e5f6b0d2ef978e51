#include "cli/usage.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include <CGAL/version.h>
#include <embree3/rtcore_config.h>
#include <oneapi/tbb/version.h>
#include <tinyxml2.h>

#include "gpu/gl_context.h"
#include "io/png_write.h"
#include "util/format.h"
#include "util/nearest_name.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

// The number `s` holds, or nothing when it is not one (trailing text, empty, out of range).
bool parseNumber(const std::string& s, double& v) {
    const char* p = s.c_str();
    char* end = nullptr;
    errno = 0;
    v = std::strtod(p, &end);
    return end != p && *end == '\0' && errno != ERANGE && std::isfinite(v);
}

// Whether `s` is written as a whole number ("1e3" and "16.0" are not: CLI11 would fail to
// convert them into the option's integer with a message of its own).
bool wholeText(const std::string& s) {
    size_t k = (!s.empty() && (s[0] == '-' || s[0] == '+')) ? 1 : 0;
    if (k == s.size()) return false;
    for (; k < s.size(); ++k)
        if (s[k] < '0' || s[k] > '9') return false;
    return true;
}

// Bounds as typed: 1048576, not 1.04858e+06.
std::string bound(double v) {
    if (v == std::floor(v) && std::abs(v) < 1e15) return std::to_string((long long)v);
    return formatNumber(v);
}

std::string got(const std::string& s) { return " (got " + (s.empty() ? std::string("nothing") : s) + ")"; }

}  // namespace

CLI::Validator atLeast(long long min) {
    const std::string want = std::to_string(min) + " or more";
    return CLI::Validator(
        [want, min](std::string& s) -> std::string {
            double v = 0;
            if (!wholeText(s) || !parseNumber(s, v)) return "must be a whole number, " + want + got("'" + s + "'");
            if (v < double(min)) return "must be " + want + got(s);
            return {};
        },
        ">= " + std::to_string(min));
}

CLI::Validator within(double lo, double hi, bool whole) {
    const std::string want = "from " + bound(lo) + " to " + bound(hi);
    return CLI::Validator(
        [=](std::string& s) -> std::string {
            double v = 0;
            if (!parseNumber(s, v) || (whole && !wholeText(s)))
                return std::string("must be a ") + (whole ? "whole " : "") + "number " + want + got("'" + s + "'");
            if (v < lo || v > hi) return "must be " + want + got(s);
            return {};
        },
        bound(lo) + ".." + bound(hi));
}

CLI::Validator positiveNumber() {
    return CLI::Validator(
        [](std::string& s) -> std::string {
            double v = 0;
            if (!parseNumber(s, v)) return "must be a number more than 0" + got("'" + s + "'");
            if (!(v > 0)) return "must be more than 0" + got(s);
            return {};
        },
        "> 0");
}

CLI::Validator oneOf(std::initializer_list<const char*> names) {
    std::vector<std::string> list(names.begin(), names.end());
    std::string want, desc;
    for (size_t k = 0; k < list.size(); ++k) {
        want += (k == 0 ? "" : k + 1 == list.size() ? " or " : ", ") + list[k];
        desc += (k ? "|" : "") + list[k];
    }
    return CLI::Validator(
        [list, want](std::string& s) -> std::string {
            for (const std::string& n : list)
                if (s == n) return {};
            return "must be " + want + got("'" + s + "'");
        },
        desc);
}

namespace {

// "" when `path` is what `want` asks for, else why not in a user's words.
std::string pathProblem(const std::string& path, bool wantDirectory, bool wantFile) {
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (!fs::exists(st)) {
        const char* what = wantDirectory ? "directory" : wantFile ? "file" : "file or directory";
        return std::string("no such ") + what + ": " + path + (ec && ec != std::errc::no_such_file_or_directory ? " (" + ec.message() + ")" : "");
    }
    if (wantDirectory && !fs::is_directory(st)) return path + " is a file, not a directory";
    if (wantFile && fs::is_directory(st)) return path + " is a directory, not a file";
    return {};
}

}  // namespace

CLI::Validator existingDirectory() {
    return CLI::Validator([](std::string& s) { return pathProblem(s, true, false); }, "DIR");
}
CLI::Validator existingFile() {
    return CLI::Validator([](std::string& s) { return pathProblem(s, false, true); }, "FILE");
}
CLI::Validator existingPath() {
    return CLI::Validator([](std::string& s) { return pathProblem(s, false, false); }, "PATH");
}

const char* const kBakeExitCodes =
    "Exit codes: 0 baked; 1 baked, but some input was skipped or a chunk file not written (warnings name file\n"
    "and line); 2 usage error; 3 bad input (stopped, nothing written); 4 I/O error; 5 internal error (Embree,\n"
    "CGAL, OpenGL); 6 another bake holds the output directory's lock; 9 --plan: the space changed since the plan\n"
    "was made (plan again); 130 interrupted by Ctrl-C, 143 by SIGTERM (the bake's temporary files removed, no\n"
    "chunk file changed unless --resume had committed some).\n";
const char* const kCheckExitCodes =
    "Exit codes: 0 no GPU false cull; 1 the GPU method culled a bit that has a witness; 2 usage error; 3 bad\n"
    "input; 4 a picture cannot be written; 5 no OpenGL context, or a library failed.\n";
const char* const kDiffExitCodes =
    "Exit codes: 0 nothing changed; 1 something changed (bits, verdicts, objects or lights); 2 usage error;\n"
    "3 bad input; 4 a report cannot be written.\n";
const char* const kImportExitCodes =
    "Exit codes: 0 written; 2 usage error; 3 bad input (file and JSON path named, nothing written); 4 the output\n"
    "exists and is not empty, or could not be written.\n";
const char* const kExportExitCodes =
    "Exit codes: 0 written; 1 written, but some mesh nodes are in chunks the results do not hold; 2 usage error;\n"
    "3 the scene, space or results do not belong together or are malformed; 4 could not write.\n";
const char* const kSavingsExitCodes =
    "Exit codes: 0 reported; 2 usage error (SPACE or RESULTS does not exist); 3 bad input (not a results file, results\n"
    "of another space or of the space before it changed, --html naming an input); 4 the page cannot be written.\n";
const char* const kMergeExitCodes =
    "Exit codes: 0 merged; 2 usage error; 3 a file is unreadable, malformed or not a shard's results; 4 OUT cannot\n"
    "be written; 7 the shards are of different bakes (inputs, options, space or shard count); 8 a shard or chunk\n"
    "is missing or given twice. Nothing is written unless the exit code is 0.\n";
const char* const kPlanExitCodes =
    "Exit codes: 0 written; 1 written, but reading the space gave warnings (the plan carries them to the shards);\n"
    "2 usage error; 3 bad input (nothing written); 4 the plan cannot be written; 130 interrupted by Ctrl-C, 143\n"
    "by SIGTERM.\n";
const char* const kPreviewExitCodes =
    "Exit codes: 0 no false cull shows; 1 a shadow the engine draws is missing (a false cull, named); 2 usage\n"
    "error; 3 bad input; 4 a file cannot be written; 5 internal error (Embree, CGAL, OpenGL).\n";
const char* const kReportExitCodes =
    "Exit codes: 0 done; 2 usage error; 3 bad input; 4 a file cannot be written; 5 internal error (Embree,\n"
    "CGAL, OpenGL).\n";
const char* const kTopFooter =
    "Run 'shadowcull COMMAND --help' for a command's options, defaults and exit codes. Exit code 2 is a usage\n"
    "error for every command. Documentation: docs/cli.md, docs/format.md.\n";

namespace {

// "no command given (bake, sweep, ...)", or for `shadowcull frobnicate` "unknown command
// 'frobnicate' (did you mean ...?)": CLI11 says "A subcommand is required" of both.
std::string missingCommand(const CLI::App* app) {
    std::vector<std::string> commands;
    for (const CLI::App* sub : app->get_subcommands({})) commands.push_back(sub->get_name());
    std::string list;
    for (size_t k = 0; k < commands.size(); ++k)
        list += (k == 0 ? "" : k + 1 == commands.size() ? " or " : ", ") + commands[k];
    // A word CLI11 could not place (not an option) is the command the user meant.
    for (const std::string& word : app->remaining(false)) {
        if (word.empty() || word[0] == '-') continue;
        const std::string nearest = nearestName(word, commands);
        const std::string hint = looksLikeMisspelling(word, nearest) ? "did you mean '" + nearest + "'?"
                                                                     : "the nearest is '" + nearest + "'";
        return "unknown command '" + word + "' (" + hint + "); the commands are " + list;
    }
    return "no command given (" + list + ")";
}

}  // namespace

std::string formatParseFailure(const CLI::App* app, const CLI::Error& e) {
    // The command whose options were being read, for "shadowcull bake --help".
    std::string command = "shadowcull";
    for (const CLI::App* sub : app->get_subcommands([](const CLI::App* a) { return a->parsed() > 0; })) {
        command += " " + sub->get_name();
        break;
    }
    // CLI11's own wording where no validator of ours speaks first.
    std::string what = e.what();
    if (what == "A subcommand is required") what = missingCommand(app);
    const std::string convert = "Could not convert: ";
    if (what.rfind(convert, 0) == 0)
        if (const size_t eq = what.find(" = ", convert.size()); eq != std::string::npos)
            what = what.substr(convert.size(), eq - convert.size()) + ": '" + what.substr(eq + 3) +
                   "' is not a value of the kind it takes (see --help)";
    return "shadowcull: error: " + what + "\nRun '" + command + " --help' for the options.\n";
}

std::string versionText() {
    std::string s = "shadowcull " SHADOWCULL_VERSION "\n";
    s += std::string("Embree ") + RTC_VERSION_STRING + "\n";
    s += std::string("CGAL ") + CGAL_VERSION_STR + "\n";
    s += std::string("oneTBB ") + TBB_runtime_version() + "\n";
    s += "libpng " + libpngVersion() + "\n";
    s += "tinyxml2 " + std::to_string(TIXML2_MAJOR_VERSION) + "." + std::to_string(TIXML2_MINOR_VERSION) + "." +
         std::to_string(TIXML2_PATCH_VERSION) + "\n";
    Expected<std::unique_ptr<gpu::GlContext>> gl = gpu::createOffscreenContext(16, 16);
    s += "OpenGL: " + (gl ? (*gl)->report() : "none (" + gl.error().message + "; the GPU stages are skipped)");
    // Every backend and EGL device, for --gl / --gl-device (the line above is what the
    // current choice, auto unless SHADOWCULL_GL says otherwise, gives).
    s += "\nOpenGL backends:";
    for (const std::string& line : gpu::listGlBackends()) s += "\n  " + line;
    return s;
}

}  // namespace shadowcull::cli

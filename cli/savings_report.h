// `shadowcull report SPACE RESULTS.json [--html FILE]`: what a bake's masks
// remove from each light's shadow pass, in casters (groups) and placed triangles, split
// into (a) what the engine's own run-time culling already removes and (b) what only this
// bake removes (cli/savings.h), for the world and per chunk, with the biggest single
// savings and their proofs. The results file is read through io/results_file.h (as
// `diff` reads it); the triangles are counted in the space, which must be the one baked.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "io/results_file.h"

namespace shadowcull::cli {

struct ReportOptions {
    std::string spaceDir, resultsPath;
    std::string resourceRoot;  // --res; empty: space.xml's <resourceRoot>, else the space
    std::string htmlPath;      // empty: no HTML page
    int top = 20;              // biggest single savings listed in the HTML page (text: 10)
};

// Prints the report to `out` (errors to `err`) and writes the HTML page when asked.
// Exit codes as the other commands: 0 reported; 3 bad input (not a results file, results
// of another space or of the space before it changed, an --html path that is an input);
// 4 the page cannot be written.
int runReport(const ReportOptions& options, std::ostream& out, std::ostream& err);

// The per-light table of the bake summary and the report: casters | triangles of every
// caster, (a), left after (a), (b) with its share of what (a) leaves, left after both,
// undecided. `lightNames[l]` names light l + 1.
std::string formatSavingsTable(const std::vector<results::LightSavingsRecord>& lights,
                               const std::vector<std::string>& lightNames);

}  // namespace shadowcull::cli

// What `shadowcull report` shows, gathered once for the text and the HTML page
// (cli/savings_report.cpp, cli/savings_html.cpp). Internal to those two files.
#pragma once

#include <string>
#include <vector>

#include "cli/savings.h"
#include "io/results_file.h"

namespace shadowcull::cli::savings_detail {

// One object's saving for one light beyond the engine's culling: the triangles of its
// groups that only the bake removed.
struct BigSaving {
    size_t chunk = 0, object = 0;  // into ReportModel::file.chunks / .objects
    int light = 0;                 // from 1
    results::WorkRecord removed;   // (b) of this object and light
};

struct ReportModel {
    std::string spaceDir, resultsPath;
    double chunkSize = 100.0;       // metres (space.xml), to place lights on the map
    results::ResultsFile file;      // groups' `triangles` counted in the space
    savings::Tally tally;           // world and per chunk (file.chunks order)
    std::vector<BigSaving> biggest;  // most triangles first, the first few only
    size_t biggestPairs = 0;         // object-light pairs with a saving beyond (a)
    ReportModel() : tally(0) {}
};

// "model #3 00000000-...-000000A1" / "terrain #0".
std::string objectLabel(const results::ObjectRecord& o);
// "light 2 'lamp' (point)".
std::string lightLabel(const results::LightRecord& L);
// A bit's proof as `explain` prints it: "culled, stage geometry; proof: ...".
std::string proofText(const results::BitRecord& b);
// 1234567 -> "1,234,567".
std::string grouped(uint64_t n);
// 100 * a / b with one decimal and " %", or "-" when b is 0.
std::string percent(uint64_t a, uint64_t b);

std::string htmlReport(const ReportModel& m);

}  // namespace shadowcull::cli::savings_detail

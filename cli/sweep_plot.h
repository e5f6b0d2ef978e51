// The SVG plot of `shadowcull sweep --svg`: seconds (log scale) on x; false keeps on y in
// the main panel; false culls (defects) as their own series in a strip below, on the same
// x. Points are numbered, labels placed clear of each other and of the markers, and a key
// table under the plot names each number's setting with its figures. Every text element
// carries x, y, font-size and text-anchor, and lies inside the viewBox.
#pragma once

#include <string>
#include <vector>

#include "cli/sweep.h"

namespace shadowcull::cli {

// Readable axis ticks: 0 and multiples of 1, 2 or 5 x 10^k up to at least `max` (about
// five of them, never fewer than two).
std::vector<double> niceLinearTicks(double max);
// Ticks for a log axis over [lo, hi] (lo > 0): 1, 2, 5 x 10^k (only 10^k over many decades).
std::vector<double> niceLogTicks(double lo, double hi);

std::string sweepSvg(const std::vector<SweepRow>& rows);

}  // namespace shadowcull::cli

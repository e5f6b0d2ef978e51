#include "cli/bake_totals.h"

#include <algorithm>

namespace shadowcull::cli {

void tallyVerdicts(savings::Tally& tally, const ChunkVerdicts& cv) {
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        for (int g = 0; g < ov.groupCount; ++g) {
            const uint64_t tris = size_t(g) < ov.groupTriangles.size() ? ov.groupTriangles[size_t(g)] : 0;
            for (int l = 0; l < cv.lightCount; ++l) {
                const Decision& d = cv.at(oi, g, l);
                tally.add(size_t(l), savings::classify(verdictName(d.verdict), d.stage, d.reason()), d.stage, tris);
            }
        }
    }
}

void BakeTotals::add(const ChunkVerdicts& cv) {
    ++chunks;
    for (const ObjectVerdicts& ov : cv.objects) {
        bits.groups += uint64_t(ov.groupCount);
        for (const Decision& d : ov.decisions) {
            ++bits.bits;
            switch (d.verdict) {
                case Verdict::Culled: ++bits.culled; ++bits.culledBy[std::string(d.stage)]; break;
                case Verdict::Kept: ++bits.kept; ++bits.provedKept; ++bits.keptBy[std::string(d.stage)]; break;
                case Verdict::Undecided: ++bits.kept; ++bits.undecided; break;
            }
        }
    }
    tallyVerdicts(savings, cv);
    for (const std::string& e : cv.simulated) {
        auto it = std::find_if(simulated.begin(), simulated.end(), [&](const auto& p) { return p.first == e; });
        if (it == simulated.end()) simulated.emplace_back(e, 1);
        else ++it->second;
    }
}

}  // namespace shadowcull::cli

#include "core/verdict.h"

#include <cassert>

namespace shadowcull {

const char* verdictName(Verdict v) {
    switch (v) {
        case Verdict::Undecided: return "undecided";
        case Verdict::Kept: return "kept";
        case Verdict::Culled: return "culled";
    }
    return "?";
}

uint32_t ChunkVerdicts::groupMask(size_t object, int group) const {
    uint32_t mask = 0;
    for (int l = 0; l < lightCount; ++l)
        if (at(object, group, l).verdict != Verdict::Culled) mask |= 1u << l;
    return mask;
}

void decide(Decision& d, Verdict v, const char* stage, std::string reason, std::optional<Witness> witness) {
    assert(d.verdict == Verdict::Undecided && v != Verdict::Undecided);
    if (d.verdict != Verdict::Undecided) return;  // a decided bit stays as it is
    d.verdict = v;
    d.stage = stage;
    d.reason = std::move(reason);
    d.witness = std::move(witness);
}

}  // namespace shadowcull

#include "core/verdict.h"

#include <cassert>

namespace shadowcull {

// A bake holds one Decision per (group, light) of the whole world (10 M in the benchmark's
// world L): keep it small.
static_assert(sizeof(Decision) <= 48, "Decision grew: every bit of a world pays for it");

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

void decideWith(Decision& d, Verdict v, const char* stage, const char* staticReason, std::shared_ptr<const Evidence> evidence) {
    assert(d.verdict == Verdict::Undecided && v != Verdict::Undecided);
    if (d.verdict != Verdict::Undecided) return;  // a decided bit stays as it is
    d.verdict = v;
    d.stage = stage;
    d.staticReason_ = staticReason;
    d.evidence_ = std::move(evidence);  // the notes were about why it was not decided yet
}

void addNote(Decision& d, const char* stage, std::string text) {
    if (d.verdict != Verdict::Undecided) return;
    auto e = d.evidence_ ? std::make_shared<Evidence>(*d.evidence_) : std::make_shared<Evidence>();
    e->notes.push_back(StageNote{stage, std::move(text)});
    d.evidence_ = std::move(e);
}

const std::vector<StageNote>& Decision::notes() const {
    static const std::vector<StageNote> none;
    return evidence_ ? evidence_->notes : none;
}

void decide(Decision& d, Verdict v, const char* stage, std::string reason, std::optional<Witness> witness) {
    decideWith(d, v, stage, nullptr, std::make_shared<const Evidence>(Evidence{std::move(reason), std::move(witness), {}}));
}

void decide(Decision& d, Verdict v, const char* stage, std::shared_ptr<const Evidence> shared) {
    decideWith(d, v, stage, nullptr, std::move(shared));
}

}  // namespace shadowcull

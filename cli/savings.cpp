#include "cli/savings.h"

namespace shadowcull::results {

WorkRecord operator-(const WorkRecord& a, const WorkRecord& b) { return {a.casters - b.casters, a.triangles - b.triangles}; }

WorkRecord& operator+=(WorkRecord& a, const WorkRecord& b) {
    a.casters += b.casters;
    a.triangles += b.triangles;
    return a;
}

}  // namespace shadowcull::results

namespace shadowcull::savings {

Why classify(std::string_view verdict, std::string_view stage, std::string_view reason) {
    if (verdict == "kept") return Why::ProvedKept;
    if (verdict != "culled") return Why::Undecided;
    // An engine skips a caster flagged castsShadow false and culls a point or spot light's
    // casters against its range sphere and cone; the reach stage proves no more than that.
    if (stage == "reach" || (stage == "input" && reason == kCastsShadowFalse)) return Why::EngineCulls;
    return Why::BakeCulls;
}

namespace {

std::vector<LightSavingsRecord> zeroed(size_t lights) {
    std::vector<LightSavingsRecord> v(lights);
    for (size_t l = 0; l < lights; ++l) v[l].light = int(l) + 1;
    return v;
}

void addTo(LightSavingsRecord& s, Why why, std::string_view stage, const WorkRecord& w) {
    s.all += w;
    switch (why) {
        case Why::EngineCulls: s.engineCulls += w; break;
        case Why::BakeCulls:
            s.bakeCulls += w;
            s.bakeCullsBy[std::string(stage)] += w;
            break;
        case Why::Undecided: s.undecided += w; break;
        case Why::ProvedKept: break;
    }
}

}  // namespace

Tally::Tally(size_t lights) : world_(zeroed(lights)) {}

void Tally::beginChunk() { chunks_.push_back(zeroed(world_.size())); }

void Tally::add(size_t light, Why why, std::string_view stage, uint64_t triangles) {
    if (light >= world_.size()) return;
    const WorkRecord w{1, triangles};
    addTo(world_[light], why, stage, w);
    if (!chunks_.empty()) addTo(chunks_.back()[light], why, stage, w);
}

void Tally::addChunk(const results::ChunkRecord& c) {
    beginChunk();
    for (const results::ObjectRecord& o : c.objects) addObject(o);
}

void Tally::addObject(const results::ObjectRecord& o) {
    for (const results::GroupRecord& g : o.groups)
        for (const results::BitRecord& b : g.lights)
            add(size_t(b.light - 1), classify(b.verdict, b.stage, b.reason), b.stage, g.triangles.value_or(0));
}

std::vector<LightSavingsRecord> Tally::takeLastChunk() {
    if (chunks_.empty()) return {};
    std::vector<LightSavingsRecord> last = std::move(chunks_.back());
    chunks_.pop_back();
    return last;
}

Tally tallyResults(const ResultsFile& file) {
    Tally t(file.lights.size());
    for (const results::ChunkRecord& c : file.chunks) t.addChunk(c);
    return t;
}

}  // namespace shadowcull::savings

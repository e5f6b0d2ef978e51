// Internal to `shadowcull diff` (cli/diff.cpp reads and compares, cli/diff_report.cpp
// writes the text and JSON reports, cli/diff_html.cpp the HTML report): what each side of
// the diff knows, and what the comparison found.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/scene.h"

namespace shadowcull::cli::diff_detail {

using Vec = std::array<double, 3>;

using BoxVec = std::array<Vec, 2>;  // world {min, max}

struct WitnessRay {
    Vec origin{}, direction{}, p{}, q{};
    std::string receiver;
    std::optional<BoxVec> receiverBounds;  // the receiving object's box, when recorded
};

// One (group, light) bit. An empty verdict means only the bit is known (a baked space).
struct Evidence {
    int bit = 1;
    std::string verdict, stage, reason;
    std::optional<WitnessRay> witness;
};

struct GroupBits {
    uint32_t mask = 0;
    std::optional<BoxVec> bounds;  // the group's box, when the results recorded it
    std::vector<Evidence> lights;  // [light - 1]; empty for a baked space
};

struct ObjectBake {
    std::string key;  // uuid (with "#n" for its n-th repeat in the chunk), else "#element"
    std::string uuid, kind;
    int element = 0;
    bool skipped = false;  // results: the bake could not use it (no verdicts)
    bool hasMask = true;   // baked space: the element has a <shadow>
    uint32_t mask = 0;
    std::vector<GroupBits> groups;
};

struct ChunkSide {
    std::vector<std::string> simulated;
    std::vector<ObjectBake> objects;  // document order
};

struct LightInfo {
    std::string name, type;
    // As baked, when the side records it (results files of this version, or space.xml).
    std::optional<Vec> position, direction;
    std::optional<double> range, coneAngle, bias, slopeBias, filterRadius, normalBias;
};

// Grid order for chunk file names (as the bake lists them), other names after, by text.
struct ChunkLess {
    bool operator()(const std::string& a, const std::string& b) const {
        const std::optional<ChunkCoord> ca = parseChunkName(a), cb = parseChunkName(b);
        if (ca && cb && !(*ca == *cb)) return *ca < *cb;
        if (bool(ca) != bool(cb)) return bool(ca);
        return a < b;
    }
};

struct Bake {
    std::string path;         // as given
    bool results = true;      // false: a baked space, masks only
    bool lightsKnown = true;  // false: a space directory without space.xml
    std::vector<LightInfo> lights;
    std::map<std::string, ChunkSide, ChunkLess> chunks;
    size_t warnings = 0;
};

// ---------------------------------------------------------------------------------------
// The comparison

struct ObjectRef {
    std::string chunk, key, uuid, kind;
    int element = 0;
    std::string label() const {
        return uuid.empty() ? kind + " #" + std::to_string(element)
                            : uuid + " (" + kind + " #" + std::to_string(element) + ")";
    }
};

struct BitRow {
    ObjectRef object;
    int group = 0, light = 0;  // light from 1
    Evidence before, after;
    std::vector<std::string> notes;  // how the evidence changed
    bool bitChanged = true;
};

struct ObjectRow {
    ObjectRef object;
    std::string change;
};

struct ChunkRow {
    std::string chunk, status;  // status: "", "only in old", "only in new"
    uint64_t bits = 0, changed = 0, toZero = 0, toOne = 0, verdictOnly = 0, added = 0, removed = 0, otherObject = 0;
    std::vector<std::string> simRemoved, simAdded;
};

struct LightRow {
    int index = 0;
    std::optional<LightInfo> before, after;
    std::string change;  // empty: same
};

struct GroupChange {  // one picture in the HTML report
    ObjectRef object;
    int group = 0;
    std::vector<BitRow> rows;
};

struct Comparison {
    std::vector<std::string> notes;
    std::vector<LightRow> lights;
    std::vector<std::string> lightMoves;
    bool lightsKnown = true, lightsDiffer = false;
    bool lightsEdited = false;  // same names and types, other parameters (range, position...)
    int lightCount = 0;  // lights compared bit by bit (by index)
    std::vector<ChunkRow> chunks;
    ChunkRow total;
    std::vector<BitRow> changed, verdictOnly;
    std::vector<ObjectRow> objects;
    std::vector<GroupChange> groups;
    bool anyChange() const {
        return !changed.empty() || !verdictOnly.empty() || !objects.empty() || lightsDiffer || lightsEdited;
    }
};

// Formatting shared by the reports (cli/diff_report.cpp).
std::string num(double v);  // %.6g, no "-0"
std::string vecText(const Vec& v);
double depthGap(const WitnessRay& w);  // depth of q behind p along the ray
std::string evidenceText(const Evidence& e);
std::string verdictShort(const Evidence& e);
std::string lightText(const LightInfo& L);  // 'name' (type)
// What differs between two lights of the same name and type ("range 25 -> 60 m"), or "".
std::string lightParameterChanges(const LightInfo& a, const LightInfo& b);
std::string lightLabel(const Comparison& c, int light);
std::string sideText(const Bake& b);

std::string textReport(const Bake& a, const Bake& b, const Comparison& c);
std::string jsonReport(const Bake& a, const Bake& b, const Comparison& c);
std::string htmlReport(const Bake& a, const Bake& b, const Comparison& c);

// The SVG picture of a changed group (cli/diff_picture.cpp), "" when there is nothing to
// draw; `caption` says what it shows (or why there is none). `id` makes its ids unique.
std::string groupPicture(const GroupChange& g, const Comparison& c, const Bake& a, const Bake& b, int id,
                         std::string& caption);

}  // namespace shadowcull::cli::diff_detail

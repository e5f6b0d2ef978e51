#include "cli/diff.h"
#include "cli/output_guard.h"
#include "core/file_read.h"
#include "core/results_file.h"

#include <tinyxml2.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <ostream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli/pipeline.h"
#include "core/scene.h"
#include "core/xml_message.h"

namespace shadowcull::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Thrown by the readers; runDiff turns it into exit code 3.
struct InputError {
    std::string message;
};

// ---------------------------------------------------------------------------------------
// What one side of the diff knows

using Vec = std::array<double, 3>;

struct WitnessRay {
    Vec origin{}, direction{}, p{}, q{};
    std::string receiver;
};

// One (group, light) bit. An empty verdict means only the bit is known (a baked space).
struct Evidence {
    int bit = 1;
    std::string verdict, stage, reason;
    std::optional<WitnessRay> witness;
};

struct GroupBits {
    uint32_t mask = 0;
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

struct ChunkBake {
    std::vector<std::string> simulated;
    std::vector<ObjectBake> objects;  // document order
};

struct LightInfo {
    std::string name, type;
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
    std::map<std::string, ChunkBake, ChunkLess> chunks;
    size_t warnings = 0;
};

// Bit `l` of a group: with its evidence when the side has it, else from the mask.
Evidence bitOf(const GroupBits& g, int l) {
    if (size_t(l) < g.lights.size()) return g.lights[size_t(l)];
    Evidence e;
    e.bit = l < 32 ? int((g.mask >> l) & 1u) : 0;
    return e;
}

void assignKeys(ChunkBake& c) {
    std::map<std::string, int> seen;
    for (ObjectBake& o : c.objects) {
        if (o.uuid.empty()) {
            o.key = "#" + std::to_string(o.element);
        } else {
            const int n = ++seen[o.uuid];
            o.key = n == 1 ? o.uuid : o.uuid + "#" + std::to_string(n);
        }
    }
}

std::string trim(const char* s) {
    std::string t = s ? s : "";
    const size_t a = t.find_first_not_of(" \t\r\n"), b = t.find_last_not_of(" \t\r\n");
    return a == std::string::npos ? "" : t.substr(a, b - a + 1);
}

// ---------------------------------------------------------------------------------------
// Reading a results JSON file: core/results_file.h reads and checks it (the one reader of
// the format); here it only becomes one side of the comparison.

Vec vecOf(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

Bake fromResults(const std::string& path, const results::ResultsFile& file) {
    Bake b;
    b.path = path;
    for (const results::LightRecord& L : file.lights) b.lights.push_back({L.name, L.type});
    for (const results::ChunkRecord& rc : file.chunks) {
        ChunkBake& c = b.chunks[rc.chunk];  // the reader refuses a chunk named twice
        c.simulated = rc.simulated;
        for (const results::ObjectRecord& ro : rc.objects) {
            ObjectBake& o = c.objects.emplace_back();
            o.element = ro.element;
            o.kind = ro.kind;
            o.uuid = ro.uuid;
            o.skipped = ro.skipped;
            o.mask = ro.mask;
            for (const results::GroupRecord& rg : ro.groups) {
                GroupBits& g = o.groups.emplace_back();
                g.mask = rg.mask;
                for (const results::BitRecord& rb : rg.lights) {
                    Evidence& e = g.lights.emplace_back();
                    e.bit = rb.bit;
                    e.verdict = rb.verdict;
                    e.stage = rb.stage;
                    e.reason = rb.reason;
                    if (const std::optional<results::WitnessRecord>& w = rb.witness)
                        e.witness = WitnessRay{vecOf(w->origin), vecOf(w->direction), vecOf(w->p), vecOf(w->q),
                                               w->receiver};
                }
            }
        }
        assignKeys(c);
    }
    b.warnings = file.warnings.size();
    return b;
}

// ---------------------------------------------------------------------------------------
// Reading a baked space: the <shadow> masks of its chunk files

uint32_t parseMask(const std::string& file, const tinyxml2::XMLElement* e) {
    const std::string t = trim(e->GetText());
    const bool digits =
        !t.empty() && t.size() <= 10 && std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (!digits || std::stoull(t) > 0xffffffffull)
        throw InputError{file + ":" + std::to_string(e->GetLineNum()) + ": <" + e->Name() + "> mask '" + t +
                         "' is not a 32-bit decimal number"};
    return uint32_t(std::stoull(t));
}

void readChunkMasks(const std::string& file, ChunkBake& c) {
    tinyxml2::XMLDocument doc;
    Expected<std::string> text = readRegularFile(file, "chunk file");
    if (!text) throw InputError{text.error().what()};
    if (doc.Parse(text->data(), text->size()) != tinyxml2::XML_SUCCESS) {
        const int line = doc.ErrorLineNum();
        throw InputError{file + (line > 0 ? ":" + std::to_string(line) : "") +
                         ": cannot read the chunk file: " + xmlParseProblem(doc)};
    }
    int element = 0;
    for (const tinyxml2::XMLElement* e = doc.RootElement()->FirstChildElement(); e; e = e->NextSiblingElement()) {
        const std::string n = e->Name();
        if (n != "model" && n != "terrain") continue;
        ObjectBake o;
        o.kind = n;
        o.element = element++;
        if (const tinyxml2::XMLElement* u = e->FirstChildElement("uuid"); u && n == "model")
            o.uuid = trim(u->GetText());
        const tinyxml2::XMLElement* s = e->FirstChildElement("shadow");
        o.hasMask = s != nullptr;
        if (s) {
            o.mask = parseMask(file, s);
            if (n == "terrain") {
                o.groups.push_back({o.mask, {}});
            } else if (const tinyxml2::XMLElement* rs = s->FirstChildElement("RenderSet")) {
                if (const tinyxml2::XMLElement* geo = rs->FirstChildElement("Geometry"))
                    for (const tinyxml2::XMLElement* pg = geo->FirstChildElement("PrimitiveGroup"); pg;
                         pg = pg->NextSiblingElement("PrimitiveGroup"))
                        o.groups.push_back({parseMask(file, pg), {}});
            }
        }
        c.objects.push_back(std::move(o));
    }
    assignKeys(c);
}

Bake readSpace(const std::string& path) {
    Bake b;
    b.path = path;
    b.results = false;
    std::vector<std::string> names;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(path, ec)) {
        const std::string name = e.path().filename().string();
        if (e.is_regular_file() && parseChunkName(name)) names.push_back(name);
    }
    if (ec) throw InputError{path + ": cannot list the directory: " + ec.message()};
    // `bake --out DIR` writes only chunk files: without space.xml the light names are unknown.
    b.lightsKnown = fs::exists(fs::path(path) / "space.xml");
    if (b.lightsKnown) {
        Expected<SpaceSettings> st = readSpaceSettings(path, "");
        if (!st) throw InputError{st.error().what()};
        for (const Light& L : st->lights) b.lights.push_back({L.name, lightTypeName(L.type)});
    }
    if (names.empty() && !b.lightsKnown)
        throw InputError{path + ": not a space directory (no space.xml and no *.chunk files)"};
    for (const std::string& name : names) readChunkMasks((fs::path(path) / name).string(), b.chunks[name]);
    return b;
}

Bake readBake(const std::string& path) {
    if (fs::is_directory(path)) return readSpace(path);
    Expected<results::ResultsFile> file = results::readResultsFile(path);
    if (!file) throw InputError{file.error().what()};
    return fromResults(path, *file);
}

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
    int lightCount = 0;  // lights compared bit by bit (by index)
    std::vector<ChunkRow> chunks;
    ChunkRow total;
    std::vector<BitRow> changed, verdictOnly;
    std::vector<ObjectRow> objects;
    std::vector<GroupChange> groups;
    bool anyChange() const { return !changed.empty() || !verdictOnly.empty() || !objects.empty() || lightsDiffer; }
};

std::string lightText(const LightInfo& L) { return "'" + L.name + "' (" + L.type + ")"; }

// Highest bit set in any mask of a side, plus one: the light count of a space without space.xml.
int lightsInMasks(const Bake& b) {
    uint32_t all = 0;
    for (const auto& [name, c] : b.chunks)
        for (const ObjectBake& o : c.objects) {
            all |= o.mask;
            for (const GroupBits& g : o.groups) all |= g.mask;
        }
    int n = 0;
    while (n < 32 && (all >> n)) ++n;
    return n;
}

std::vector<std::string> evidenceNotes(const Evidence& a, const Evidence& b) {
    if (a.verdict.empty() || b.verdict.empty())
        return {std::string("evidence unavailable (") +
                (a.verdict.empty() && b.verdict.empty() ? "both are baked spaces"
                 : a.verdict.empty()                    ? "old is a baked space"
                                                        : "new is a baked space") +
                ")"};
    std::vector<std::string> n;
    if (!a.witness && b.witness) n.push_back("new witness");
    if (a.witness && !b.witness) n.push_back("lost witness");
    const bool ca = a.verdict == "culled", cb = b.verdict == "culled";
    if (!ca && cb) n.push_back("new proof (" + b.stage + ")");
    if (ca && !cb) n.push_back("lost proof (" + a.stage + ")");
    if (ca && cb && a.stage != b.stage) n.push_back("proof by " + a.stage + " -> " + b.stage);
    if (a.verdict == "kept" && b.verdict == "kept" && a.stage != b.stage)
        n.push_back("witness by " + a.stage + " -> " + b.stage);
    if (n.empty()) n.push_back("verdict " + a.verdict + " -> " + b.verdict);
    return n;
}

// "light 2 'lamp': range 5 m" -> "light 2: range 5 m": a renamed light (reported with the
// lights) should not make every chunk's simulated effects look different.
std::string withoutLightName(std::string s) {
    const size_t a = s.find(" '");
    const size_t b = a == std::string::npos ? a : s.find("':", a + 2);
    if (s.compare(0, 6, "light ") == 0 && b != std::string::npos) s.erase(a, b + 1 - a);
    return s;
}

class Comparer {
public:
    Comparer(const Bake& a, const Bake& b) : a_(a), b_(b) {}

    Comparison run() {
        for (const Bake* s : {&a_, &b_}) {
            const char* side = s == &a_ ? "old" : "new";
            if (!s->results)
                c_.notes.push_back(std::string(side) + " (" + s->path +
                                   ") is a baked space: masks only, no evidence (verdicts, stages, witnesses, proofs)");
            if (!s->lightsKnown)
                c_.notes.push_back(std::string(side) +
                                   " has no space.xml: light names unknown, bits compared by index");
        }
        compareLights();
        std::set<std::string, ChunkLess> names;
        for (const auto& [n, ch] : a_.chunks) names.insert(n);
        for (const auto& [n, ch] : b_.chunks) names.insert(n);
        for (const std::string& n : names) compareChunk(n);
        for (const ChunkRow& r : c_.chunks) {
            ChunkRow& t = c_.total;
            t.bits += r.bits, t.changed += r.changed, t.toZero += r.toZero, t.toOne += r.toOne;
            t.verdictOnly += r.verdictOnly, t.added += r.added, t.removed += r.removed, t.otherObject += r.otherObject;
        }
        c_.total.chunk = "total";
        return std::move(c_);
    }

private:
    void compareLights() {
        // A side without space.xml has as many lights as the other side, else as its masks show.
        auto known = [](const Bake& s) { return s.lightsKnown ? int(s.lights.size()) : -1; };
        int na = known(a_), nb = known(b_);
        c_.lightsKnown = na >= 0 && nb >= 0;
        if (na < 0) na = nb >= 0 ? nb : std::max(lightsInMasks(a_), lightsInMasks(b_));
        if (nb < 0) nb = na;
        c_.lightCount = std::min(na, nb);
        if (!c_.lightsKnown) return;
        for (int i = 0; i < std::max(na, nb); ++i) {
            LightRow r;
            r.index = i + 1;
            if (i < na) r.before = a_.lights[size_t(i)];
            if (i < nb) r.after = b_.lights[size_t(i)];
            if (!r.before)
                r.change = "added";
            else if (!r.after)
                r.change = "removed";
            else if (r.before->name != r.after->name)
                r.change = r.before->type != r.after->type ? "renamed, type changed" : "renamed";
            else if (r.before->type != r.after->type)
                r.change = "type changed";
            c_.lightsDiffer |= !r.change.empty();
            c_.lights.push_back(r);
        }
        if (!c_.lightsDiffer) return;
        // A light inserted or removed renumbers the later ones: their bits then compare
        // against another light's. Say where each name went.
        for (int i = 0; i < na; ++i)
            for (int k = 0; k < nb; ++k)
                if (k != i && a_.lights[size_t(i)].name == b_.lights[size_t(k)].name)
                    c_.lightMoves.push_back("'" + a_.lights[size_t(i)].name + "' was light " + std::to_string(i + 1) +
                                            ", is light " + std::to_string(k + 1));
    }

    void compareChunk(const std::string& name) {
        ChunkRow row;
        row.chunk = name;
        const auto ia = a_.chunks.find(name), ib = b_.chunks.find(name);
        if (ia == a_.chunks.end() || ib == b_.chunks.end()) {
            const bool isNew = ia == a_.chunks.end();
            const ChunkBake& only = isNew ? ib->second : ia->second;
            row.status = isNew ? "only in new" : "only in old";
            (isNew ? row.added : row.removed) = only.objects.size();
            c_.objects.push_back({ObjectRef{name, "", "", "chunk", 0},  // kind "chunk": the whole chunk
                                  std::string(isNew ? "chunk only in new (" : "chunk only in old (") +
                                      std::to_string(only.objects.size()) + " objects)"});
            c_.chunks.push_back(row);
            return;
        }
        const ChunkBake &ca = ia->second, &cb = ib->second;
        auto missing = [](const std::vector<std::string>& list, const std::string& s) {
            return std::none_of(list.begin(), list.end(),
                                [&](const std::string& t) { return withoutLightName(t) == withoutLightName(s); });
        };
        // A baked space does not record what was simulated: nothing to compare then.
        for (const std::string& s : ca.simulated)
            if (b_.results && missing(cb.simulated, s)) row.simRemoved.push_back(s);
        for (const std::string& s : cb.simulated)
            if (a_.results && missing(ca.simulated, s)) row.simAdded.push_back(s);
        // Objects by key, in the new document order (removed ones at their old place).
        std::map<std::string, const ObjectBake*> oa, ob;
        for (const ObjectBake& o : ca.objects) oa[o.key] = &o;
        for (const ObjectBake& o : cb.objects) ob[o.key] = &o;
        std::vector<std::pair<int, std::string>> order;
        for (const auto& [k, o] : ob) order.push_back({o->element, k});
        for (const auto& [k, o] : oa)
            if (!ob.count(k)) order.push_back({o->element, k});
        std::sort(order.begin(), order.end());
        for (const auto& [element, key] : order) {
            const ObjectBake* before = oa.count(key) ? oa[key] : nullptr;
            const ObjectBake* after = ob.count(key) ? ob[key] : nullptr;
            const ObjectBake& any = after ? *after : *before;
            const ObjectRef ref{name, key, any.uuid, any.kind, any.element};
            if (!before || !after) {
                ++(after ? row.added : row.removed);
                c_.objects.push_back({ref, after ? "added" : "removed"});
                continue;
            }
            compareObject(*before, *after, ref, row);
        }
        c_.chunks.push_back(row);
    }

    void objectChange(const ObjectRef& ref, ChunkRow& row, std::string what) {
        ++row.otherObject;
        c_.objects.push_back({ref, std::move(what)});
    }

    void compareObject(const ObjectBake& a, const ObjectBake& b, const ObjectRef& ref, ChunkRow& row) {
        if (a.kind != b.kind) return objectChange(ref, row, "kind " + a.kind + " -> " + b.kind);
        if (a.skipped || b.skipped) {
            if (a.skipped != b.skipped)
                objectChange(ref, row,
                             a.skipped ? "skipped in old (no verdicts), baked in new"
                                       : "baked in old, skipped in new (no verdicts)");
            return;
        }
        if (a.hasMask != b.hasMask)
            return objectChange(ref, row, std::string("no <shadow> in ") + (a.hasMask ? "new" : "old"));
        if (a.groups.size() != b.groups.size()) {
            std::string what = "groups " + std::to_string(a.groups.size()) + " -> " + std::to_string(b.groups.size());
            if (a.mask != b.mask) what += ", mask " + std::to_string(a.mask) + " -> " + std::to_string(b.mask);
            objectChange(ref, row, what + " (common groups compared)");
        }
        for (size_t g = 0; g < std::min(a.groups.size(), b.groups.size()); ++g) {
            GroupChange gc{ref, int(g), {}};
            for (int l = 0; l < c_.lightCount; ++l) {
                BitRow r{ref, int(g), l + 1, bitOf(a.groups[g], l), bitOf(b.groups[g], l), {}, true};
                ++row.bits;
                const bool known = !r.before.verdict.empty() && !r.after.verdict.empty();
                if (r.before.bit != r.after.bit) {
                    ++row.changed;
                    ++(r.after.bit ? row.toOne : row.toZero);
                    r.notes = evidenceNotes(r.before, r.after);
                    c_.changed.push_back(r);
                } else if (known && (r.before.verdict != r.after.verdict || r.before.stage != r.after.stage)) {
                    ++row.verdictOnly;
                    r.bitChanged = false;
                    r.notes = evidenceNotes(r.before, r.after);
                    c_.verdictOnly.push_back(r);
                } else {
                    continue;
                }
                gc.rows.push_back(std::move(r));
            }
            if (!gc.rows.empty()) c_.groups.push_back(std::move(gc));
        }
    }

    const Bake &a_, &b_;
    Comparison c_;
};

// ---------------------------------------------------------------------------------------
// Formatting

std::string num(double v) {
    if (v == 0) v = 0;  // no "-0"
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

std::string vecText(const Vec& v) { return "(" + num(v[0]) + ", " + num(v[1]) + ", " + num(v[2]) + ")"; }

// Depth of q behind p along the (normalised) ray.
double depthGap(const WitnessRay& w) {
    const double len =
        std::sqrt(w.direction[0] * w.direction[0] + w.direction[1] * w.direction[1] + w.direction[2] * w.direction[2]);
    double d = 0;
    for (int k = 0; k < 3; ++k) d += (w.q[size_t(k)] - w.p[size_t(k)]) * w.direction[size_t(k)];
    return len > 0 ? d / len : 0.0;
}

std::string evidenceText(const Evidence& e) {
    if (e.verdict.empty()) return "bit " + std::to_string(e.bit) + " (mask only, no evidence)";
    if (e.verdict == "undecided") return "undecided, kept as 1";
    std::string s = e.verdict + " by " + (e.stage.empty() ? "?" : e.stage);
    if (e.witness)
        return s + ": witness ray p " + vecText(e.witness->p) + " -> q " + vecText(e.witness->q) + " on " +
               e.witness->receiver + ", gap " + num(depthGap(*e.witness)) + " m";
    return e.reason.empty() || e.reason == "witness ray" ? s : s + ": " + e.reason;
}

std::string verdictShort(const Evidence& e) {
    if (e.verdict.empty()) return "?";
    return e.verdict + (e.stage.empty() ? "" : "/" + e.stage);
}

std::string lightLabel(const Comparison& c, int light) {
    std::string s = "light " + std::to_string(light);
    if (size_t(light) <= c.lights.size()) {
        const LightRow& r = c.lights[size_t(light - 1)];
        const std::optional<LightInfo>& L = r.after ? r.after : r.before;
        if (L) s += " '" + L->name + "'";
    }
    return s;
}

std::string sideText(const Bake& b) {
    return b.path + " (" + (b.results ? "results JSON" : "baked space, masks only") + ", " +
           std::to_string(b.chunks.size()) + (b.chunks.size() == 1 ? " chunk)" : " chunks)");
}

std::string pad(const std::string& s, size_t w, bool right = true) {
    if (s.size() >= w) return s;
    return right ? std::string(w - s.size(), ' ') + s : s + std::string(w - s.size(), ' ');
}

std::string textReport(const Bake& a, const Bake& b, const Comparison& c) {
    std::ostringstream o;
    o << "shadowcull diff\n  old: " << sideText(a) << "\n  new: " << sideText(b) << "\n";
    for (const std::string& n : c.notes) o << "note: " << n << "\n";
    o << "\n";
    if (c.lightsDiffer) {
        o << "*** LIGHT LISTS DIFFER: bits are compared by light index ***\n";
        for (const LightRow& r : c.lights) {
            if (r.change.empty()) continue;
            o << "  light " << r.index << ": " << (r.before ? lightText(*r.before) : "-") << " -> "
              << (r.after ? lightText(*r.after) : "-") << ": " << r.change << "\n";
        }
        for (const std::string& m : c.lightMoves) o << "  " << m << " (its bits now compare against another light's)\n";
    } else if (c.lightsKnown) {
        o << "lights:";
        for (const LightRow& r : c.lights)
            o << (r.index > 1 ? "," : "") << " " << r.index << " " << lightText(*r.after);
        if (c.lights.empty()) o << " none";
        o << "\n";
    } else {
        o << "lights: " << c.lightCount << " compared by index (names unknown)\n";
    }

    o << "\n"
      << pad("chunk", 16, false) << pad("bits", 8) << pad("changed", 9) << pad("1->0", 7) << pad("0->1", 7)
      << pad("verdict-only", 14) << "  objects +added -removed ~changed\n";
    auto line = [&](const ChunkRow& r) {
        o << pad(r.chunk, 16, false) << pad(std::to_string(r.bits), 8) << pad(std::to_string(r.changed), 9)
          << pad(std::to_string(r.toZero), 7) << pad(std::to_string(r.toOne), 7)
          << pad(std::to_string(r.verdictOnly), 14) << "  +" << r.added << " -" << r.removed << " ~" << r.otherObject
          << (r.status.empty() ? "" : "  (" + r.status + ")") << "\n";
    };
    for (const ChunkRow& r : c.chunks) line(r);
    line(c.total);

    auto rows = [&](const std::vector<BitRow>& list) {
        for (const BitRow& r : list) {
            o << "  " << r.object.chunk << "  " << r.object.label() << "  group " << r.group << "  "
              << lightLabel(c, r.light) << ": ";
            if (r.bitChanged)
                o << r.before.bit << " -> " << r.after.bit << "\n";
            else
                o << "bit " << r.after.bit << ", " << verdictShort(r.before) << " -> " << verdictShort(r.after) << "\n";
            o << "      old: " << evidenceText(r.before) << "\n      new: " << evidenceText(r.after)
              << "\n      evidence: ";
            for (size_t k = 0; k < r.notes.size(); ++k) o << (k ? ", " : "") << r.notes[k];
            o << "\n";
        }
    };
    o << "\nchanged bits (" << c.changed.size()
      << "), by chunk, object, group, light:" << (c.changed.empty() ? " none" : "") << "\n";
    rows(c.changed);
    o << "\nverdict-only changes, bit unchanged (" << c.verdictOnly.size()
      << "):" << (c.verdictOnly.empty() ? " none" : "") << "\n";
    rows(c.verdictOnly);
    o << "\nobject changes (" << c.objects.size() << "):" << (c.objects.empty() ? " none" : "") << "\n";
    for (const ObjectRow& r : c.objects)
        o << "  " << r.object.chunk << (r.object.kind == "chunk" ? "" : "  " + r.object.label()) << ": " << r.change
          << "\n";
    bool simHeader = false;
    for (const ChunkRow& r : c.chunks) {
        if (r.simRemoved.empty() && r.simAdded.empty()) continue;
        if (!simHeader) o << "\nsimulated effects changed (informational):\n";
        simHeader = true;
        o << "  " << r.chunk << "\n";
        for (const std::string& s : r.simRemoved) o << "    - " << s << "\n";
        for (const std::string& s : r.simAdded) o << "    + " << s << "\n";
    }
    if (a.warnings || b.warnings) o << "\nwarnings in the bakes: old " << a.warnings << ", new " << b.warnings << "\n";

    o << "\nresult: ";
    if (!c.anyChange()) {
        o << "no changes\n";
    } else {
        o << c.changed.size() << " bits changed (" << c.total.toZero << " 1->0, " << c.total.toOne << " 0->1), "
          << c.verdictOnly.size() << " verdict-only changes, " << c.objects.size() << " object changes"
          << (c.lightsDiffer ? ", LIGHT LISTS DIFFER" : "") << "\n";
    }
    return o.str();
}

// --- JSON ---

json vecJson(const Vec& v) { return json::array({v[0], v[1], v[2]}); }

json evidenceJson(const Evidence& e) {
    json j = {{"bit", e.bit}};
    if (!e.verdict.empty()) j["verdict"] = e.verdict;
    if (!e.stage.empty()) j["stage"] = e.stage;
    if (!e.reason.empty()) j["reason"] = e.reason;
    if (e.witness)
        j["witness"] = {{"origin", vecJson(e.witness->origin)},
                        {"direction", vecJson(e.witness->direction)},
                        {"p", vecJson(e.witness->p)},
                        {"q", vecJson(e.witness->q)},
                        {"receiver", e.witness->receiver}};
    return j;
}

json objectJson(const ObjectRef& r) {
    json j = {{"chunk", r.chunk}, {"kind", r.kind}, {"element", r.element}};
    if (!r.uuid.empty()) j["uuid"] = r.uuid;
    return j;
}

json sideJson(const Bake& b) {
    json lights = json::array();
    for (size_t i = 0; i < b.lights.size(); ++i)
        lights.push_back({{"index", i + 1}, {"name", b.lights[i].name}, {"type", b.lights[i].type}});
    json j = {{"path", b.path},
              {"source", b.results ? "results" : "space"},
              {"evidence", b.results},
              {"chunks", b.chunks.size()},
              {"warnings", b.warnings}};
    if (b.lightsKnown) j["lights"] = lights;
    return j;
}

json countsJson(const ChunkRow& r) {
    return {{"bits", r.bits},
            {"changed", r.changed},
            {"toZero", r.toZero},
            {"toOne", r.toOne},
            {"verdictOnly", r.verdictOnly},
            {"objectsAdded", r.added},
            {"objectsRemoved", r.removed},
            {"objectsChanged", r.otherObject}};
}

std::string jsonReport(const Bake& a, const Bake& b, const Comparison& c) {
    json j;
    j["format"] = "shadowcull-diff";
    j["version"] = 1;
    j["old"] = sideJson(a);
    j["new"] = sideJson(b);
    j["notes"] = c.notes;
    j["changed"] = c.anyChange();
    j["lightsDiffer"] = c.lightsDiffer;
    json lights = json::array();
    for (const LightRow& r : c.lights) {
        if (r.change.empty()) continue;
        json jl = {{"index", r.index}, {"change", r.change}};
        if (r.before) jl["old"] = {{"name", r.before->name}, {"type", r.before->type}};
        if (r.after) jl["new"] = {{"name", r.after->name}, {"type", r.after->type}};
        lights.push_back(jl);
    }
    j["lightChanges"] = lights;
    j["lightMoves"] = c.lightMoves;
    json chunks = json::array();
    for (const ChunkRow& r : c.chunks) {
        json jc = countsJson(r);
        jc["chunk"] = r.chunk;
        if (!r.status.empty()) jc["status"] = r.status;
        if (!r.simRemoved.empty() || !r.simAdded.empty())
            jc["simulated"] = {{"removed", r.simRemoved}, {"added", r.simAdded}};
        chunks.push_back(jc);
    }
    j["chunks"] = chunks;
    j["totals"] = countsJson(c.total);
    auto bitRows = [&](const std::vector<BitRow>& list) {
        json out = json::array();
        for (const BitRow& r : list) {
            json jr = objectJson(r.object);
            jr["group"] = r.group;
            jr["light"] = r.light;
            jr["old"] = evidenceJson(r.before);
            jr["new"] = evidenceJson(r.after);
            jr["evidence"] = r.notes;
            out.push_back(jr);
        }
        return out;
    };
    j["changedBits"] = bitRows(c.changed);
    j["verdictChanges"] = bitRows(c.verdictOnly);
    json objects = json::array();
    for (const ObjectRow& r : c.objects) {
        json jo = r.object.kind == "chunk" ? json{{"chunk", r.object.chunk}} : objectJson(r.object);
        jo["change"] = r.change;
        objects.push_back(jo);
    }
    j["objectChanges"] = objects;
    return j.dump(1, ' ', false, json::error_handler_t::replace) + "\n";  // paths need not be UTF-8
}

// --- HTML ---

std::string esc(const std::string& s) {
    std::string o;
    for (char ch : s) {
        switch (ch) {
            case '&': o += "&amp;"; break;
            case '<': o += "&lt;"; break;
            case '>': o += "&gt;"; break;
            case '"': o += "&quot;"; break;
            case '\'': o += "&#39;"; break;
            default: o += ch;
        }
    }
    return o;
}

std::string f1(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", v);
    return buf;
}

// A top-down (x right, z down) plot of the witness rays' p and q on each side, or a
// placeholder saying why there is nothing to draw. Honest: only recorded points are shown.
std::string groupSvg(const GroupChange& g) {
    struct Seg {
        const WitnessRay* w;
        bool isNew;
    };
    std::vector<Seg> segs;
    bool maskOnly = false;
    for (const BitRow& r : g.rows) {
        if (r.before.witness) segs.push_back({&*r.before.witness, false});
        if (r.after.witness) segs.push_back({&*r.after.witness, true});
        maskOnly |= r.before.verdict.empty() || r.after.verdict.empty();
    }
    const int W = 240;
    std::string s =
        "<svg class=\"pic\" width=\"240\" height=\"240\" viewBox=\"0 0 240 240\">"
        "<rect x=\"0.5\" y=\"0.5\" width=\"239\" height=\"239\" class=\"frame\"/>";
    if (segs.empty()) {
        s += "<text x=\"120\" y=\"112\" text-anchor=\"middle\">no witness ray on either side</text>";
        s += std::string("<text x=\"120\" y=\"130\" text-anchor=\"middle\">") +
             (maskOnly ? "(a baked space records masks only)" : "(proofs and undecided bits have no points)") +
             "</text>";
        return s + "</svg>";
    }
    double x0 = 1e300, x1 = -1e300, z0 = 1e300, z1 = -1e300;
    for (const Seg& sg : segs)
        for (const Vec* v : {&sg.w->p, &sg.w->q}) {
            x0 = std::min(x0, (*v)[0]), x1 = std::max(x1, (*v)[0]);
            z0 = std::min(z0, (*v)[2]), z1 = std::max(z1, (*v)[2]);
        }
    const double extent = std::max({x1 - x0, z1 - z0, 1.0}) * 1.25, cx = (x0 + x1) / 2, cz = (z0 + z1) / 2;
    const double scale = (W - 40) / extent;
    auto X = [&](double x) { return f1(W / 2.0 + (x - cx) * scale); };
    auto Z = [&](double z) { return f1(W / 2.0 + 8 + (z - cz) * scale); };
    for (const Seg& sg : segs) {
        const std::string cls = sg.isNew ? "new" : "old";
        const Vec &p = sg.w->p, &q = sg.w->q;
        s += "<line class=\"" + cls + "\" x1=\"" + X(p[0]) + "\" y1=\"" + Z(p[2]) + "\" x2=\"" + X(q[0]) + "\" y2=\"" +
             Z(q[2]) + "\"/>";
        s += "<circle class=\"" + cls + " p\" cx=\"" + X(p[0]) + "\" cy=\"" + Z(p[2]) + "\" r=\"4\"/>";
        s += "<circle class=\"" + cls + " q\" cx=\"" + X(q[0]) + "\" cy=\"" + Z(q[2]) + "\" r=\"4\"/>";
    }
    s += "<text x=\"6\" y=\"14\">x " + esc(num(x0)) + " .. " + esc(num(x1)) + " m, z " + esc(num(z0)) + " .. " +
         esc(num(z1)) + " m</text>";
    return s + "</svg>";
}

std::string htmlReport(const Bake& a, const Bake& b, const Comparison& c) {
    std::ostringstream o;
    o << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>shadowcull diff</title>\n<style>\n"
         "body{font:14px/1.4 sans-serif;margin:1.5em;color:#222}\n"
         "table{border-collapse:collapse;margin:.5em 0 1.5em}\n"
         "th,td{border:1px solid #bbb;padding:3px 7px;text-align:left;vertical-align:top}\n"
         "th{background:#eee} td.n{text-align:right} code{font-size:12px}\n"
         ".warn{background:#fdd;border:2px solid #c00;padding:.5em 1em;font-weight:bold}\n"
         ".note{background:#ffd;padding:.3em 1em}\n"
         ".group{display:flex;gap:1em;align-items:flex-start;margin-bottom:1.5em}\n"
         "svg.pic{background:#fafafa;font-size:11px} .frame{fill:none;stroke:#999}\n"
         "line.old{stroke:#1f77b4;stroke-width:2} line.new{stroke:#d62728;stroke-width:2}\n"
         "circle.old.p{fill:#1f77b4} circle.new.p{fill:#d62728}\n"
         "circle.old.q{fill:#fff;stroke:#1f77b4;stroke-width:2} circle.new.q{fill:#fff;stroke:#d62728;stroke-width:2}\n"
         ".old{color:#1f77b4} .new{color:#d62728}\n"
         "</style></head><body>\n<h1>shadowcull diff</h1>\n";
    o << "<p>old: <code>" << esc(sideText(a)) << "</code><br>new: <code>" << esc(sideText(b)) << "</code></p>\n";
    for (const std::string& n : c.notes) o << "<p class=\"note\">" << esc(n) << "</p>\n";
    o << "<p><b>result:</b> " << (c.anyChange() ? "changed" : "no changes") << " &mdash; " << c.changed.size()
      << " bits changed, " << c.verdictOnly.size() << " verdict-only changes, " << c.objects.size()
      << " object changes</p>\n";

    o << "<h2>Lights</h2>\n";
    if (c.lightsDiffer) {
        o << "<p class=\"warn\">Light lists differ: bits are compared by light index.";
        for (const std::string& m : c.lightMoves) o << "<br>" << esc(m);
        o << "</p>\n";
    }
    if (c.lightsKnown) {
        o << "<table><tr><th>light</th><th>old</th><th>new</th><th>change</th></tr>\n";
        for (const LightRow& r : c.lights)
            o << "<tr><td class=\"n\">" << r.index << "</td><td>" << (r.before ? esc(lightText(*r.before)) : "-")
              << "</td><td>" << (r.after ? esc(lightText(*r.after)) : "-") << "</td><td>" << esc(r.change)
              << "</td></tr>\n";
        o << "</table>\n";
    } else {
        o << "<p>" << c.lightCount << " lights compared by index (names unknown).</p>\n";
    }

    o << "<h2>Counts per "
         "chunk</h2>\n<table><tr><th>chunk</th><th>bits</th><th>changed</th><th>1&rarr;0</th><th>0&rarr;1</th>"
         "<th>verdict-only</th><th>objects added</th><th>removed</th><th>changed</th><th>status</th></tr>\n";
    auto countRow = [&](const ChunkRow& r) {
        o << "<tr><td>" << esc(r.chunk) << "</td>";
        for (uint64_t v : {r.bits, r.changed, r.toZero, r.toOne, r.verdictOnly, r.added, r.removed, r.otherObject})
            o << "<td class=\"n\">" << v << "</td>";
        o << "<td>" << esc(r.status) << "</td></tr>\n";
    };
    for (const ChunkRow& r : c.chunks) countRow(r);
    countRow(c.total);
    o << "</table>\n";

    auto bitTable = [&](const std::vector<BitRow>& list) {
        if (list.empty()) return void(o << "<p>none</p>\n");
        o << "<table><tr><th>chunk</th><th>object</th><th>group</th><th>light</th><th>bit</th><th>old</th><th>new</th>"
             "<th>evidence</th></tr>\n";
        for (const BitRow& r : list) {
            o << "<tr><td>" << esc(r.object.chunk) << "</td><td>" << esc(r.object.label()) << "</td><td class=\"n\">"
              << r.group << "</td><td>" << esc(lightLabel(c, r.light)) << "</td><td>" << r.before.bit << " &rarr; "
              << r.after.bit << "</td><td class=\"old\">" << esc(evidenceText(r.before)) << "</td><td class=\"new\">"
              << esc(evidenceText(r.after)) << "</td><td>";
            for (size_t k = 0; k < r.notes.size(); ++k) o << (k ? ", " : "") << esc(r.notes[k]);
            o << "</td></tr>\n";
        }
        o << "</table>\n";
    };
    o << "<h2>Changed bits</h2>\n";
    bitTable(c.changed);
    o << "<h2>Verdict-only changes (bit unchanged)</h2>\n";
    bitTable(c.verdictOnly);

    o << "<h2>Object changes</h2>\n";
    if (c.objects.empty())
        o << "<p>none</p>\n";
    else {
        o << "<table><tr><th>chunk</th><th>object</th><th>change</th></tr>\n";
        for (const ObjectRow& r : c.objects)
            o << "<tr><td>" << esc(r.object.chunk) << "</td><td>"
              << (r.object.kind == "chunk" ? "" : esc(r.object.label())) << "</td><td>" << esc(r.change)
              << "</td></tr>\n";
        o << "</table>\n";
    }

    bool simHeader = false;
    for (const ChunkRow& r : c.chunks) {
        if (r.simRemoved.empty() && r.simAdded.empty()) continue;
        if (!simHeader)
            o << "<h2>Simulated effects changed</h2>\n<table><tr><th>chunk</th><th>old only</th><th>new "
                 "only</th></tr>\n";
        simHeader = true;
        o << "<tr><td>" << esc(r.chunk) << "</td><td class=\"old\">";
        for (const std::string& s : r.simRemoved) o << esc(s) << "<br>";
        o << "</td><td class=\"new\">";
        for (const std::string& s : r.simAdded) o << esc(s) << "<br>";
        o << "</td></tr>\n";
    }
    if (simHeader) o << "</table>\n";

    o << "<h2>Changed groups</h2>\n<p>Top-down view (x right, z down): witness ray points p (filled) and q (hollow), "
         "<span class=\"old\">old</span> and <span class=\"new\">new</span>.</p>\n";
    if (c.groups.empty()) o << "<p>none</p>\n";
    for (const GroupChange& g : c.groups) {
        o << "<div class=\"group\">" << groupSvg(g) << "<div><h3>" << esc(g.object.chunk) << " "
          << esc(g.object.label()) << " group " << g.group << "</h3><ul>";
        for (const BitRow& r : g.rows)
            o << "<li>" << esc(lightLabel(c, r.light)) << ": " << r.before.bit << " &rarr; " << r.after.bit << " ("
              << esc(verdictShort(r.before)) << " &rarr; " << esc(verdictShort(r.after)) << ")</li>";
        o << "</ul></div></div>\n";
    }
    o << "</body></html>\n";
    return o.str();
}

bool writeReport(const std::string& path, const std::string& text) {
    std::ofstream f(path, std::ios::binary);
    f << text;
    f.close();
    return bool(f);
}

}  // namespace

int runDiff(const DiffOptions& opt, std::ostream& out, std::ostream& err) {
    for (const auto& [path, option] : {std::pair{opt.htmlPath, "--html"}, std::pair{opt.jsonPath, "--json"}})
        if (Status s = refuseInputAsOutput(path, {opt.oldPath, opt.newPath}, option); !s) {
            err << "shadowcull: error: " << s.error().what() << "\n";
            return kExitBadInput;
        }
    Bake a, b;
    try {
        a = readBake(opt.oldPath);
        b = readBake(opt.newPath);
    } catch (const InputError& e) {
        err << "shadowcull: error: " << e.message << "\n";
        return kExitBadInput;
    }
    const Comparison c = Comparer(a, b).run();
    out << textReport(a, b, c);
    for (const auto& [path, text] : {std::pair{opt.htmlPath, &htmlReport}, std::pair{opt.jsonPath, &jsonReport}}) {
        if (path.empty()) continue;
        if (!writeReport(path, text(a, b, c))) {
            err << "shadowcull: error: " << path << ": cannot write the report\n";
            return kExitIo;
        }
    }
    return c.anyChange() ? kDiffChanged : kDiffSame;
}

}  // namespace shadowcull::cli

#include "cli/diff.h"

#include "cli/diff_model.h"
#include "cli/output_guard.h"
#include "io/chunk_writer.h"
#include "io/file_read.h"
#include "io/results_file.h"

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


#include "cli/pipeline.h"
#include "core/scene.h"
#include "io/scene_reader.h"
#include "io/xml_message.h"

namespace shadowcull::cli {

namespace {

namespace fs = std::filesystem;
using namespace diff_detail;

// Thrown by the readers; runDiff turns it into exit code 3.
struct InputError {
    std::string message;
};

// Bit `l` of a group: with its evidence when the side has it, else from the mask.
Evidence bitOf(const GroupBits& g, int l) {
    if (size_t(l) < g.lights.size()) return g.lights[size_t(l)];
    Evidence e;
    e.bit = l < 32 ? int((g.mask >> l) & 1u) : 0;
    return e;
}

void assignKeys(ChunkSide& c) {
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
// Reading a results JSON file: io/results_file.h reads and checks it (the one reader of
// the format); here it only becomes one side of the comparison.

Vec vecOf(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

Bake fromResults(const std::string& path, const results::ResultsFile& file) {
    Bake b;
    b.path = path;
    for (const results::LightRecord& L : file.lights) {
        LightInfo& i = b.lights.emplace_back();
        i.name = L.name, i.type = L.type;
        if (L.position) i.position = vecOf(*L.position);
        if (L.direction) i.direction = vecOf(*L.direction);
        i.range = L.range, i.coneAngle = L.coneAngle, i.bias = L.bias, i.slopeBias = L.slopeBias;
        i.filterRadius = L.filterRadius, i.normalBias = L.normalBias;
    }
    for (const results::ChunkRecord& rc : file.chunks) {
        ChunkSide& c = b.chunks[rc.chunk];  // the reader refuses a chunk named twice
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
                if (rg.bounds) g.bounds = BoxVec{vecOf((*rg.bounds)[0]), vecOf((*rg.bounds)[1])};
                for (const results::BitRecord& rb : rg.lights) {
                    Evidence& e = g.lights.emplace_back();
                    e.bit = rb.bit;
                    e.verdict = rb.verdict;
                    e.stage = rb.stage;
                    e.reason = rb.reason;
                    if (const std::optional<results::WitnessRecord>& w = rb.witness)
                    {
                        e.witness = WitnessRay{vecOf(w->origin), vecOf(w->direction), vecOf(w->p), vecOf(w->q),
                                               w->receiver, std::nullopt};
                        if (w->receiverBounds)
                            e.witness->receiverBounds = BoxVec{vecOf((*w->receiverBounds)[0]), vecOf((*w->receiverBounds)[1])};
                    }
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

void readChunkMasks(const std::string& file, ChunkSide& c) {
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
                o.groups.push_back({o.mask, std::nullopt, {}});
            } else if (const tinyxml2::XMLElement* rs = s->FirstChildElement("RenderSet")) {
                if (const tinyxml2::XMLElement* geo = rs->FirstChildElement("Geometry"))
                    for (const tinyxml2::XMLElement* pg = geo->FirstChildElement("PrimitiveGroup"); pg;
                         pg = pg->NextSiblingElement("PrimitiveGroup"))
                        o.groups.push_back({parseMask(file, pg), std::nullopt, {}});
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
        for (const Light& L : st->lights) {
            LightInfo& i = b.lights.emplace_back();
            i.name = L.name, i.type = lightTypeName(L.type);
            if (L.type != LightType::Directional) i.position = vecOf(L.position), i.range = L.range;
            if (L.type != LightType::Point) i.direction = vecOf(L.direction);
            if (L.type == LightType::Spot) i.coneAngle = L.coneHalfAngleDeg;
            i.bias = L.bias, i.slopeBias = L.slopeBias, i.filterRadius = L.filterRadius, i.normalBias = L.normalBias;
        }
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
            if (r.change.empty() && r.before && r.after) {
                // Same light, other settings: bits still compare against the same light.
                r.change = lightParameterChanges(*r.before, *r.after);
                c_.lightsEdited |= !r.change.empty();
            }
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
            const ChunkSide& only = isNew ? ib->second : ia->second;
            row.status = isNew ? "only in new" : "only in old";
            (isNew ? row.added : row.removed) = only.objects.size();
            c_.objects.push_back({ObjectRef{name, "", "", "chunk", 0},  // kind "chunk": the whole chunk
                                  std::string(isNew ? "chunk only in new (" : "chunk only in old (") +
                                      std::to_string(only.objects.size()) + " objects)"});
            c_.chunks.push_back(row);
            return;
        }
        const ChunkSide &ca = ia->second, &cb = ib->second;
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
// Writing


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
        // Written whole or not at all; a failure says why.
        if (Status s = writeFileAtomic(path, text(a, b, c)); !s) {
            err << "shadowcull: error: " << s.error().what() << "; the report is printed above\n";
            return kExitIo;
        }
    }
    return c.anyChange() ? kDiffChanged : kDiffSame;
}

}  // namespace shadowcull::cli